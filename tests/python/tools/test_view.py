"""wiretape view (DESIGN §21): the page, seen in headless Chromium.

Chromium (Debian's; skipped, saying so, when missing) is driven through its
own DevTools protocol over --remote-debugging-pipe: no driver to install.
The page sets data-ready on <html> once its lists are built (the tests wait
for it), data-first-paint-ms once its timeline is drawn, selects the record
named by #record=N, and exposes wiretapeView to point at records; console
calls, uncaught exceptions and the browser's errors about the page are
collected, and must be none."""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

import serial  # pyserial, a test dependency

from devices import skip_unless_serial_opens_on_a_pty, start_cli, wait_until
from view_browser import DevTools, element_text, open_page, png_pixels, table_rows
from wiretape import _core
from wiretape.faults import session_digest
from wiretape.tools.view import MAX_RECORD_BYTES, default_output, view

ROOT = Path(__file__).resolve().parents[3]
HOKUYO = ROOT / "examples" / "hokuyo" / "recordings"
TX_COLOUR = (0x1F, 0x6F, 0xD1)
RX_COLOUR = (0x1A, 0x9A, 0x3A)
CRASH_COLOUR = (0xC6, 0x28, 0x28)


def records_of(path):
    return list(_core.SessionReader(os.fspath(path)))


# --------------------------------------------------------------------------


def test_a_hokuyo_session_shows_both_lanes_its_exchanges_and_frames(tmp_path):
    session = HOKUYO / "urg04lx_gd.wtape"
    page = Path(view(session, tmp_path / "gd.html", profile="scip"))
    dom, console = open_page(page, tmp_path)
    assert console == []
    exchanges = _core.session_exchanges(os.fspath(session), profile="scip")
    rows = table_rows(dom, "exchange-list")
    assert [cells[0] for _, cells in rows] == [f"#{e.index}" for e in exchanges]
    assert rows[-1][1][3] == "GD0044072501\\n"
    frames = [cells[3] for _, cells in table_rows(dom, "frame-list")]
    assert len(frames) == 18 and any(name.startswith("GD0044072501") for name in frames)
    assert 'data-first-paint-ms="' in dom

    picture = tmp_path / "gd.png"
    open_page(page, tmp_path, screenshot=picture)
    colours = png_pixels(picture)
    assert TX_COLOUR in colours and RX_COLOUR in colours


def test_the_hex_pane_shows_the_selected_records_bytes(tmp_path):
    session = HOKUYO / "urg04lx_md.wtape"
    page = Path(view(session, tmp_path / "md.html"))
    records = records_of(session)
    chosen = max((i for i, r in enumerate(records) if r.kind == "rx"), key=lambda i: len(records[i].data))
    dom, console = open_page(page, tmp_path, fragment=f"#record={chosen}")
    assert console == []
    assert f'data-record="{chosen}"' in dom
    pane = element_text(dom, "hex").splitlines()
    assert pane[0].startswith(f"record {chosen} ") and " rx " in pane[0]
    shown = bytearray()
    for line in pane[1:]:
        match = re.match(r"^[0-9a-f]{8}  ((?:[0-9a-f]{2} )+)", line)
        if match:
            shown += bytes.fromhex(match.group(1))
    assert bytes(shown) == records[chosen].data[:MAX_RECORD_BYTES]
    assert len(shown) > 100


def test_a_campaigns_runs_mark_the_exchanges_they_faulted(tmp_path):
    session = HOKUYO / "urg04lx_gd.wtape"
    runs = [{"case": 0, "kind": "corrupt", "where": "exchange:8", "outcome": "crash", "exit": -11,
             "seconds": 0.5, "repro": "wiretape replay ... --fault corrupt@exchange:8"},
            {"case": 1, "kind": "drop", "where": "exchange:3", "outcome": "ok", "exit": 0,
             "seconds": 0.2, "repro": ""},
            {"case": 2, "kind": "silence", "where": "rx:100", "outcome": "hang", "exit": None,
             "seconds": 5.0, "repro": ""}]
    campaign = tmp_path / "campaign.json"
    campaign.write_text(json.dumps({
        "session": os.fspath(session), "session_sha256": session_digest(os.fspath(session)),
        "seed": 0, "kinds": None, "budget": None, "options": "", "cases": 3, "shard": None,
        "runs": runs, "summary": {"ok": 1, "error": 0, "crash": 1, "hang": 1},
        "interrupted": False}))
    page = Path(view(session, tmp_path / "campaign.html", campaign=os.fspath(campaign)))
    dom, console = open_page(page, tmp_path)
    assert console == []
    listed = table_rows(dom, "runs")
    assert [(cells[1], cells[2], cells[5]) for _, cells in listed] == [
        ("corrupt@exchange:8", "crash", "#8"), ("drop@exchange:3", "ok", "#3"),
        ("silence@rx:100", "hang", "")]
    exchanges = {cells[0]: (attributes, cells) for attributes, cells in table_rows(dom, "exchange-list")}
    assert 'outcome-crash' in exchanges["#8"][0] and exchanges["#8"][1][6] == "corrupt:crash"
    assert "warning" not in element_text(dom, "notes")

    picture = tmp_path / "campaign.png"
    open_page(page, tmp_path, screenshot=picture)
    assert CRASH_COLOUR in png_pixels(picture)


def test_a_campaign_of_another_session_is_refused_naming_the_run(tmp_path):
    campaign = tmp_path / "campaign.json"
    campaign.write_text(json.dumps({
        "session": "other.wtape", "session_sha256": "", "seed": 0, "kinds": None,
        "budget": None, "options": "", "cases": 1, "shard": None, "interrupted": False,
        "runs": [{"case": 0, "kind": "drop", "where": "exchange:99", "outcome": "ok",
                  "exit": 0, "seconds": 0.1, "repro": ""}], "summary": {}}))
    result = subprocess.run([sys.executable, "-m", "wiretape.cli", "view",
                             os.fspath(HOKUYO / "urg04lx_gd.wtape"), "--campaign",
                             os.fspath(campaign), "-o", os.fspath(tmp_path / "x.html")],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 2, result.stderr
    assert "exchange 99" in result.stderr and "9 exchanges" in result.stderr
    assert not (tmp_path / "x.html").exists()


def test_a_replays_mismatch_is_marked_on_the_clients_record(tmp_path):
    skip_unless_serial_opens_on_a_pty()
    original = HOKUYO / "urg04lx_gd.wtape"
    link, recording = tmp_path / "pty", tmp_path / "replayed.wtape"
    child = start_cli("replay", os.fspath(original), "--pty", os.fspath(link),
                      "-o", os.fspath(recording))
    try:
        wait_until(link.exists, what="the replay's pty")
        with serial.Serial(os.fspath(link), timeout=30) as client:
            client.write(b"VV\n")
            assert client.read(6) == b"VV\nE\n\n"
            client.write(b"XX\n")  # the recording holds QT\n here
            _, err = child.communicate(timeout=60)
    finally:
        if child.poll() is None:
            child.kill()
            child.communicate()
    assert child.returncode == 1 and "mismatch" in err, err
    page = Path(view(recording, tmp_path / "mismatch.html"))
    records = records_of(recording)
    wrong = next(i for i, r in enumerate(records) if r.kind == "tx" and r.data == b"XX\n")
    dom, console = open_page(page, tmp_path, fragment=f"#record={wrong}")
    assert console == []
    notes = element_text(dom, "notes")
    assert f"Mismatch (record {wrong}, tx byte 3)" in notes
    assert "expected: 51 54 0a  |QT.|" in notes and "actual:   58 58 0a  |XX.|" in notes
    assert "MISMATCH" in element_text(dom, "hex").splitlines()[0]
    picture = tmp_path / "mismatch.png"
    open_page(page, tmp_path, fragment=f"#record={wrong}", screenshot=picture)
    assert CRASH_COLOUR in png_pixels(picture)  # the mismatch's mark


def many_records(path, pairs):
    with _core.SessionWriter(os.fspath(path)) as writer:
        writer.write("open", 0, b'{"description":"generated"}')
        for n in range(pairs):
            writer.write("tx", 1_000_000 * n + 1, b"GET %d\n" % n)
            writer.write("rx", 1_000_000 * n + 200_000, b"VALUE %d\n" % (n * 7))
    return path


def test_100000_records_open_in_under_2_s_to_first_paint(tmp_path):
    session = many_records(tmp_path / "big.wtape", 50_000)
    page = Path(view(session, tmp_path / "big.html"))
    dom, console = open_page(page, tmp_path)
    assert console == []
    first_paint_ms = float(re.search(r'data-first-paint-ms="([0-9.]+)"', dom).group(1))
    assert first_paint_ms <= 2000, f"first paint after {first_paint_ms} ms"
    assert "100001 records" in element_text(dom, "summary")


# --- the command line ------------------------------------------------------


def run_view(*argv, cwd=None):
    return subprocess.run([sys.executable, "-m", "wiretape.cli", "view", *argv], cwd=cwd,
                          capture_output=True, text=True, timeout=120)


def test_the_default_page_is_the_session_with_html_and_says_so(tmp_path):
    session = tmp_path / "scan.wtape"
    shutil.copy(HOKUYO / "urg04lx_gd.wtape", session)
    result = run_view(os.fspath(session))
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "scan.html").is_file()
    assert default_output(session) == os.fspath(tmp_path / "scan.html")
    assert "scan.html (the default: SESSION with .html" in result.stderr
    page = (tmp_path / "scan.html").read_text()
    # Self-contained: nothing fetched from anywhere.
    assert not re.search(r'(src|href)="(https?:)?//', page)
    assert "default-src 'none'" in page


def test_the_page_is_never_written_over_its_session(tmp_path):
    session = tmp_path / "scan.wtape"
    shutil.copy(HOKUYO / "urg04lx_gd.wtape", session)
    os.symlink(session, tmp_path / "scan.html")
    before = session.read_bytes()
    for output in (session, tmp_path / "scan.html"):
        result = run_view(os.fspath(session), "-o", os.fspath(output))
        assert result.returncode == 3 and "refusing to overwrite the input" in result.stderr
    result = run_view(os.fspath(session))  # the default output is the link to the session
    assert result.returncode == 3
    assert session.read_bytes() == before


def test_a_damaged_session_is_shown_up_to_the_damage_and_exits_1(tmp_path):
    session = tmp_path / "cut.wtape"
    data = (HOKUYO / "urg04lx_gd.wtape").read_bytes()
    session.write_bytes(data[:len(data) - 100])
    result = run_view(os.fspath(session), "-o", os.fspath(tmp_path / "cut.html"))
    assert result.returncode == 1, result.stderr
    dom, console = open_page(tmp_path / "cut.html", tmp_path)
    assert console == []
    assert "Damaged:" in element_text(dom, "notes")


def test_bytes_and_names_from_the_file_stay_text_in_the_page(tmp_path):
    hostile = b"</script><script>console.error('injected')</script><img src=x onerror=alert(1)>"
    session = tmp_path / "hostile.wtape"
    with _core.SessionWriter(os.fspath(session), metadata={"note": hostile.decode()}) as writer:
        writer.write("tx", 1_000, hostile)
        writer.write("rx", 2_000, hostile)
        writer.write("settings", 3_000, b'{"baud":9600,"source":"</script>"}')
    page = Path(view(session, tmp_path / "hostile.html"))
    assert page.read_text().count("<script") == 2  # the data's and the page's own
    dom, console = open_page(page, tmp_path, fragment="#record=0")
    assert console == []
    rows = table_rows(dom, "exchange-list")
    assert rows[0][1][3] == hostile.decode()[:60]
    assert "<img" not in dom.split('id="lists"')[1].replace("&lt;img", "")


def test_an_empty_session_draws_without_errors(tmp_path):
    session = tmp_path / "empty.wtape"
    _core.SessionWriter(os.fspath(session)).close()
    dom, console = open_page(Path(view(session, tmp_path / "empty.html")), tmp_path)
    assert console == []
    assert "0 records" in element_text(dom, "summary")


@pytest.fixture
def devtools(tmp_path):
    browser = DevTools(tmp_path)
    yield browser
    browser.close()


def test_the_wheel_zooms_at_the_pointer_dragging_pans_and_a_click_selects(tmp_path, devtools):
    session = HOKUYO / "urg04lx_md.wtape"
    page = Path(view(session, tmp_path / "md.html"))
    devtools.open(page.resolve().as_uri())
    left, top = devtools.evaluate(
        "(r => [r.left, r.top])(document.getElementById('lanes').getBoundingClientRect())")
    before = devtools.evaluate("wiretapeView.range()")
    middle = (before[0] + before[1]) / 2
    x = left + devtools.evaluate(f"wiretapeView.xOf({middle})")
    y = top + devtools.evaluate("wiretapeView.laneMiddle('rx')")
    devtools.mouse("mouseWheel", x, y, deltaX=0, deltaY=-400)
    wait_until(lambda: devtools.evaluate("wiretapeView.range()") != before, what="the zoom")
    zoomed = devtools.evaluate("wiretapeView.range()")
    assert zoomed[1] - zoomed[0] < (before[1] - before[0]) / 1.5
    assert zoomed[0] < middle < zoomed[1]  # around the pointer

    devtools.mouse("mousePressed", x, y, button="left", buttons=1, clickCount=1)
    devtools.mouse("mouseMoved", x - 200, y, button="left", buttons=1)
    devtools.mouse("mouseReleased", x - 200, y, button="left", buttons=0, clickCount=1)
    panned = devtools.evaluate("wiretapeView.range()")
    assert panned[1] - panned[0] == pytest.approx(zoomed[1] - zoomed[0])
    assert panned[0] > zoomed[0]  # dragged to the left: later times come into view

    records = records_of(session)
    fit = devtools.evaluate("document.getElementById('fit').click(), wiretapeView.range()")
    chosen = next(i for i, r in enumerate(records) if r.kind == "rx" and len(r.data) > 100)
    wait_until(lambda: devtools.evaluate("wiretapeView.range()") == fit, what="the fit")
    devtools.mouse("mouseWheel", left + devtools.evaluate(f"wiretapeView.xOf({records[chosen].t_ns})"),
                   y, deltaX=0, deltaY=-3000)  # close enough to tell records apart
    wait_until(lambda: devtools.evaluate("wiretapeView.range()") != fit, what="the zoom")
    x = left + devtools.evaluate(f"wiretapeView.xOf({records[chosen].t_ns})")
    devtools.mouse("mousePressed", x, y, button="left", buttons=1, clickCount=1)
    devtools.mouse("mouseReleased", x, y, button="left", buttons=0, clickCount=1)
    wait_until(lambda: devtools.evaluate("document.getElementById('hex').dataset.record") == str(chosen),
               what="the click's record in the hex pane")
    devtools.mouse("mouseMoved", left + 5, top + 5)  # off the records: the pane keeps the selection
    pane = devtools.evaluate("document.getElementById('hex').textContent")
    assert pane.startswith(f"record {chosen} ")
    assert records[chosen].data[:16].hex(" ") in pane
    devtools.evaluate("window.dispatchEvent(new KeyboardEvent('keydown', {key: 'ArrowRight'}))")
    assert devtools.evaluate("document.getElementById('hex').dataset.record") == str(chosen + 1)


# A driver that trusts its device: it aborts (a crash) on an answer it did
# not expect, and fails cleanly (an error) when the device goes away.
TRUSTING_DRIVER = """
import os, sys, tty
fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
tty.setraw(fd)
for n in range(3):
    os.write(fd, b"Q%d\\n" % n)
    line = b""
    while not line.endswith(b"\\n"):
        try:
            chunk = os.read(fd, 1)
        except OSError:
            sys.exit(3)
        if not chunk:
            sys.exit(3)
        line += chunk
    if line != b"R%d-abcdef\\n" % n:
        os.abort()
"""


def test_a_real_campaigns_json_colours_the_exchanges_it_crashed(tmp_path):
    skip_unless_serial_opens_on_a_pty()
    session = tmp_path / "lines.wtape"
    with _core.SessionWriter(os.fspath(session), port_type="serial") as writer:
        for n in range(3):
            writer.write("tx", n * 10_000_000, b"Q%d\n" % n)
            writer.write("rx", n * 10_000_000 + 1_000_000, b"R%d-abcdef\n" % n)
    driver = tmp_path / "driver.py"
    driver.write_text(TRUSTING_DRIVER)
    campaign = tmp_path / "campaign.json"
    result = subprocess.run([sys.executable, "-m", "wiretape.cli", "faults", os.fspath(session),
                             "--kinds", "corrupt,disconnect", "--timeout", "20", "--json",
                             os.fspath(campaign), "--", sys.executable, os.fspath(driver), "{port}"],
                            capture_output=True, text=True, timeout=600)
    assert result.returncode == 1 and campaign.exists(), result.stderr
    runs = json.loads(campaign.read_text())["runs"]
    page = Path(view(session, tmp_path / "campaign.html", campaign=os.fspath(campaign)))
    dom, console = open_page(page, tmp_path)
    assert console == []
    listed = [(cells[1], cells[2]) for _, cells in table_rows(dom, "runs")]
    assert listed == [(f"{run['kind']}@{run['where']}", run["outcome"]) for run in runs]
    assert ("corrupt@exchange:1", "crash") in listed
    exchanges = {cells[0]: (attributes, cells) for attributes, cells in table_rows(dom, "exchange-list")}
    assert "outcome-crash" in exchanges["#1"][0]
    assert "corrupt:crash" in exchanges["#1"][1][6].split()
    picture = tmp_path / "campaign.png"
    open_page(page, tmp_path, screenshot=picture)
    assert CRASH_COLOUR in png_pixels(picture)


def test_every_kind_of_event_is_drawn_and_listed(tmp_path):
    events = [("open", b'{"description":"serial /dev/ttyUSB0 @ 9600 8N1"}'),
              ("settings", b'{"baud":115200}'), ("modem_lines", b'{"dtr":true}'),
              ("flush_input", b""), ("client_connect", b'{"peer":"pty","role":"control"}'),
              ("fault", b'{"kind":"corrupt","where":"exchange:0","detail":"flipped bit 3"}'),
              ("capture_gap", b'{"direction":"rx","offset":0,"length":4}'),
              ("client_disconnect", b'{"peer":"pty"}'), ("close", b"")]
    session = tmp_path / "events.wtape"
    with _core.SessionWriter(os.fspath(session)) as writer:
        for n, (kind, payload) in enumerate(events):
            writer.write(kind, n * 10_000_000, payload)
            writer.write("tx", n * 10_000_000 + 1_000_000, b"Q\n")
    page = Path(view(session, tmp_path / "events.html"))
    picture = tmp_path / "events.png"
    dom, console = open_page(page, tmp_path, screenshot=picture)
    assert console == []
    listed = [(cells[1], cells[2]) for _, cells in table_rows(dom, "event-list")]
    assert listed == [(kind, payload.decode() or "") for kind, payload in events]
    colours = png_pixels(picture)
    for colour in ((0x6A, 0x3F, 0xB5), (0xB5, 0x28, 0x7A), (0xE0, 0x7A, 0x00),
                   (0x0A, 0x8A, 0x8A), (0xC6, 0x28, 0x28), (0x8A, 0x8A, 0x8A)):
        assert colour in colours  # settings, modem lines, flush, connect, fault, gap


def test_an_interrupted_view_exits_130_and_leaves_no_page(tmp_path):
    # The campaign is a FIFO: the view blocks reading it, after the session,
    # and opening its other end says when the view got there.
    campaign = tmp_path / "campaign.json"
    os.mkfifo(campaign)
    output = tmp_path / "gd.html"
    child = start_cli("view", os.fspath(HOKUYO / "urg04lx_gd.wtape"), "--campaign",
                      os.fspath(campaign), "-o", os.fspath(output))
    try:
        with open(campaign, "w"):  # returns once the view opened it to read
            child.send_signal(signal.SIGINT)
            _, err = child.communicate(timeout=60)
    finally:
        if child.poll() is None:
            child.kill()
            child.communicate()
    assert child.returncode == 130, err
    assert sorted(path.name for path in tmp_path.iterdir()) == ["campaign.json"]
