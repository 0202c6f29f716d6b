"""Serial lines through ``--as`` to a line exported over RFC 2217 (DESIGN
§20, §28): `record --device rfc2217://HOST:PORT --as PATH -- CMD` sends the
program's custom baud, DTR pulse and break to the exporter as RFC 2217
requests, in order among its bytes, and records them as it does for a local
serial port; the replay of that recording passes the same program.

The exporter is `wiretape serve --protocol rfc2217` in front of a replay of
the board (test_serial_lines.py's), recording what it is sent: the pulse and
the break reach it as RFC 2217 requests, in their place among the bytes."""

import sys

import pytest

from wiretape import bridge

from test_serial_lines import (HARD_CODED, board_session, joined, reset_board,  # noqa: F401
                               timeline, wiretape_cli)

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="the preload shim is Linux only")

DEADLINE = 10.0


@pytest.fixture
def exported_board(tmp_path):
    device = board_session(tmp_path / "board.wtape")
    handle = bridge.serve(f"type=replay,file={device},timing=none,check=off", "127.0.0.1:0",
                          protocol="rfc2217", output=tmp_path / "exporter.wtape", quiet=True)
    yield handle
    handle.stop()
    assert handle.wait(DEADLINE)


LINES_AND_BYTES = [
    ("tx", b"HELLO\n"),
    ("modem_lines", {"dtr": False}),
    ("modem_lines", {"dtr": True}),
    ("tx", b"SYNC\n"),
    ("break", {"duration_ms": 250}),
    ("tx", b"PING\n"),
    ("rx", b"PONG\n"),
]


def test_record_sends_the_pulse_the_break_and_the_baud_to_the_exporter(tmp_path, reset_board,
                                                                       exported_board):
    recording = tmp_path / "reset.wtape"
    done = wiretape_cli("record", "--device", "rfc2217://" + exported_board.address,
                        "--as", HARD_CODED, "-o", str(recording), "-q", "--", reset_board)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "cts=1 dtr=1\nread: PONG\n"
    events = joined(timeline(recording))
    assert [what["baud"] for kind, what in events if kind == "settings"][-1] == 250000
    assert [(kind, what) for kind, what in events if kind != "settings"] == LINES_AND_BYTES
    # The exporter was sent the same, in the same order.
    exported_board.stop()
    assert exported_board.wait(DEADLINE)
    assert exported_board.result().ok, exported_board.result()
    exported = joined(timeline(tmp_path / "exporter.wtape"))
    assert [what["baud"] for kind, what in exported if kind == "settings"][-1] == 250000
    # RFC 2217 has no timed break: the exporter holds it from BREAK on to
    # BREAK off, as long as the client waited and the requests took.
    breaks = [what for kind, what in exported if kind == "break"]
    assert len(breaks) == 1 and 250 <= breaks[0]["duration_ms"] < 250 + DEADLINE * 1000, breaks
    breaks[0]["duration_ms"] = 250
    assert [(kind, what) for kind, what in exported if kind != "settings"] == LINES_AND_BYTES, \
        exported

    replayed = wiretape_cli("replay", str(recording), "--as", HARD_CODED, "-q", "--",
                            reset_board)
    assert replayed.returncode == 0, replayed.stderr
    assert replayed.stdout == "cts=1 dtr=1\nread: PONG\n"
