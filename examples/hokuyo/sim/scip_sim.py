"""A simulated Hokuyo URG-04LX / UTM-30LX speaking SCIP 2.0 (and enough of
SCIP 1.1 to be switched to 2.0), for making recordings without hardware.

The device model (`Device`) is transport-free: `handle_line()` answers one
command, `due_scans()` yields the stream scans whose time has come. `serve()`
connects it to a pty or a TCP listener.

Behaviour worth knowing (chosen to follow real units):
- the URG-04LX powers on in SCIP 1.1: any command but `SCIP2.0` is echoed with
  the 1.1 status `E` (no sum), which no SCIP 2.0 driver takes for a valid
  reply; the UTM-30LX powers on in SCIP 2.0;
- the laser is off at power-on; GD/GS with the laser off answer `10`; MD/MS/ME
  turn it on for the stream and off again once the count is done;
- GD/GS are answered on the next scan boundary (100 ms URG, 25 ms UTM);
  stream scans come on boundaries too, skipping `interval` scans between;
- `SS` answers first, then changes the line speed; `DBnn` (a debug command)
  makes the device report hardware fault `nn` to scan commands (`DB00`
  clears it); `TM0/TM1/TM2` enter, read and leave time adjust mode.
"""

import math
import os
import select
import socket
import sys
import termios
import time
import tty

SCAN_LINE = 64  # characters of scan data per line


def checksum(data: bytes) -> bytes:
    return bytes([(sum(data) & 0x3F) + 0x30])


def encode(value: int, digits: int) -> bytes:
    out = bytearray()
    for shift in range(digits - 1, -1, -1):
        out.append(((value >> (6 * shift)) & 0x3F) + 0x30)
    return bytes(out)


def data_line(data: bytes, spoil=False) -> bytes:
    """A data line with its sum (a wrong one when `spoil`)."""
    sum_byte = checksum(data)
    if spoil:
        sum_byte = bytes([0x30 + ((sum_byte[0] - 0x30 + 1) & 0x3F)])
    return data + sum_byte + b"\n"


def status_line(status: bytes) -> bytes:
    return status + checksum(status) + b"\n"


def param_line(text: str) -> bytes:
    data = text.encode("ascii")
    return data + b";" + checksum(data) + b"\n"


MODELS = {
    "urg04lx": {
        "vend": "Hokuyo Automatic Co.,Ltd.",
        "prod": "SOKUIKI Sensor URG-04LX",
        "firm": "3.1.04(02/Aug./2007)",
        "seri": "H0706400",
        "modl": "URG-04LX(Hokuyo Automatic Co.,Ltd.)",
        "dmin": 20, "dmax": 5600, "ares": 1024, "amin": 44, "amax": 725,
        "afrt": 384, "scan_rpm": 600,
        "scip1_at_power_on": True,
        "sbps": "19200[bps]",
        "cr_already": b"03",
        "has_me": False,
    },
    "utm30lx": {
        "vend": "Hokuyo Automatic Co.,Ltd.",
        "prod": "SOKUIKI Sensor TOP-URG UTM-30LX",
        "firm": "P.1.05(17/Apr./2009)",
        "seri": "00903971",
        "modl": "UTM-30LX(Hokuyo Automatic Co.,Ltd.)",
        "dmin": 23, "dmax": 60000, "ares": 1440, "amin": 0, "amax": 1080,
        "afrt": 540, "scan_rpm": 2400,
        "scip1_at_power_on": False,
        "sbps": "USB Full Speed",
        "cr_already": b"04",
        "has_me": True,
    },
}

BAUDS = {19200, 38400, 57600, 115200, 250000, 500000, 750000}


class Device:
    """One simulated scanner. Times are seconds on time.monotonic()."""

    def __init__(self, model="urg04lx", scip2=None, laser_on=False,
                 start_time_ms=0, bad_sum=(), garbage=(), now=None):
        self.model_name = model
        self.model = MODELS[model]
        self.opened_at = time.monotonic() if now is None else now
        self.period = 60.0 / self.model["scan_rpm"]
        self.start_time_ms = start_time_ms
        # Each entry spoils one reply; repeat a command to spoil several.
        self.bad_sum = [c.upper().encode() for c in bad_sum]
        self.garbage = [c.upper().encode() for c in garbage]
        self.baud = 19200
        self.baud_changed = None  # set by SS; the transport applies it
        self.power_on(scip2)
        self.laser = laser_on

    def power_on(self, scip2=None):
        self.scip2 = (not self.model["scip1_at_power_on"]) if scip2 is None else scip2
        self.laser = False
        self.time_mode = False
        self.fault = None
        self.stream = None
        self.scan_index = 0
        self.clock_started = False

    # --- time -----------------------------------------------------------
    def timestamp_ms(self, now):
        elapsed = int(round((now - self.opened_at) * 1000))
        return (self.start_time_ms + elapsed) & 0xFFFFFF

    def next_boundary(self, now):
        k = math.floor((now - self.opened_at) / self.period) + 1
        return self.opened_at + k * self.period

    # --- scans -----------------------------------------------------------
    def ranges(self, first, last, cluster, index):
        """A rectangular room seen from off-centre; a slow sway per scan
        makes consecutive scans differ."""
        m = self.model
        values = []
        step = first
        while step <= last:
            group = []
            for s in range(step, min(step + cluster, last + 1)):
                angle = (s - m["afrt"]) * 2 * math.pi / m["ares"]
                c, sn = abs(math.cos(angle)), abs(math.sin(angle))
                wall_x = 2500 if math.cos(angle) >= 0 else 1800
                wall_y = 1600 if math.sin(angle) >= 0 else 2100
                d = min(wall_x / c if c > 1e-9 else 1e9, wall_y / sn if sn > 1e-9 else 1e9)
                d += 7 * ((s * 13 + index * 5) % 11)
                group.append(int(max(m["dmin"], min(m["dmax"], d))))
            values.append(min(group))  # a cluster reports its nearest range
            step += cluster
        return values

    def scan_data(self, kind, first, last, cluster, now):
        index = self.scan_index
        self.scan_index += 1
        ranges = self.ranges(first, last, cluster, index)
        data = bytearray()
        for i, r in enumerate(ranges):
            if kind in (b"GS", b"MS"):
                data += encode(min(r, 4095), 2)
            else:
                data += encode(r, 3)
            if kind == b"ME":
                data += encode(1000 + (first + i * cluster) * 7 % 900, 3)
        spoil = kind in self.bad_sum
        if spoil:
            self.bad_sum.remove(kind)
        chunks = [encode(self.timestamp_ms(now), 4)]
        chunks += [bytes(data[at:at + SCAN_LINE]) for at in range(0, len(data), SCAN_LINE)]
        # A spoiled reply breaks in its middle, with more lines still to come.
        spoiled = len(chunks) // 2 if spoil else -1
        return b"".join(data_line(c, i == spoiled) for i, c in enumerate(chunks)) + b"\n"

    # --- commands ---------------------------------------------------------
    def handle_line(self, line: bytes, now):
        """Answers one command line (without its terminator). Returns a list
        of (due_time, bytes)."""
        if not self.clock_started:
            # The clock (and the scan boundaries) start with the first
            # command, so that --start-time-ms places the wrap where a test
            # wants it however long the client took to start.
            self.opened_at = now
            self.clock_started = True
        replies = self.answer(line, now)
        cmd = line[:2].upper()
        if replies and cmd in self.garbage:
            self.garbage.remove(cmd)
            due, data = replies[0]
            replies[0] = (due, b"\x00\xff#!garbage\n" + data)
        return replies

    def answer(self, line, now):
        if not self.scip2:
            if line == b"SCIP2.0":
                self.scip2 = True
                return [(now, b"SCIP2.0\n0\n\n")]
            return [(now, line + b"\nE\n\n")]
        cmd = line[:2]
        simple = lambda status, body=b"": [(now, line + b"\n" + status_line(status) + body + b"\n")]
        if line == b"SCIP2.0":
            return simple(b"0E")
        if cmd == b"VV" and len(line) == 2:
            m = self.model
            return simple(b"00", param_line("VEND:" + m["vend"]) + param_line("PROD:" + m["prod"])
                          + param_line("FIRM:" + m["firm"]) + param_line("PROT:SCIP 2.0")
                          + param_line("SERI:" + m["seri"]))
        if cmd == b"PP" and len(line) == 2:
            m = self.model
            return simple(b"00", param_line("MODL:" + m["modl"]) + param_line("DMIN:%d" % m["dmin"])
                          + param_line("DMAX:%d" % m["dmax"]) + param_line("ARES:%d" % m["ares"])
                          + param_line("AMIN:%d" % m["amin"]) + param_line("AMAX:%d" % m["amax"])
                          + param_line("AFRT:%d" % m["afrt"]) + param_line("SCAN:%d" % m["scan_rpm"]))
        if cmd == b"II" and len(line) == 2:
            m = self.model
            sbps = m["sbps"] if m["sbps"].startswith("USB") else "%d[bps]" % self.baud
            stat = "Sensor works well." if self.fault is None else \
                "Hardware trouble (status %s)." % self.fault.decode()
            return simple(b"00", param_line("MODL:" + m["modl"])
                          + param_line("LASR:" + ("ON" if self.laser else "OFF"))
                          + param_line("SCSP:Initial(%d[rpm])<-Default setting by user" % m["scan_rpm"])
                          + param_line("MESM:CLASSIC") + param_line("SBPS:" + sbps)
                          + param_line("TIME:%06X" % self.timestamp_ms(now))
                          + param_line("STAT:" + stat))
        if cmd == b"BM" and len(line) == 2:
            if self.fault is not None:
                return simple(b"01")
            if self.laser:
                return simple(b"02")
            self.laser = True
            return simple(b"00")
        if cmd == b"QT" and len(line) == 2:
            self.stream = None
            self.laser = False
            return simple(b"00")
        if cmd == b"RS" and len(line) == 2:
            self.stream = None
            self.laser = False
            self.time_mode = False
            return simple(b"00")
        if cmd == b"TM" and len(line) == 3:
            arg = line[2:3]
            if arg == b"0":
                if self.time_mode:
                    return simple(b"02")
                self.time_mode = True
                return simple(b"00")
            if arg == b"1":
                if not self.time_mode:
                    return simple(b"01")
                stamp = encode(self.timestamp_ms(now), 4)
                return simple(b"00", stamp + checksum(stamp) + b"\n")
            if arg == b"2":
                if not self.time_mode:
                    return simple(b"03")
                self.time_mode = False
                return simple(b"00")
            return simple(b"0C")
        if cmd == b"SS" and len(line) == 8:
            try:
                baud = int(line[2:])
            except ValueError:
                return simple(b"01")
            if self.model["sbps"].startswith("USB"):
                return simple(b"04")
            if baud not in BAUDS:
                return simple(b"01")
            if baud == self.baud:
                return simple(b"03")
            self.baud = baud
            self.baud_changed = baud
            return simple(b"00")
        if cmd == b"CR" and len(line) == 4:
            return simple(self.model["cr_already"] if line[2:] == b"00" else b"00")
        if cmd == b"DB" and len(line) == 4:
            code = line[2:]
            self.fault = None if code == b"00" else code
            if self.fault is not None:
                self.stream = None
            return simple(b"00")
        if cmd in (b"GD", b"GS") and len(line) == 12:
            return self.single_scan(line, now)
        if cmd in (b"MD", b"MS", b"ME") and len(line) == 15:
            if cmd == b"ME" and not self.model["has_me"]:
                return simple(b"0E")
            return self.start_stream(line, now)
        return simple(b"0E")

    def scan_arguments(self, line):
        """(first, last, cluster) or an error status."""
        m = self.model
        try:
            first = int(line[2:6])
        except ValueError:
            return b"01"
        try:
            last = int(line[6:10])
        except ValueError:
            return b"02"
        try:
            cluster = int(line[10:12])
        except ValueError:
            return b"03"
        if last > m["amax"] or first < m["amin"]:
            return b"04"
        if last < first:
            return b"05"
        return first, last, max(cluster, 1)

    def single_scan(self, line, now):
        args = self.scan_arguments(line)
        if isinstance(args, bytes):
            return [(now, line + b"\n" + status_line(args) + b"\n")]
        if self.fault is not None:
            return [(now, line + b"\n" + status_line(self.fault) + b"\n")]
        if not self.laser:
            return [(now, line + b"\n" + status_line(b"10") + b"\n")]
        due = self.next_boundary(now)
        body = self.scan_data(line[:2], *args, due)
        return [(due, line + b"\n" + status_line(b"00") + body)]

    def start_stream(self, line, now):
        args = self.scan_arguments(line)
        if isinstance(args, bytes):
            return [(now, line + b"\n" + status_line(args) + b"\n")]
        try:
            interval = int(line[12:13])
        except ValueError:
            return [(now, line + b"\n" + status_line(b"06") + b"\n")]
        try:
            count = int(line[13:15])
        except ValueError:
            return [(now, line + b"\n" + status_line(b"07") + b"\n")]
        if self.fault is not None:
            return [(now, line + b"\n" + status_line(self.fault) + b"\n")]
        self.laser = True
        self.stream = {
            "prefix": line[:13], "args": args, "interval": interval,
            "count": count, "left": count, "next": self.next_boundary(now),
        }
        return [(now, line + b"\n" + status_line(b"00") + b"\n")]

    def next_stream_time(self):
        return None if self.stream is None else self.stream["next"]

    def due_scans(self, now):
        """The stream scans due by `now`."""
        out = []
        while self.stream is not None and self.stream["next"] <= now:
            s = self.stream
            due = s["next"]
            s["next"] = due + self.period * (s["interval"] + 1)
            if s["count"]:
                s["left"] -= 1
                remaining = s["left"]
            else:
                remaining = 0
            echo = s["prefix"] + b"%02d" % remaining
            out.append((due, echo + b"\n" + status_line(b"99")
                        + self.scan_data(s["prefix"][:2], *s["args"], due)))
            if s["count"] and remaining == 0:
                self.stream = None
                self.laser = False
        return out


class LineSplitter:
    """Cuts a byte stream into command lines (LF or CR ends a command)."""

    def __init__(self, limit=256):
        self.buffer = bytearray()
        self.limit = limit

    def feed(self, data):
        self.buffer += data
        lines = []
        while True:
            ends = [i for i in (self.buffer.find(b"\n"), self.buffer.find(b"\r")) if i >= 0]
            if not ends:
                break
            end = min(ends)
            line = bytes(self.buffer[:end])
            del self.buffer[:end + 1]
            if line:
                lines.append(line)
        if len(self.buffer) > self.limit:  # no terminator in sight: noise
            self.buffer.clear()
        return lines


def run_session(device, read_fd, write, wait_fd, log, stop, apply_baud=None):
    """Serves one connection until `stop()` or the peer goes away. A line
    speed change (SS) is applied once its reply has been written."""
    splitter = LineSplitter()
    pending = []  # (due, seq, bytes), sent in order of due time
    seq = 0
    while not stop():
        now = time.monotonic()
        for item in device.due_scans(now):
            pending.append((item[0], seq, item[1]))
            seq += 1
        pending.sort()
        while pending and pending[0][0] <= now:
            _, _, data = pending.pop(0)
            write(data)
            if device.baud_changed is not None:
                log("line speed %d" % device.baud_changed)
                if apply_baud is not None:
                    apply_baud(device.baud_changed)
                device.baud_changed = None
        deadlines = [p[0] for p in pending]
        if device.next_stream_time() is not None:
            deadlines.append(device.next_stream_time())
        timeout = 0.5 if not deadlines else max(0.0, min(min(deadlines) - now, 0.5))
        ready, _, _ = select.select([wait_fd], [], [], timeout)
        if not ready:
            continue
        data = read_fd()
        if data is None:
            return
        now = time.monotonic()
        for line in splitter.feed(data):
            log("<- %r" % line)
            for due, reply in device.handle_line(line, now):
                pending.append((due, seq, reply))
                seq += 1


def serve_pty(device, link, log, stop, ready):
    master, slave = os.openpty()
    path = os.ttyname(slave)
    # Only clients hold the terminal open: a terminal left open here would
    # keep a client's exclusive lock (TIOCEXCL) after it closed, and the
    # next client (not root) would get EBUSY. Terminal settings made through
    # the master apply to the client's side.
    os.close(slave)
    tty.setraw(master)
    if link:
        try:
            os.unlink(link)
        except FileNotFoundError:
            pass
        os.symlink(path, link)
    ready("pty=%s link=%s" % (path, link or path))
    os.set_blocking(master, False)

    def read_fd():
        try:
            return os.read(master, 4096)
        except BlockingIOError:
            return b""
        except OSError:
            # EIO: no client has the terminal open. It polls readable until
            # one does, so wait a little instead of spinning.
            time.sleep(0.05)
            return b""

    def write(data):
        # A device keeps talking whether or not anyone reads: when the
        # terminal's buffer stays full (no client, or one that stopped
        # reading), the rest is lost, as on a real line.
        view = memoryview(data)
        while view:
            try:
                view = view[os.write(master, view):]
            except BlockingIOError:
                if not select.select([], [master], [], 0.5)[1]:
                    log("nobody reads: %d bytes dropped" % len(view))
                    return
            except OSError:
                log("no client: %d bytes dropped" % len(view))
                return

    def apply_baud(baud):
        # The terminal's speed is what a driver on the other side sees.
        speed = getattr(termios, "B%d" % baud, None)
        if speed is None:
            log("no termios speed for %d; left unchanged" % baud)
            return
        attrs = termios.tcgetattr(master)
        attrs[4] = attrs[5] = speed
        termios.tcsetattr(master, termios.TCSADRAIN, attrs)

    try:
        run_session(device, read_fd, write, master, log, stop, apply_baud)
    finally:
        if link:
            try:
                os.unlink(link)
            except FileNotFoundError:
                pass
        os.close(master)


def serve_tcp(device, host, port, log, stop, ready):
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    server.bind((host, port))
    server.listen(1)
    ready("tcp=%s:%d" % server.getsockname()[:2])
    try:
        while not stop():
            ready_list, _, _ = select.select([server], [], [], 0.5)
            if not ready_list:
                continue
            client, peer = server.accept()
            log("client %s:%d" % peer[:2])
            client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

            def read_fd():
                try:
                    data = client.recv(4096)
                except ConnectionError:
                    return None
                return data or None

            try:
                run_session(device, read_fd, client.sendall, client, log, stop)
            except (BrokenPipeError, ConnectionError):
                pass
            finally:
                client.close()
            device.power_on()
            log("client gone; device reset")
    finally:
        server.close()
