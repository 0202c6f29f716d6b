"""wiretape view answers the questions Wireshark's and Saleae Logic's users
ask (docs/view.md, "Finding things"): a record table to filter and sort with
Δt and the latency of `wiretape stats`, search, follow stream, two
measurement cursors, idle gaps folded, a colour legend, the channel of each
exchange, the session's --meta, labels that fit. Driven in headless
Chromium (tests/python/support/view_browser.py) by the events a user makes;
the DOM read back."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from devices import wait_until
from multichannel_sessions import write_channels_session
from view_browser import DevTools, table_rows
from wiretape import _core
from wiretape.tools.view import view

CHANNELS = [
    dict(id=0, name="gps-receiver-on-the-mast", port_options="type=serial,device=/dev/ttyUSB0",
         port_type="serial", capture="wire"),
    dict(id=1, name="imu", port_options="type=serial,device=/dev/ttyUSB1",
         port_type="serial", capture="wire"),
]
# Each channel polled: a request, its answer after 2 ms (gps) or 5 ms (imu);
# then a minute of silence, then one more poll of each.
RECORDS = []
for n, start in enumerate([0, 100_000_000, 200_000_000, 60_200_000_000]):
    RECORDS += [(start + 1_000, "tx", b"POLL %d\r\n" % n, 0),
                (start + 2_001_000, "rx", b"$GPGGA,%d,4807.038,N*47\r\n" % n, 0),
                (start + 10_000_000, "tx", b"IMU?\n", 1),
                (start + 15_000_000, "rx", b"ACC 0.%d 9.81\n" % n, 1)]


@pytest.fixture
def page(tmp_path):
    session = write_channels_session(tmp_path / "robot.wtape", RECORDS, CHANNELS,
                                     metadata={"rig": "bench-3", "firmware": "2.1"})
    return Path(view(session, tmp_path / "robot.html")), session


@pytest.fixture
def browser(tmp_path, page):
    devtools = DevTools(tmp_path)
    devtools.open(page[0].resolve().as_uri())
    yield devtools
    assert devtools.console() == []
    devtools.close()


def table(browser):
    """The record table's rows as shown: lists of cell texts."""
    return browser.evaluate(
        "Array.from(document.querySelectorAll('#record-table tbody tr'))"
        ".map(tr => Array.from(tr.cells).map(td => td.textContent))")


def column(browser, name):
    heads = browser.evaluate(
        "Array.from(document.querySelectorAll('#record-table thead th')).map(th => th.dataset.key)")
    return heads.index(name)


def set_value(browser, element_id, value, event="input"):
    browser.evaluate(f"(e => {{ e.value = {value!r}; e.dispatchEvent(new Event('{event}')); }})"
                     f"(document.getElementById('{element_id}'))")


def key(browser, name, target="window"):
    browser.evaluate(f"{target}.dispatchEvent(new KeyboardEvent('keydown', {{key: '{name}', bubbles: true}}))")


def test_the_exchange_list_names_each_exchanges_channel_time_and_latency(page, browser):
    _, session = page
    rows = table_rows(browser.evaluate("document.documentElement.outerHTML"), "exchange-list")
    listed = [(cells[0], cells[1], cells[2]) for _, cells in rows]
    # Each channel numbers its own exchanges: #0 twice, told apart by channel.
    assert listed[:2] == [("#0", "gps-receiver-on-the-mast", "+0.000001 s"),
                          ("#0", "imu", "+0.010000 s")]
    assert all(time.startswith("+") for _, _, time in listed)
    # The latencies are `wiretape stats`' (the C++ LatencyMeter's).
    header = _core.SessionReader(os.fspath(session)).header
    for channel in (0, 1):
        meter = _core.LatencyMeter(header, channel=channel)
        for record in _core.SessionReader(os.fspath(session), channel=channel):
            meter.feed(record.kind, record.t_ns, record.data)
        expected = {answered.exchange: answered.wait_ns for answered in meter.answered}
        name = CHANNELS[channel]["name"]
        shown = {int(cells[0][1:]): cells[5] for _, cells in rows if cells[1] == name}
        assert shown == {n: f"{wait / 1e6:.3f} ms" for n, wait in expected.items()}
        assert set(shown.values()) == {"2.000 ms" if channel == 0 else "5.000 ms"}


def test_the_header_shows_the_sessions_meta_and_a_legend_of_its_colours(browser):
    assert browser.evaluate("document.getElementById('meta').textContent") == \
        "meta: firmware=2.1 · rig=bench-3"
    legend = browser.evaluate(
        "Array.from(document.querySelectorAll('#legend .legend-item')).map(e => e.dataset.name)")
    assert legend[:2] == ["tx: host to device", "rx: device to host"]
    assert "cursor A" in legend and "idle gap, folded" in legend


def test_the_record_table_filters_and_sorts_with_delta_t_and_latency(browser):
    rows = table(browser)
    assert len(rows) == len(RECORDS)
    assert [row[0] for row in rows] == [str(n) for n in range(len(RECORDS))]
    kind, delta, latency = column(browser, "kind"), column(browser, "Δt"), column(browser, "latency")
    assert rows[1][delta] == "+2.000 ms" and rows[0][latency] == "2.000 ms"

    set_value(browser, "kind-filter", "rx", "change")
    rows = table(browser)
    assert {row[kind] for row in rows} == {"rx"} and len(rows) == len(RECORDS) // 2
    assert rows[1][delta] == "+12.999 ms"  # from the previous row the filter keeps
    set_value(browser, "channel-filter", "1", "change")
    assert [row[column(browser, "channel")] for row in table(browser)] == ["imu"] * 4
    set_value(browser, "kind-filter", "", "change")
    set_value(browser, "channel-filter", "", "change")
    set_value(browser, "text-filter", "GPGGA,2")
    assert [row[0] for row in table(browser)] == ["9"]
    set_value(browser, "text-filter", "")

    bytes_column = column(browser, "bytes")
    browser.evaluate(f"document.querySelectorAll('#record-table thead th')[{bytes_column}].click()")
    sizes = [int(row[bytes_column]) for row in table(browser)]
    assert sizes == sorted(sizes)
    browser.evaluate(f"document.querySelectorAll('#record-table thead th')[{bytes_column}].click()")
    sizes = [int(row[bytes_column]) for row in table(browser)]
    assert sizes == sorted(sizes, reverse=True)
    assert browser.evaluate("document.getElementById('record-table').dataset.sort") == "bytes:down"

    browser.evaluate("document.querySelector('#record-table tbody tr').click()")
    chosen = table(browser)[0][0]
    assert browser.evaluate("document.getElementById('hex').dataset.record") == chosen


def test_search_steps_through_the_records_holding_the_bytes(browser):
    set_value(browser, "search", "$GPGGA")
    key(browser, "Enter", "document.getElementById('search')")
    status = "document.getElementById('search-status')"
    assert browser.evaluate(f"{status}.dataset.matches") == "4"
    assert browser.evaluate(f"{status}.textContent") == "match 1 of 4"
    assert browser.evaluate("document.getElementById('hex').dataset.record") == "1"
    browser.evaluate("document.getElementById('search-next').click()")
    assert browser.evaluate("document.getElementById('hex').dataset.record") == "5"
    set_value(browser, "search", "9.81\\n")  # an escape, as the lists write bytes
    key(browser, "Enter", "document.getElementById('search')")
    assert browser.evaluate(f"{status}.dataset.matches") == "4"
    set_value(browser, "search", "nowhere")
    key(browser, "Enter", "document.getElementById('search')")
    assert browser.evaluate(f"{status}.textContent") == "not found"


def test_follow_stream_shows_both_directions_of_the_selected_channel(browser):
    browser.evaluate("wiretapeView.select(2)")  # an imu record
    browser.evaluate("document.getElementById('follow').click()")
    assert browser.evaluate("document.getElementById('stream').hidden") is False
    blocks = browser.evaluate(
        "Array.from(document.querySelectorAll('#stream-text span'))"
        ".map(s => [s.className, s.textContent, s.dataset.record])")
    assert blocks == [[("stream-tx" if n % 2 == 0 else "stream-rx"),
                       (b"IMU?\n" if n % 2 == 0 else b"ACC 0.%d 9.81\n" % (n // 2)).decode(),
                       str(4 * (n // 2) + 2 + n % 2)] for n in range(8)]
    title = browser.evaluate("document.getElementById('stream-title').textContent")
    assert "of channel imu" in title and "tx (host to device) 20 bytes" in title
    browser.evaluate("document.querySelectorAll('#stream-text span')[3].click()")
    assert browser.evaluate("document.getElementById('hex').dataset.record") == "7"


def test_two_cursors_measure_the_time_between_records(browser):
    browser.evaluate("wiretapeView.select(0)")
    key(browser, "a")
    browser.evaluate("wiretapeView.select(5)")
    browser.evaluate("document.getElementById('cursor-b').click()")
    cursors = "document.getElementById('cursors')"
    assert browser.evaluate(f"{cursors}.dataset.deltaNs") == str(RECORDS[5][0] - RECORDS[0][0])
    assert "Δt B−A = 102.000 ms" in browser.evaluate(f"{cursors}.textContent")
    # Shift+click on the timeline moves cursor B to the record there.
    left, top = browser.evaluate(
        "(r => [r.left, r.top])(document.getElementById('lanes').getBoundingClientRect())")
    x = left + browser.evaluate(f"wiretapeView.xOf({RECORDS[12][0]})")
    y = top + browser.evaluate("wiretapeView.laneMiddle('tx')")
    browser.mouse("mousePressed", x, y, button="left", buttons=1, clickCount=1, modifiers=8)
    browser.mouse("mouseReleased", x, y, button="left", buttons=0, clickCount=1, modifiers=8)
    wait_until(lambda: browser.evaluate(f"{cursors}.dataset.b") == "12", what="cursor B moved")
    assert browser.evaluate(f"{cursors}.dataset.deltaNs") == str(RECORDS[12][0] - RECORDS[0][0])


def test_a_minute_of_silence_is_folded_and_can_be_unfolded(browser):
    assert browser.evaluate("wiretapeView.folds()") == [[RECORDS[11][0], RECORDS[12][0]]]
    width = browser.evaluate("document.getElementById('lanes').clientWidth")

    def gap_pixels():
        return browser.evaluate(f"wiretapeView.xOf({RECORDS[12][0]}) - wiretapeView.xOf({RECORDS[11][0]})")
    assert gap_pixels() < width * 0.05  # folded: the polls fill the width
    browser.evaluate("document.getElementById('fold').click(); document.getElementById('fit').click()")
    wait_until(lambda: gap_pixels() > width * 0.5, what="the gap unfolded")


def test_lane_labels_fit_beside_the_lanes(browser):
    # The labels' column is as wide as the longest label: none is clipped.
    needed = browser.evaluate(
        "(c => { c.font = '11px sans-serif'; return c.measureText('gps-receiver-on-the-mast events').width; })"
        "(document.createElement('canvas').getContext('2d'))")
    assert browser.evaluate("wiretapeView.plotLeft") >= needed + 4
