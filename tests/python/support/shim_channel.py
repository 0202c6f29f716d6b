"""The side channel between the --as shim and the bridge, as tests speak it
(src/shim/line_protocol.h): its messages, and a bridge's end that answers
every request at once and keeps what it was asked."""

import socket
import struct
import threading

# struct wt_line_request and wt_line_reply (src/shim/line_protocol.h).
REQUEST = struct.Struct("=IIQIIII")
REPLY = struct.Struct("=iIIIII")
MAGIC = 0x57544C31
OPS = {1: "hello", 2: "set_outputs", 3: "break", 4: "break_on", 5: "break_off",
       6: "settings", 7: "drain", 8: "get", 9: "wait"}
TIOCM_DTR, TIOCM_RTS, TIOCM_CTS, TIOCM_CD, TIOCM_RI, TIOCM_DSR = 0x2, 0x4, 0x20, 0x40, 0x80, 0x100


class FakeBridge:
    """The bridge's end of the side channel: answers every request at once,
    TIOCMGET with `lines`, and keeps what it was asked."""

    def __init__(self, path, lines=TIOCM_CTS | TIOCM_RI, counts=(3, 4, 5, 6)):
        self.lines = lines
        self.counts = counts
        self.requests = []
        self._server = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        self._server.bind(path)
        self._server.listen(8)
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self):
        while True:
            try:
                connection, _ = self._server.accept()
            except OSError:
                return
            threading.Thread(target=self._answer, args=(connection,), daemon=True).start()

    def _answer(self, connection):
        with connection:
            while True:
                message = connection.recv(REQUEST.size)
                if not message:
                    return
                magic, op, written, set_bits, clear_bits, value, _ = REQUEST.unpack(message)
                assert magic == MAGIC
                self.requests.append({"op": OPS[op], "written": written, "set": set_bits,
                                      "clear": clear_bits, "value": value})
                connection.send(REPLY.pack(0, self.lines, *self.counts))

    def ops(self):
        return [(r["op"], r["written"], r["set"], r["clear"], r["value"])
                for r in self.requests if r["op"] != "hello"]

    def close(self):
        self._server.close()
