"""Every command on a compressed copy of a real recording (format 2.0,
``convert --compress zstd``): each gives what it gives on the uncompressed
session, since Python reads both through the one C++ reader."""

import json
import re

import pytest

from wiretape import _core, cli

from real_recordings import flexiport_log


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    """(plain, compressed): the Hokuyo UTM-30LX recording as a .wtape, and
    the same compressed."""
    folder = tmp_path_factory.mktemp("compressed")
    source = flexiport_log("utm30lx_2011")
    plain, packed = folder / "plain.wtape", folder / "packed.wtape"
    assert cli.main(["convert", "-q", str(source), str(plain)]) == 0
    assert cli.main(["convert", "-q", "--compress", "zstd", str(plain), str(packed)]) == 0
    return plain, packed


def run(capsys, *argv):
    code = cli.main([str(arg) for arg in argv])
    captured = capsys.readouterr()
    return code, captured.out


def records(path):
    return [(r.t_ns, r.kind, r.data, r.channel) for r in _core.SessionReader(path)]


def test_the_copy_is_format_2_smaller_and_holds_the_same_records(sessions):
    plain, packed = sessions
    header = _core.SessionReader(packed).header
    assert (header.version_major, header.version_minor) == (2, 0)
    assert records(packed) == records(plain)
    assert packed.stat().st_size * 3 < plain.stat().st_size, "a Hokuyo scan shrinks to 1/3"


@pytest.mark.parametrize("argv", [
    ["show"], ["show", "--format", "jsonl"], ["show", "--format", "hex"], ["stats", "--json"],
    ["show", "--textconv", "--no-start"],
], ids=lambda argv: " ".join(argv))
def test_a_reading_command_prints_the_same(capsys, sessions, argv):
    plain, packed = sessions

    def output(path):
        code, out = run(capsys, *argv, path)
        # The one difference: the file's format version (1.3, 2.0).
        out = re.sub(r"wiretape [12]\.[0-9]", "wiretape X.Y", out.replace(str(path), "FILE"))
        out = re.sub(r'"version_(major|minor)": [0-9]+', r'"version_\1": N', out)
        return code, out

    assert output(packed) == output(plain)


def test_verify_checks_each_chunk(capsys, sessions):
    _, packed = sessions
    code, out = run(capsys, "verify", "--json", packed)
    result = json.loads(out)
    assert code == 0 and result["ok"]
    assert result["records"] == len(records(packed))
    assert result["index"] == "not needed"


def test_diff_finds_no_difference(capsys, sessions):
    plain, packed = sessions
    code, _ = run(capsys, "diff", plain, packed)
    assert code == 0


@pytest.mark.parametrize("suffix", [".jsonl", ".pcapng", ".mcap", ".log"])
def test_a_conversion_of_it_is_that_of_the_plain_session(tmp_path, sessions, suffix):
    plain, packed = sessions
    from_plain, from_packed = tmp_path / f"a{suffix}", tmp_path / f"b{suffix}"
    assert cli.main(["convert", "-q", str(plain), str(from_plain)]) == 0
    assert cli.main(["convert", "-q", str(packed), str(from_packed)]) == 0
    if suffix == ".log":  # name.logr + name.logw
        for part in ("r", "w"):
            assert (tmp_path / f"b.log{part}").read_bytes() == \
                (tmp_path / f"a.log{part}").read_bytes()
    elif suffix == ".jsonl":
        assert from_packed.read_text().splitlines()[1:] == from_plain.read_text().splitlines()[1:]
    else:
        assert from_packed.stat().st_size == from_plain.stat().st_size


def test_edit_reads_it_and_writes_it_compressed_on_request(tmp_path, sessions):
    plain, packed = sessions
    out_plain, out_packed = tmp_path / "a.wtape", tmp_path / "b.wtape"
    assert cli.main(["edit", "-q", "--cut", "0:1", str(plain), str(out_plain)]) == 0
    assert cli.main(["edit", "-q", "--cut", "0:1", "--compress", "zstd", str(packed),
                     str(out_packed)]) == 0
    assert records(out_packed) == records(out_plain)
    assert _core.SessionReader(out_packed).header.version_major == 2
    assert _core.SessionReader(out_plain).header.version_major == 1


def test_a_replay_of_it_serves_what_the_plain_one_serves(sessions):
    plain, packed = sessions

    rx = b"".join(r.data for r in _core.SessionReader(plain) if r.kind == "rx")

    def served(path):
        port = _core.open_port(f"type=replay,file={path},timing=none,unused=ignore,timeout=10")
        got = bytearray()
        for kind, data in ((r.kind, r.data) for r in _core.SessionReader(path)):
            if kind == "tx":
                port.write(data)
        while len(got) < len(rx):
            chunk = port.read(65536)
            if not chunk:
                break
            got += chunk
        port.close()
        return bytes(got)

    assert served(packed) == served(plain) == rx


def test_view_writes_the_page_it_writes_of_the_plain_session(tmp_path, sessions):
    plain, packed = sessions
    pages = []
    for path in (plain, packed):
        page = tmp_path / f"{path.stem}.html"
        assert cli.main(["view", str(path), "-o", str(page)]) == 0
        text = page.read_text()
        text = text.replace(str(path), "FILE").replace(path.name, "FILE")
        pages.append(re.sub(r"wiretape [12]\.[0-9]", "wiretape X.Y", text))
    assert len(pages[1]) > 1000
    assert pages[1] == pages[0]


def test_an_import_can_be_written_compressed(tmp_path):
    """An import (here flexiport's logs) straight into a compressed session."""
    packed = tmp_path / "imported.wtape"
    source = flexiport_log("urg04lx_2011")
    assert cli.main(["convert", "-q", "--compress", "zstd", str(source), str(packed)]) == 0
    plain = tmp_path / "plain.wtape"
    assert cli.main(["convert", "-q", str(source), str(plain)]) == 0
    assert records(packed) == records(plain)
    assert _core.SessionReader(packed).header.version_major == 2
