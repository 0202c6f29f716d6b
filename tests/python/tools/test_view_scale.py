"""wiretape view on a session larger than a page holds in detail (docs/view.md,
"Large sessions"): the records are streamed with bounded memory, the page
is bounded, it holds the first records in detail and the whole session in
its summary timeline, and both the page and the command say so."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

from view_browser import DevTools, element_text
from wiretape import _core
from wiretape.tools.view import (DETAIL_BYTES, DETAIL_RECORDS, MAX_RECORD_BYTES, detail_limit,
                                 page_data)

# As large as writes in a few seconds here: 300,000 exchanges.
EXCHANGES = 300_000


def polling_session(path: Path, exchanges: int) -> Path:
    with _core.SessionWriter(os.fspath(path)) as writer:
        for n in range(exchanges):
            writer.write("tx", 1_000_000 * n + 1, b"GET %d\n" % n)
            writer.write("rx", 1_000_000 * n + 200_000, b"VALUE %d\n" % (n * 7))
    return path


def test_the_detail_is_the_first_records_within_both_bounds():
    assert detail_limit(0, 0)
    assert detail_limit(DETAIL_RECORDS - 1, DETAIL_BYTES - 1)
    assert not detail_limit(DETAIL_RECORDS, 0)  # records past the count
    assert not detail_limit(10, DETAIL_BYTES)  # or past the bytes
    # A page of the largest detail stays openable: bytes as base64, and a
    # few dozen bytes of columns per record.
    assert DETAIL_BYTES * 4 / 3 + DETAIL_RECORDS * 64 < 48 << 20


def test_large_records_end_the_detail_at_its_bytes(tmp_path):
    session = tmp_path / "bulk.wtape"
    count = DETAIL_BYTES // MAX_RECORD_BYTES + 50
    with _core.SessionWriter(os.fspath(session)) as writer:
        for n in range(count):
            writer.write("rx", 1_000 * n, bytes([n % 256]) * MAX_RECORD_BYTES)
    data = page_data(session)
    shown = data["decimated"]["shown"]
    assert shown == DETAIL_BYTES // MAX_RECORD_BYTES
    assert data["decimated"]["records"] == count == data["session"]["records"]
    assert len(data["records"]["t_ns"]) == shown
    binned = sum(bin[1] for lane in data["summary"]["lanes"] for bin in lane["bins"])
    assert binned == count  # every record in the summary


def peak_rss_mb(argv) -> tuple:
    """Runs argv; (its peak RSS in MB, from wait4, its stderr)."""
    child = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    stderr = child.stderr.read().decode()
    _, status, usage = os.wait4(child.pid, 0)
    child.stderr.close()
    assert os.waitstatus_to_exitcode(status) == 0, stderr
    return usage.ru_maxrss / 1024, stderr


def test_a_large_session_is_written_with_bounded_memory_into_a_bounded_page(tmp_path):
    session = polling_session(tmp_path / "big.wtape", EXCHANGES)
    page = tmp_path / "big.html"
    python = [sys.executable, "-c", "import wiretape.cli"]
    baseline, _ = peak_rss_mb(python)
    rss, stderr = peak_rss_mb([sys.executable, "-m", "wiretape.cli", "view", os.fspath(session),
                               "-o", os.fspath(page)])
    # Generous: what the detail holds, whatever the session's size (the
    # whole of it held in lists took ten times that).
    assert rss - baseline < 250, f"{rss:.0f} MB peak RSS ({baseline:.0f} MB to start Python)"
    assert page.stat().st_size < 40e6
    said = f"{2 * EXCHANGES:,} records, more than a page holds in detail"
    assert said in stderr and f"the first {DETAIL_RECORDS:,}" in stderr

    browser = DevTools(tmp_path)
    try:
        browser.open(page.resolve().as_uri())
        dom = browser.evaluate("document.documentElement.outerHTML")
        assert browser.console() == []
    finally:
        browser.close()
    assert said in element_text(dom, "notes")
    assert f"{2 * EXCHANGES} records" in element_text(dom, "summary")
    assert re.search(r'data-rows="%d"' % DETAIL_RECORDS, dom)


def test_a_small_session_is_held_whole(tmp_path):
    data = page_data(polling_session(tmp_path / "small.wtape", 10))
    assert data["decimated"] is None
    assert len(data["records"]["t_ns"]) == data["session"]["records"] == 20
