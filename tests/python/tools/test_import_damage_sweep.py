"""Damage sweep of the import formats (pcap, reserial, umockdev, jsonl):
every small input truncated at every byte, and bit flips, goes through
fuzz/import_check.py's contract: converts with bytes that are in the input,
or fails with exit 1 naming the file and leaves nothing; never a traceback,
an internal message, a hang or an invented byte.

Fast in `make test` (every truncation and flip of the text formats; a
sample of positions for pcap, where each input runs tshark twice).
WIRETAPE_DAMAGE_SWEEP=full (as `make fuzz` sets) sweeps every position of
the captures too, WIRETAPE_DAMAGE_SWEEP=N samples N positions of them."""

import importlib.util
import json
import os
import pathlib
import shutil
import sys

import pytest

from captures import pcap, pcapng, tcp_conversation

ROOT = pathlib.Path(__file__).resolve().parents[3]
SWEEP = os.environ.get("WIRETAPE_DAMAGE_SWEEP", "")
FULL = SWEEP == "full"
# Positions sampled in a capture (each input runs tshark twice);
# WIRETAPE_DAMAGE_SWEEP=N samples N.
PCAP_SAMPLES = int(SWEEP) if SWEEP.isdigit() else 4
# Named streams import each conversation as a single stream is imported, and
# the single-stream captures are swept at every position under `full`; their
# combination is sampled, also under `full`, where every position would add
# some 20 minutes of tshark runs to `make fuzz`.
NAMED_STREAM_SAMPLES = max(PCAP_SAMPLES, 128) if FULL else PCAP_SAMPLES


def _checker():
    sys.path.insert(0, str(ROOT / "fuzz"))
    try:
        spec = importlib.util.spec_from_file_location("import_check", ROOT / "fuzz" / "import_check.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module
    finally:
        sys.path.remove(str(ROOT / "fuzz"))


def _reserial():
    lines = [{"test_text": {"rx": "OK\r\n", "tx": "ID\n", "rx_encoding": "utf-8",
                            "tx_encoding": "utf-8"}},
             {"test_bin": {"rx": "AP/+", "tx": "QklO"}}]
    return ("".join(json.dumps(line) + "\n" for line in lines)).encode()


def _jsonl():
    lines = [{"header": {"port_type": "serial"}},
             {"t_ns": 0, "kind": "tx", "data_hex": "49440a"},
             {"t_ns": 1000, "kind": "rx", "data_hex": "4f4b0a"},
             {"t_ns": 2000, "kind": "settings", "event": {"baud": 9600}}]
    return ("".join(json.dumps(line) + "\n" for line in lines)).encode()


def _jsonl_of_channels():
    """A session of two named channels (DESIGN §19): records name theirs."""
    lines = [{"header": {"port_type": "serial", "channels": [
                 {"id": 0, "name": "gps", "port_type": "serial"},
                 {"id": 1, "name": "rtk", "port_type": "tcp",
                  "port_options": "type=tcp,host=127.0.0.1,port=2101"}]}},
             {"t_ns": 0, "kind": "tx", "data_hex": "49440a", "channel": "gps"},
             {"t_ns": 500, "kind": "tx", "data_hex": "474554", "channel": "rtk"},
             {"t_ns": 1000, "kind": "rx", "data_hex": "4f4b0a", "channel": "gps"},
             {"t_ns": 2000, "kind": "rx", "data_hex": "d30013", "channel": "rtk"}]
    return ("".join(json.dumps(line) + "\n" for line in lines)).encode()


EXCHANGES = [("tx", b"ID;"), ("rx", b"OK;"), ("tx", b"GET;"), ("rx", b"42;")]
INPUTS = {
    "umockdev": [("talk", b"d 0 /dev/ttyUSB0\nw 5 ID^J\nr 10 OK ^`^[x\nf 5 -\nw 3 GET^@\nr 1 42\n")],
    "reserial": [("two-tests", _reserial())],
    "jsonl": [("session", _jsonl()), ("channels", _jsonl_of_channels())],
    "pcap": [("tcp.pcap", pcap(tcp_conversation(EXCHANGES))),
             ("tcp.pcapng", pcapng(tcp_conversation(EXCHANGES)))],
}
OPTIONS = {"reserial": {"test": "test_bin"}}


def damaged(data: bytes, sample: int = 0):
    """Every truncation and one bit flip per byte (a different bit each
    byte), or `sample` positions of each spread over the input."""
    positions = range(len(data))
    if sample and len(data) > sample:
        step = len(data) / sample
        positions = sorted({int(index * step) for index in range(sample)} | {len(data) - 1})
    for at in positions:
        yield f"cut at {at}", data[:at]
        flipped = bytearray(data)
        flipped[at] ^= 1 << (at % 8)
        yield f"bit {at % 8} of byte {at} flipped", bytes(flipped)


CASES = [(fmt, name, data) for fmt, inputs in INPUTS.items() for name, data in inputs]


@pytest.mark.parametrize("fmt,name,data", CASES, ids=[f"{c[0]}-{c[1]}" for c in CASES])
def test_damaged_imports_convert_honestly_or_fail_cleanly(tmp_path, fmt, name, data):
    if fmt == "pcap" and shutil.which("tshark") is None:
        pytest.skip("SKIPPED LOUDLY: tshark is not installed")
    check = _checker()
    options = dict(OPTIONS.get(fmt, {}))
    assert check.check_input(fmt, data, str(tmp_path), **options) == "ok"  # the input itself
    outcomes = {"ok": 0, "refused": 0}
    sample = 0 if FULL or fmt != "pcap" else PCAP_SAMPLES
    for what, variant in damaged(data, sample):
        try:
            outcomes[check.check_input(fmt, variant, str(tmp_path), **options)] += 1
        except AssertionError as error:
            raise AssertionError(f"{fmt} {name}, {what}: {error}") from error
    tried = outcomes["ok"] + outcomes["refused"]
    print(f"damage sweep {fmt} {name}: {tried} inputs, {outcomes['ok']} converted, "
          f"{outcomes['refused']} refused, 0 crashes, 0 hangs, 0 wrong successes")
    assert outcomes["refused"] > 0


def test_a_damaged_capture_of_named_streams_converts_honestly_or_fails_cleanly(tmp_path):
    """Several conversations into channels (--stream NAME=FILTER) keep the
    contract of one: no byte that is not in the capture."""
    if shutil.which("tshark") is None:
        pytest.skip("SKIPPED LOUDLY: tshark is not installed")
    from captures import udp_frame

    sensor, driver = ("10.0.0.3", 2368), ("10.0.0.1", 50000)
    frames = [udp_frame(sensor, driver, b"SCAN1")] + tcp_conversation(EXCHANGES) + \
        [udp_frame(sensor, driver, b"SCAN2")]
    data = pcap(frames)
    check = _checker()
    options = {"stream": ["cmd=tcp:0", "scan=udp:0"]}
    assert check.check_input("pcap", data, str(tmp_path), **options) == "ok"
    outcomes = {"ok": 0, "refused": 0}
    for what, variant in damaged(data, NAMED_STREAM_SAMPLES):
        try:
            outcomes[check.check_input("pcap", variant, str(tmp_path), **options)] += 1
        except AssertionError as error:
            raise AssertionError(f"pcap of named streams, {what}: {error}") from error
    assert outcomes["refused"] > 0


CORPUS = [(fmt, path) for fmt in ("pcap", "umockdev")
          for path in sorted((ROOT / "fuzz" / "corpus" / f"{fmt}_import_fuzz").iterdir())]


@pytest.mark.parametrize("fmt,path", CORPUS, ids=[f"{f}-{p.name}" for f, p in CORPUS])
def test_the_fuzz_corpus_converts_or_fails_cleanly(tmp_path, fmt, path):
    """What ctest's corpus replay is for the C++ fuzz targets."""
    if fmt == "pcap" and shutil.which("tshark") is None:
        pytest.skip("SKIPPED LOUDLY: tshark is not installed")
    _checker().check_input(fmt, path.read_bytes(), str(tmp_path))
