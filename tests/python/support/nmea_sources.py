"""Small simulated NMEA receivers for the tests of several sources at once
(issue 25): one on a pseudo-terminal, one a TCP server, one streaming UDP
datagrams to an address. Each sends a GGA+RMC fix at 5 Hz at its own
position (``latitude``), so that a reader can tell whose fixes it got; and
``Gpspipe`` collects gpsd's TPV reports per device path."""

import json
import os
import select
import socket
import subprocess
import threading
import time
import tty

# How often a receiver sends a fix (seconds): 5 Hz.
FIX_PERIOD_S = 0.2


def sentence(body):
    checksum = 0
    for byte in body.encode():
        checksum ^= byte
    return f"${body}*{checksum:02X}\r\n".encode()


def nmea_fix(latitude, tick):
    """A GGA and an RMC sentence at `latitude` (north, in degrees), 11.5167 E;
    `tick` counts fixes (a new second every 5)."""
    hhmmss = f"1235{(tick // 5) % 60:02d}"
    fraction = f"{(tick % 5) * 20:02d}"
    degrees = int(latitude)
    minutes = (latitude - degrees) * 60
    lat = f"{degrees:02d}{minutes:06.3f}"
    return (sentence(f"GPGGA,{hhmmss}.{fraction},{lat},N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,")
            + sentence(f"GPRMC,{hhmmss}.{fraction},A,{lat},N,01131.000,E,022.4,084.4,230394,"
                       "003.1,W"))


class _Source:
    """A thread sending a fix every FIX_PERIOD_S through `send` until closed."""

    def __init__(self, latitude):
        self.latitude = latitude
        self.sent = 0  # fixes sent (or tried: nobody may be there yet)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def start(self):
        self._thread.start()
        return self

    def _run(self):
        tick = 0
        while not self._stop.wait(FIX_PERIOD_S):
            try:
                self.send(nmea_fix(self.latitude, tick))
            except OSError:
                pass  # nobody there yet (or any more): the next fix tries again
            tick += 1
            self.sent = tick

    def send(self, data):
        raise NotImplementedError

    def close(self):
        self._stop.set()
        self._thread.join(10.0)

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.close()


class PtyNmeaSource(_Source):
    """A receiver on a serial line: ``path`` is the terminal a proxy opens
    as the device."""

    def __init__(self, latitude):
        super().__init__(latitude)
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        self.path = os.ttyname(self._slave)
        self.options = f"type=serial,device={self.path}"

    def send(self, data):
        # Drain what the other side wrote (nothing, from a read-only gpsd),
        # so that a full buffer never blocks the receiver.
        while select.select([self._master], [], [], 0)[0]:
            os.read(self._master, 4096)
        os.write(self._master, data)

    def close(self):
        super().close()
        os.close(self._master)
        os.close(self._slave)


class TcpNmeaSource(_Source):
    """A receiver that serves its fixes over TCP (a caster, ser2net):
    every connected client gets them."""

    def __init__(self, latitude):
        super().__init__(latitude)
        self._server = socket.socket()
        self._server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self._server.bind(("127.0.0.1", 0))
        self._server.listen(4)
        self._server.setblocking(False)
        self.port = self._server.getsockname()[1]
        self.options = f"type=tcp,host=127.0.0.1,port={self.port}"
        self._clients = []

    def send(self, data):
        while True:
            try:
                client, _ = self._server.accept()
            except BlockingIOError:
                break
            self._clients.append(client)
        for client in list(self._clients):
            try:
                client.sendall(data)
            except OSError:
                self._clients.remove(client)
                client.close()

    def close(self):
        super().close()
        for client in self._clients:
            client.close()
        self._server.close()


class UdpNmeaSource(_Source):
    """A receiver that streams its fixes as datagrams to `destination`
    (host, port): gpsd's ``udp://`` source."""

    def __init__(self, latitude, destination):
        super().__init__(latitude)
        self.destination = destination
        self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    def send(self, data):
        self._socket.sendto(data, self.destination)

    def close(self):
        super().close()
        self._socket.close()


def free_port(kind=socket.SOCK_STREAM):
    with socket.socket(socket.AF_INET, kind) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def listening(port):
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=1.0):
            return True
    except OSError:
        return False


def start_gpsd(port, sources, directory):
    """gpsd on TCP `port`, read-only (-b), opening every source at once
    (-n), in the foreground (-N)."""
    return subprocess.Popen(["gpsd", "-N", "-n", "-b", "-S", str(port),
                             "-F", str(directory / f"gpsd-{port}.sock"), *sources],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def stop(child, deadline_s=20.0):
    if child is None or child.poll() is not None:
        return
    child.terminate()
    try:
        child.wait(timeout=deadline_s)
    except subprocess.TimeoutExpired:
        child.kill()
        child.wait()


def fixes_by_device(port, devices, deadline_s, watching=None):
    """gpspipe -w on gpsd at `port` until each of `devices` (TPV ``device``
    paths) has reported a fix, or the deadline: {device: latitude}.
    `watching` is called once gpsd has answered gpspipe's watch (a feed
    started then is reported from its first fix)."""
    gpspipe = subprocess.Popen(["gpspipe", "-w", f"127.0.0.1:{port}"],
                               stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    fixes = {}
    try:
        if watching is not None:
            gpspipe.stdout.readline()  # gpsd's VERSION: the watch is set
            watching()
        end = time.monotonic() + deadline_s
        buffered = b""
        while not set(devices) <= set(fixes) and time.monotonic() < end:
            ready, _, _ = select.select([gpspipe.stdout], [], [], end - time.monotonic())
            if not ready:
                break
            chunk = gpspipe.stdout.read1(65536)
            if not chunk:
                break
            buffered += chunk
            *complete, buffered = buffered.split(b"\n")
            for line in complete:
                try:
                    report = json.loads(line)
                except ValueError:
                    continue
                if report.get("class") == "TPV" and "lat" in report and "device" in report:
                    fixes[report["device"]] = report["lat"]
    finally:
        stop(gpspipe)
    return fixes
