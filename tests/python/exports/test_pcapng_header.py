"""The pcapng export of a session whose header JSON is longer than one
pcapng option holds (64 KiB: a large metadata value, 1,024 channels): every
command reads what verify accepts (docs/cli.md), so convert writes it, the
header in the section's comments, cut at characters, which joined are the
header JSON; tshark opens the file."""

import json
import shutil
import struct
import subprocess
import sys

import pytest
from channel_sessions import write_channel_session
from pcapng_reader import read_pcapng

import wiretape
from wiretape import _core

WIRETAPE = [sys.executable, "-m", "wiretape.cli"]
OPTION_MAX = 0xFFFF


def large_metadata_session(path):
    header = _core.SessionHeader()
    header.port_type = "serial"
    # Two-byte characters, so that a cut at 64 KiB would fall inside one.
    header.metadata = {"note": "é" * 50_000 + "end"}
    with wiretape.SessionWriter(str(path), header) as writer:
        writer.write("tx", 1_000, b"PING\n")
        writer.write("rx", 2_000, b"PONG\n")
    return path


def many_channels_session(path):
    channels = [(f"port{n:04}", "serial") for n in range(1024)]
    records = [(name, kind, 1_000 * n + offset, b"%s %d\n" % (kind.encode(), n))
               for n, (name, _) in enumerate(channels[:3])
               for kind, offset in (("tx", 0), ("rx", 500))]
    write_channel_session(path, channels, records)
    return path


def section_comments(path):
    """The section header's comment options, in order, as raw bytes."""
    blob = path.read_bytes()
    block_type, length = struct.unpack_from("<II", blob)
    assert block_type == 0x0A0D0D0A
    body, position, comments = blob[8 + 16:length - 4], 0, []
    while position + 4 <= len(body):
        code, size = struct.unpack_from("<HH", body, position)
        position += 4
        if code == 0:
            break
        if code == 1:
            comments.append(body[position:position + size])
        position += size + (-size % 4)
    return comments


@pytest.mark.parametrize("make", [large_metadata_session, many_channels_session])
def test_a_header_over_64_kib_converts_whole_into_the_section_comments(tmp_path, make):
    session = make(tmp_path / "big.wtape")
    header_json = wiretape.SessionReader(str(session)).header.to_json()
    assert len(header_json.encode()) > OPTION_MAX
    assert subprocess.run([*WIRETAPE, "verify", str(session)],
                          capture_output=True).returncode == 0
    out = tmp_path / "big.pcapng"
    result = subprocess.run([*WIRETAPE, "convert", str(session), str(out)],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr

    pieces = section_comments(out)
    assert len(pieces) > 1
    assert all(len(piece) <= OPTION_MAX for piece in pieces)
    for piece in pieces:
        piece.decode("utf-8")  # each comment is text of its own
    comment, _, packets = read_pcapng(out)
    assert json.loads(comment) == json.loads(header_json)
    assert sum(1 for packet in packets if packet[3] in (b"PING\n", b"PONG\n")
               or packet[3].startswith((b"tx ", b"rx "))) >= 2

    tshark = shutil.which("tshark")
    if tshark is None:
        pytest.skip("SKIPPED LOUDLY: tshark is not installed (apt-get install tshark): cannot "
                    "check that Wireshark opens a pcapng whose header is over 64 KiB")
    read = subprocess.run([tshark, "-r", str(out), "-T", "fields", "-e", "frame.number"],
                          capture_output=True, text=True, timeout=120)
    assert read.returncode == 0, read.stderr
    assert len([line for line in read.stdout.splitlines() if line.strip()]) == len(packets)
