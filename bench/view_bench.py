#!/usr/bin/env python3
"""wiretape view's figures (bench/run.py, group "view"): prints one JSON
line. Usage: view_bench.py [RECORDS]

A generated session of RECORDS records (default 100,000: tx requests and rx
answers 1 ms apart, as a polling driver makes; 5,000,000 records are the
2.5 million exchanges of docs/view.md "Large sessions") is written as a
page by `wiretape view` in a process of its own (timed: write_s; its peak
RSS from wait4: peak_rss_MB), then opened in headless Chromium three
times; the page sets data-first-paint-ms on <html> when its timeline is
first drawn (performance.now(), from the start of navigation: parsing the
page and its data included). first_paint_ms is the median.
"""

import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from wiretape import _core


def chromium() -> str:
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    sys.exit("chromium is not installed (Debian: apt-get install chromium)")


def first_paint_ms(browser: str, page: Path, profile: Path) -> float:
    result = subprocess.run(
        [browser, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
         f"--user-data-dir={profile}", "--window-size=1200,900", "--virtual-time-budget=10000",
         "--dump-dom", page.resolve().as_uri()], capture_output=True, text=True, timeout=300)
    match = re.search(r'data-first-paint-ms="([0-9.]+)"', result.stdout)
    if not match:
        sys.exit("the page did not paint: " + result.stderr[-500:])
    return float(match.group(1))


def write_page(session: Path, page: Path):
    """`wiretape view SESSION -o PAGE` in a child: (seconds, peak RSS MB)."""
    started = time.perf_counter()
    child = subprocess.Popen([sys.executable, "-m", "wiretape.cli", "view", "-q",
                              os.fspath(session), "-o", os.fspath(page)],
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(child.pid, 0)
    seconds = time.perf_counter() - started
    child.returncode = os.waitstatus_to_exitcode(status)
    if child.returncode != 0:
        sys.exit("wiretape view failed: " + child.stderr.read().decode()[-500:])
    return seconds, usage.ru_maxrss / 1024


def main() -> int:
    records = int(sys.argv[1]) if len(sys.argv) > 1 else 100_000
    browser = chromium()
    with tempfile.TemporaryDirectory(prefix="wiretape-view-bench-") as directory:
        work = Path(directory)
        session = work / "big.wtape"
        with _core.SessionWriter(os.fspath(session)) as writer:
            for n in range(records // 2):
                writer.write("tx", 1_000_000 * n + 1, b"GET %d\n" % n)
                writer.write("rx", 1_000_000 * n + 200_000, b"VALUE %d\n" % (n * 7))
        session_mb = round(session.stat().st_size / 1e6, 1)
        write_s, rss_mb = write_page(session, work / "big.html")
        page = work / "big.html"
        page_mb = round(page.stat().st_size / 1e6, 2)
        paints = [first_paint_ms(browser, page, work / f"profile-{n}") for n in range(3)]
    print(json.dumps({"records": records, "session_MB": session_mb, "write_s": round(write_s, 3),
                      "peak_rss_MB": round(rss_mb, 1), "page_MB": page_mb,
                      "first_paint_ms": statistics.median(paints), "paints_ms": paints}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
