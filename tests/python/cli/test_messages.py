"""The command line's messages (issue 26): one prefix, `wiretape COMMAND: `,
and a bridge's last line a readable summary with plurals right, not a
key=value dump."""

import re
import subprocess
import sys

from wiretape.cli.bridges import bridge_summary

WIRETAPE = [sys.executable, "-m", "wiretape.cli"]


class _Stats:
    def __init__(self, **counts):
        self._counts = counts

    def items(self):
        return list(self._counts.items())


def test_a_summary_reads_as_a_sentence_with_plurals_right():
    assert bridge_summary(_Stats(bytes_to_device=1, bytes_from_device=340, clients_accepted=1,
                                 records_written=12, device_losses=0)) == \
        "12 records written, 1 byte to the device, 340 bytes from it, 1 client"
    assert bridge_summary(_Stats(records_written=1, datagrams_dropped=3)) == \
        "1 record written, datagrams dropped 3"
    assert bridge_summary(_Stats(records_written=0)) == ""


def test_record_speaks_with_one_prefix_and_ends_with_a_summary(tmp_path):
    output = tmp_path / "r.wtape"
    done = subprocess.run([*WIRETAPE, "record", "--device", "type=loopback", "--listen", "0",
                           "-o", str(output), "--duration", "0.2"],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    lines = done.stderr.splitlines()
    ours = lines  # the bridge's own notes too: the command relays them
    assert ours and all(line.startswith("wiretape record: ") for line in ours), lines
    assert any(line.startswith("wiretape record: listening on ") for line in ours), lines
    assert any(line.startswith(f"wiretape record: recording to {output}") for line in ours)
    assert re.fullmatch(r"wiretape record: finished: \d+ records? written.*", ours[-1]), ours
    assert "=" not in ours[-1]


def test_the_unused_data_report_says_1_record_not_1_records(tmp_path, capfd):
    import wiretape

    path = tmp_path / "u.wtape"
    with wiretape.SessionWriter(str(path), port_type="serial") as writer:
        for n in range(2):
            writer.write("tx", n * 1000, b"Q%d\n" % n)
            writer.write("rx", n * 1000 + 500, b"R%d\n" % n)
    port = wiretape.open_port(f"type=replay,file={path},timing=none,unused=warn")
    port.write(b"Q0\n")
    assert port.read(10, timeout=5) == b"R0\n"
    port.close()
    err = capfd.readouterr().err
    assert "3 recorded rx bytes (1 record) were never read" in err, err
    assert "1 records" not in err


def test_after_a_mismatch_no_unused_data_warning_follows(tmp_path, capfd):
    import pytest

    import wiretape

    path = tmp_path / "m.wtape"
    with wiretape.SessionWriter(str(path), port_type="serial") as writer:
        for n in range(3):
            writer.write("tx", n * 1000, b"Q%d\n" % n)
            writer.write("rx", n * 1000 + 500, b"R%d\n" % n)
    port = wiretape.open_port(f"type=replay,file={path},timing=none,unused=warn")
    port.write(b"Q0\n")
    assert port.read(10, timeout=5) == b"R0\n"
    with pytest.raises(wiretape.ReplayMismatch):
        port.write(b"XX\n")
    port.close()
    err = capfd.readouterr().err
    assert "never read" not in err and "never written" not in err, err
