"""profile=modbus-tcp with a real client (DESIGN §13): a session recorded
between pymodbus's TCP client and pymodbus's own server, through
`wiretape record --listen`, replays to a pymodbus client that polls in
another order and once more than recorded (repeat=last); each response
carries the client's own transaction id, which pymodbus checks."""

import asyncio
import socket
import threading

import pytest

from wiretape import _core, bridge

try:
    from pymodbus.client import ModbusTcpClient
    from pymodbus.datastore import (ModbusDeviceContext, ModbusSequentialDataBlock,
                                    ModbusServerContext)
    from pymodbus.server import ModbusTcpServer
except ImportError as error:  # pragma: no cover - the set-up installs it
    pytest.skip(f"pymodbus not installed: {error} (make installs it)", allow_module_level=True)

from devices import wait_until

DEADLINE = 20.0
REGISTERS = [1000 + i for i in range(100)]
RECORDED_POLLS = [(0, 2), (10, 3), (20, 1)]


def free_port():
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def accepting(port):
    try:
        socket.create_connection(("127.0.0.1", port), timeout=1).close()
        return True
    except OSError:
        return False


class ModbusDevice:
    """pymodbus's TCP server with holding registers REGISTERS, on a thread."""

    def __init__(self):
        self.port = free_port()
        # Request address 0 is the block's address 1 (pymodbus counts from 1).
        block = ModbusSequentialDataBlock(1, REGISTERS)
        self.context = ModbusServerContext(devices=ModbusDeviceContext(hr=block), single=True)
        self.loop = asyncio.new_event_loop()
        self.server = None
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()
        wait_until(lambda: accepting(self.port), DEADLINE, "the pymodbus server to listen")

    def _run(self):
        asyncio.set_event_loop(self.loop)

        async def serve():
            self.server = ModbusTcpServer(self.context, address=("127.0.0.1", self.port))
            await self.server.serve_forever()

        try:
            self.loop.run_until_complete(serve())
        except asyncio.CancelledError:
            pass

    def close(self):
        if self.server is not None:
            asyncio.run_coroutine_threadsafe(self.server.shutdown(), self.loop).result(DEADLINE)
        self.thread.join(DEADLINE)


def poll(host, port, polls):
    """Each poll's registers and the transaction ids of request and response."""
    client = ModbusTcpClient(host, port=port, timeout=5, retries=0)
    assert client.connect(), f"no connection to {host}:{port}"
    results = []
    try:
        for address, count in polls:
            response = client.read_holding_registers(address, count=count, device_id=1)
            assert not response.isError(), response
            results.append((address, list(response.registers), response.transaction_id))
    finally:
        client.close()
    return results


@pytest.fixture
def recording(tmp_path):
    device = ModbusDevice()
    path = tmp_path / "modbus.wtape"
    try:
        handle = bridge.record(f"type=tcp,host=127.0.0.1,port={device.port}", path,
                               listen="127.0.0.1:0", quiet=True)
        try:
            host, port = handle.address.rsplit(":", 1)
            recorded = poll(host, int(port), RECORDED_POLLS)
        finally:
            handle.stop()
            assert handle.wait(DEADLINE)
    finally:
        device.close()
    for address, registers, _ in recorded:
        assert registers == REGISTERS[address:address + len(registers)]
    return path


def test_the_recording_frames_as_modbus_tcp(recording):
    profile = _core.find_profile("modbus-tcp")
    frames = [(kind, data, description)
              for _, kind, data, description in profile.decode_session(str(recording))
              if description is not None]
    assert [kind for kind, _, _ in frames] == ["tx", "rx"] * len(RECORDED_POLLS)
    for kind, data, description in frames:
        assert profile.frame_name(kind, data) == "read holding registers"
    assert "address 10 count 3" in frames[2][2]


def test_a_reordering_client_polling_once_more_gets_its_own_transaction_ids(recording):
    handle = bridge.serve_replay(
        recording, listen="127.0.0.1:0", quiet=True,
        replay_options="timing=none,match=request,profile=modbus-tcp,repeat=last")
    polls = [(20, 1), (0, 2), (10, 3), (0, 2)]
    try:
        host, port = handle.address.rsplit(":", 1)
        results = poll(host, int(port), polls)
    finally:
        handle.stop()
        assert handle.wait(DEADLINE)
    for (address, count), (_, registers, _) in zip(polls, results):
        assert registers == REGISTERS[address:address + count]
    # pymodbus numbers its requests 1, 2, ...: the recording answered
    # address 20 under id 3, the replay under the client's.
    assert [tid for _, _, tid in results] == [1, 2, 3, 4]
    assert handle.result().ok, handle.result()


def test_without_the_profile_the_reordered_polls_do_not_match(recording):
    handle = bridge.serve_replay(recording, listen="127.0.0.1:0", quiet=True,
                                 replay_options="timing=none,match=request")
    try:
        host, port = handle.address.rsplit(":", 1)
        client = ModbusTcpClient(host, port=int(port), timeout=2, retries=0)
        assert client.connect()
        try:
            with pytest.raises(Exception):
                response = client.read_holding_registers(20, count=1, device_id=1)
                if response.isError():
                    raise RuntimeError(str(response))
        finally:
            client.close()
    finally:
        handle.stop()
        handle.wait(DEADLINE)
    assert not handle.result().ok


def test_modbus_rtu_frames_what_pymodbus_rtu_framer_builds():
    """A simulator-made RTU stream (pymodbus's own framer): requests and
    replies frame one by one, named and keyed without their CRC."""
    from pymodbus.framer import FramerRTU
    from pymodbus.pdu import DecodePDU
    from pymodbus.pdu.register_message import (ReadHoldingRegistersRequest,
                                               ReadHoldingRegistersResponse,
                                               WriteMultipleRegistersRequest,
                                               WriteMultipleRegistersResponse)
    host_side, device_side = FramerRTU(DecodePDU(False)), FramerRTU(DecodePDU(True))
    requests = [host_side.buildFrame(ReadHoldingRegistersRequest(address=5, count=2, dev_id=1)),
                host_side.buildFrame(WriteMultipleRegistersRequest(address=1, registers=[7, 8, 9],
                                                                   dev_id=3))]
    replies = [device_side.buildFrame(ReadHoldingRegistersResponse(registers=[1, 2], dev_id=1)),
               device_side.buildFrame(WriteMultipleRegistersResponse(address=1, count=3, dev_id=3))]
    profile = _core.find_profile("modbus-rtu")
    assert profile.frames("tx", b"".join(requests)) == requests
    assert profile.frames("rx", b"".join(replies)) == replies
    assert profile.frame_name("tx", requests[1]) == "write multiple registers"
    assert "address 5 count 2" in profile.describe("tx", requests[0])
    assert profile.match_key(requests[0]) == requests[0][:-2]
