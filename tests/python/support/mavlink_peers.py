"""The two ends of a MAVLink link, both made with pymavlink, for
tests/python/clients/test_mavlink.py.

``Vehicle`` is the device: a small MAVLink 2 autopilot (dialect ``common``)
on TCP or UDP, or a component of it on a serial line (a pty), that sends a HEARTBEAT every second to whoever it talks to,
answers each HEARTBEAT of a ground station with one of its own, and
answers PARAM_REQUEST_LIST with one PARAM_VALUE per parameter of
``PARAMETERS``. It runs in a thread of the test.

Run as a script, this file is the ground station (a separate process, so
that pymavlink's MAVLINK20/dialect choice, made at import, is its own):

    python mavlink_peers.py CONNECTION     # tcp:HOST:PORT, udpout:HOST:PORT or a pty

It connects with ``mavutil.mavlink_connection``, sends a HEARTBEAT (a GCS
announces itself; on UDP that is how the vehicle learns its address), waits
for the vehicle's, fetches the parameter list and prints one JSON line:
``{"heartbeat": {...}, "params": {NAME: VALUE, ...}}``. It exits 1 with a
message on stderr when the heartbeat or a parameter does not come within
``--timeout`` seconds."""

import argparse
import json
import os
import select
import socket
import sys
import threading
import time

VEHICLE_SYSTEM = 7
VEHICLE_COMPONENT = 1
GCS_SYSTEM = 255
HEARTBEAT_PERIOD_S = 1.0
_POLL_S = 0.05

PARAMETERS = {
    "SYSID_THISMAV": 7.0,
    "BATT_CAPACITY": 5200.0,
    "RTL_ALT": 1500.0,
    "WPNAV_SPEED": 750.0,
    "FENCE_RADIUS": 300.0,
}


class Vehicle:
    """A MAVLink vehicle on ``transport`` ("tcp" or "udp") at 127.0.0.1.

    ``options`` is the wiretape option string that reaches it.
    ``param_requests`` counts the PARAM_REQUEST_LISTs it answered."""

    def __init__(self, transport, component=VEHICLE_COMPONENT):
        from pymavlink.dialects.v20 import common as mavlink2

        self._mavlink = mavlink2
        self._mav = mavlink2.MAVLink(None, srcSystem=VEHICLE_SYSTEM, srcComponent=component)
        self.transport = transport
        self.param_requests = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        if transport == "pty":
            # A component on a serial line: the device end is the terminal
            # (``path``); the component reads and writes its master.
            import tty

            self._master, self._terminal = os.openpty()
            tty.setraw(self._terminal)
            self.path = os.ttyname(self._terminal)
            self.options = f"type=serial,device={self.path}"
            self._socket = None
            self._thread.start()
            return
        kind = socket.SOCK_STREAM if transport == "tcp" else socket.SOCK_DGRAM
        self._socket = socket.socket(socket.AF_INET, kind)
        self._socket.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self._socket.bind(("127.0.0.1", 0))
        if transport == "tcp":
            self._socket.listen(1)
        self.port = self._socket.getsockname()[1]
        self.options = f"type={transport},host=127.0.0.1,port={self.port}"
        self._thread.start()

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.close()

    def close(self):
        self._stop.set()
        self._thread.join(10.0)
        if self._socket is None:
            os.close(self._master)
            os.close(self._terminal)
        else:
            self._socket.close()

    # --- MAVLink -------------------------------------------------------------------

    def _heartbeat(self):
        m = self._mavlink
        return self._mav.heartbeat_encode(
            m.MAV_TYPE_QUADROTOR, m.MAV_AUTOPILOT_ARDUPILOTMEGA,
            m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 0, m.MAV_STATE_STANDBY).pack(self._mav)

    def _parameters(self):
        m = self._mavlink
        return [self._mav.param_value_encode(name.encode(), value, m.MAV_PARAM_TYPE_REAL32,
                                             len(PARAMETERS), index).pack(self._mav)
                for index, (name, value) in enumerate(PARAMETERS.items())]

    def _answers(self, parser, data):
        """The messages (packed) that answer what the ground station sent."""
        answers = []
        for message in parser.parse_buffer(data) or []:
            kind = message.get_type()
            if kind == "HEARTBEAT":
                answers.append(self._heartbeat())
            elif kind == "PARAM_REQUEST_LIST":
                self.param_requests += 1
                answers.extend(self._parameters())
        return answers

    # --- transports ----------------------------------------------------------------------

    def _run(self):
        if self.transport == "tcp":
            self._run_tcp()
        elif self.transport == "pty":
            self._run_pty()
        else:
            self._run_udp()

    def _run_pty(self):
        parser = self._mavlink.MAVLink(None)
        next_beat = time.monotonic()
        while not self._stop.is_set():
            if time.monotonic() >= next_beat:
                next_beat += HEARTBEAT_PERIOD_S
                os.write(self._master, self._heartbeat())
            ready, _, _ = select.select([self._master], [], [], _POLL_S)
            if not ready:
                continue
            try:
                data = os.read(self._master, 65536)
            except OSError:  # EIO: nobody has the terminal open (yet)
                continue
            for packet in self._answers(parser, data):
                os.write(self._master, packet)

    def _run_tcp(self):
        while not self._stop.is_set():
            ready, _, _ = select.select([self._socket], [], [], _POLL_S)
            if not ready:
                continue
            connection, _ = self._socket.accept()
            parser = self._mavlink.MAVLink(None)
            with connection:
                next_beat = time.monotonic()
                while not self._stop.is_set():
                    if time.monotonic() >= next_beat:
                        next_beat += HEARTBEAT_PERIOD_S
                        if not self._send_all(connection, [self._heartbeat()]):
                            break
                    ready, _, _ = select.select([connection], [], [], _POLL_S)
                    if not ready:
                        continue
                    data = connection.recv(65536)
                    if not data or not self._send_all(connection, self._answers(parser, data)):
                        break

    @staticmethod
    def _send_all(connection, packets):
        try:
            for packet in packets:
                connection.sendall(packet)
        except OSError:
            return False
        return True

    def _run_udp(self):
        parser = self._mavlink.MAVLink(None)
        ground_station = None
        next_beat = None
        while not self._stop.is_set():
            if ground_station is not None and time.monotonic() >= next_beat:
                next_beat += HEARTBEAT_PERIOD_S
                self._socket.sendto(self._heartbeat(), ground_station)
            ready, _, _ = select.select([self._socket], [], [], _POLL_S)
            if not ready:
                continue
            data, ground_station = self._socket.recvfrom(65535)
            if next_beat is None:
                next_beat = time.monotonic() + HEARTBEAT_PERIOD_S
            for packet in self._answers(parser, data):
                # One message a datagram, as MAVLink over UDP is sent.
                self._socket.sendto(packet, ground_station)


# --- the ground station (run as a script) ---------------------------------------------------


def ground_station(connection, timeout_s):
    """Connects, says hello, returns (heartbeat, params) or raises
    RuntimeError saying what did not come."""
    os.environ.setdefault("MAVLINK20", "1")
    os.environ.setdefault("MAVLINK_DIALECT", "common")
    from pymavlink import mavutil

    link = mavutil.mavlink_connection(connection, source_system=GCS_SYSTEM,
                                      source_component=0, dialect="common")
    try:
        link.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS,
                                mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        heartbeat = link.recv_match(type="HEARTBEAT", blocking=True, timeout=timeout_s)
        if heartbeat is None:
            raise RuntimeError(f"no HEARTBEAT from {connection} within {timeout_s} s")
        link.target_system = heartbeat.get_srcSystem()
        link.target_component = heartbeat.get_srcComponent()
        link.param_fetch_all()
        params = {}
        expected = None
        end = time.monotonic() + timeout_s
        while expected is None or len(params) < expected:
            left = end - time.monotonic()
            message = link.recv_match(type="PARAM_VALUE", blocking=True,
                                      timeout=max(left, 0.0)) if left > 0 else None
            if message is None:
                raise RuntimeError(f"the parameter list from {connection} stopped at "
                                   f"{len(params)} of {expected} within {timeout_s} s")
            expected = message.param_count
            params[message.param_id] = message.param_value
        return ({"system": heartbeat.get_srcSystem(),
                 "component": heartbeat.get_srcComponent(),
                 "type": heartbeat.type, "autopilot": heartbeat.autopilot,
                 "mavlink_version": 2 if heartbeat.get_msgbuf()[0] == 0xFD else 1},
                params)
    finally:
        link.close()


def main(argv=None):
    parser = argparse.ArgumentParser(description="a pymavlink ground station")
    parser.add_argument("connection", help="tcp:HOST:PORT or udpout:HOST:PORT")
    parser.add_argument("--timeout", type=float, default=20.0)
    args = parser.parse_args(argv)
    try:
        heartbeat, params = ground_station(args.connection, args.timeout)
    except RuntimeError as error:
        print(f"ground station: {error}", file=sys.stderr)
        return 1
    print(json.dumps({"heartbeat": heartbeat, "params": params}, sort_keys=True), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
