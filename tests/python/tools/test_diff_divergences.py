"""wiretape diff (issue 26): every divergence, aligned by exchange (--max),
and each pointing at its differing byte, with --profile too."""

from pathlib import Path

import pytest

import wiretape
from wiretape import cli
from wiretape.tools.diff import diff

GOOD = b"GD0044072501\n"


def write(path: Path, requests) -> Path:
    with wiretape.SessionWriter(str(path), port_type="serial",
                                port_options="type=serial,device=/dev/ttyX") as writer:
        for n, request in enumerate(requests):
            writer.write("tx", n * 1_000_000, request)
            reply = request + b"00P\n" + bytes([48 + n]) + b"\n\n"
            writer.write("rx", n * 1_000_000 + 500_000, reply)
    return path


@pytest.fixture()
def pair(tmp_path):
    a = write(tmp_path / "a.wtape", [GOOD] * 12)
    changed = [GOOD] * 12
    for n in (2, 5, 9):  # one byte changed in three requests (and their echoes)
        changed[n] = GOOD.replace(b"25", b"26")
    b = write(tmp_path / "b.wtape", changed)
    return a, b


def test_every_divergence_is_listed_by_exchange(pair):
    result = diff(*pair)
    assert result.divergence_count == 6  # three requests, three responses
    assert [(d.exchange, d.direction, d.offset) for d in result.divergences] == [
        (2, "tx", 9), (2, "rx", 9), (5, "tx", 9), (5, "rx", 9), (9, "tx", 9), (9, "rx", 9)]
    assert result.divergences[2].time_a_ns == 5_000_000


def test_max_keeps_the_first_n_and_counts_them_all(pair, capsys):
    assert cli.main(["diff", str(pair[0]), str(pair[1]), "--max", "2"]) == 1
    out = capsys.readouterr().out
    assert "6 divergences by exchange (the first 2 of 6; --max shows more):" in out
    assert "exchange 2 request (tx) differs at byte 9" in out
    assert "exchange 2 response (rx) differs at byte 9" in out
    assert "exchange 5" not in out


def test_the_differing_byte_is_pointed_at(pair, capsys):
    cli.main(["diff", str(pair[0]), str(pair[1]), "--max", "1"])
    lines = capsys.readouterr().out.splitlines()
    at = next(i for i, line in enumerate(lines) if "exchange 2 request" in line)
    line_a, line_b, carets = lines[at + 1], lines[at + 2], lines[at + 3]
    assert line_a.strip().startswith("A:") and line_b.strip().startswith("B:")
    hex_caret = carets.index("^^")
    assert line_a[hex_caret:hex_caret + 2] == "35" and line_b[hex_caret:hex_caret + 2] == "36"
    text_caret = carets.rindex("^")
    assert line_a[text_caret] == "5" and line_b[text_caret] == "6"


def test_with_a_profile_the_frame_is_named_and_the_byte_pointed_at(pair, capsys):
    assert cli.main(["diff", str(pair[0]), str(pair[1]), "--profile", "scip"]) == 1
    out = capsys.readouterr().out
    assert "at byte 9 of the frame:" in out
    assert "A is GD0044072501" in out and "B is GD0044072601" in out
    # the 32 identical bytes of old are gone: the window is 8 bytes each side
    assert "47 44 30 30 34 34 30 37 32 35 30 31 0a" not in out
    assert "divergences by exchange" in out


def test_a_missing_exchange_is_a_divergence(tmp_path):
    a = write(tmp_path / "a.wtape", [GOOD] * 3)
    b = write(tmp_path / "b.wtape", [GOOD] * 2)
    result = diff(a, b)
    assert [(d.exchange, d.direction, d.bytes_b) for d in result.divergences] == [
        (2, "tx", None), (2, "rx", None)]
    assert "exchange 2 request (tx): B has none" in result.report()


def test_identical_sessions_list_no_divergence(pair):
    result = diff(pair[0], pair[0])
    assert result.identical and result.divergence_count == 0
    assert "by exchange" not in result.report()


def modbus_tcp(transaction: int, pdu: bytes) -> bytes:
    return transaction.to_bytes(2, "big") + b"\x00\x00" + (len(pdu) + 1).to_bytes(2, "big") + \
        b"\x01" + pdu


def test_with_a_profile_what_the_key_leaves_out_is_no_divergence(tmp_path):
    def session(name, transactions, register):
        path = tmp_path / name
        with wiretape.SessionWriter(str(path), port_type="tcp") as writer:
            for n, transaction in enumerate(transactions):
                pdu = b"\x03\x00" + bytes([register if n == 2 else n]) + b"\x00\x01"
                writer.write("tx", n * 1_000_000, modbus_tcp(transaction, pdu))
                writer.write("rx", n * 1_000_000 + 500_000,
                             modbus_tcp(transaction, b"\x03\x02\x00" + bytes([n])))
        return path

    a = session("a.wtape", [1, 2, 3, 4], 2)
    b = session("b.wtape", [101, 102, 103, 104], 9)  # other transaction ids; one register
    result = diff(a, b, profile="modbus-tcp")
    # the transaction ids differ in every frame, but only exchange 2's request does by key
    assert [(d.exchange, d.direction, d.offset) for d in result.divergences] == [(2, "tx", 9)]
    first = result["tx"]
    assert first.index == 2 and first.byte == 9
    assert "at byte 9 of the frame:" in result.report()
