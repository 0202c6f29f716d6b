"""Headless Chromium for the tests of `wiretape view` (docs/view.md, "How
it is tested"): driven through its own DevTools protocol over
--remote-debugging-pipe, no driver to install; the page's DOM, console and
screenshots read back. A test skips, saying so, when chromium is missing."""

from __future__ import annotations

import base64
import html
import json
import os
import re
import select
import shutil
import struct
import time
import zlib
from pathlib import Path

import pytest

from devices import wait_until


def chromium() -> str:
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name) or (f"/usr/bin/{name}" if os.path.exists(f"/usr/bin/{name}") else None)
        if found:
            return found
    pytest.skip("chromium is not installed (Debian: apt-get install chromium): "
                "the view is tested in headless Chromium")



class DevTools:
    """Headless Chromium driven through --remote-debugging-pipe (JSON
    messages ended by NUL on its fds 3 and 4): mouse events as a user makes
    them, and the page's state read back."""

    def __init__(self, tmp_path: Path):
        to_browser_r, self._to_browser = os.pipe()
        self._from_browser, from_browser_w = os.pipe()
        null = os.open(os.devnull, os.O_RDWR)
        actions = [(os.POSIX_SPAWN_DUP2, to_browser_r, 3), (os.POSIX_SPAWN_DUP2, from_browser_w, 4),
                   (os.POSIX_SPAWN_DUP2, null, 1), (os.POSIX_SPAWN_DUP2, null, 2)]
        argv = [chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                "--remote-debugging-pipe", f"--user-data-dir={tmp_path / 'chromium-devtools'}",
                "--window-size=1200,900", "--force-device-scale-factor=1", "about:blank"]
        self._pid = os.posix_spawn(argv[0], argv, os.environ, file_actions=actions)
        for fd in (to_browser_r, from_browser_w, null):
            os.close(fd)
        self._buffer = b""
        self._next_id = 0
        self._session = None
        self.events = []

    def call(self, method, session=True, **params):
        self._next_id += 1
        message = {"id": self._next_id, "method": method, "params": params}
        if session and self._session:
            message["sessionId"] = self._session
        os.write(self._to_browser, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + 60
        while True:
            while b"\0" in self._buffer:
                raw, self._buffer = self._buffer.split(b"\0", 1)
                reply = json.loads(raw)
                if reply.get("id") == self._next_id:
                    assert "error" not in reply, reply["error"]
                    return reply["result"]
                if "method" in reply:
                    self.events.append(reply)
            remaining = deadline - time.monotonic()
            assert remaining > 0, f"no answer to {method}"
            ready, _, _ = select.select([self._from_browser], [], [], remaining)
            if ready:
                chunk = os.read(self._from_browser, 1 << 16)
                assert chunk, "chromium went away"
                self._buffer += chunk

    def open(self, url: str) -> None:
        target = self.call("Target.createTarget", url="about:blank")["targetId"]
        self._session = self.call("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]
        self.call("Emulation.setDeviceMetricsOverride", width=1200, height=900,
                  deviceScaleFactor=1, mobile=False)
        for domain in ("Runtime", "Log", "Page"):
            self.call(f"{domain}.enable")
        self.call("Page.navigate", url=url)
        wait_until(lambda: self.evaluate("location.href.startsWith('file:') && "
                                         "!!document.documentElement && "
                                         "document.documentElement.dataset.ready") == "true",
                   what="the page to be ready")

    def evaluate(self, expression: str):
        result = self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        assert "exceptionDetails" not in result, result
        return result["result"].get("value")

    def console(self):
        """What the page logged: console calls, uncaught exceptions, and
        the browser's errors and warnings about it (a refused fetch...)."""
        self.evaluate("0")  # every event before this answer has arrived
        found = []
        for event in self.events:
            method, params = event["method"], event["params"]
            if method == "Runtime.consoleAPICalled":
                found.append(f"console.{params['type']}: {params['args']}")
            elif method == "Runtime.exceptionThrown":
                found.append(f"exception: {params['exceptionDetails']}")
            elif method == "Log.entryAdded" and params["entry"]["level"] in ("error", "warning"):
                found.append(f"log: {params['entry']}")
        return found

    def mouse(self, kind: str, x: float, y: float, **extra) -> None:
        self.call("Input.dispatchMouseEvent", type=kind, x=x, y=y, **extra)

    def close(self) -> None:
        try:
            self.call("Browser.close", session=False)
        except (AssertionError, OSError):
            os.kill(self._pid, 9)
        os.waitpid(self._pid, 0)
        os.close(self._to_browser)
        os.close(self._from_browser)



def open_page(page: Path, tmp_path: Path, fragment: str = "", screenshot: Path = None):
    """The page once ready in headless Chromium: (its DOM, the console
    messages and errors it logged); with `screenshot`, its picture saved
    there too."""
    browser = DevTools(tmp_path)
    try:
        browser.open(page.resolve().as_uri() + fragment)
        dom = browser.evaluate("document.documentElement.outerHTML")
        if screenshot:
            picture = browser.call("Page.captureScreenshot", format="png")["data"]
            screenshot.write_bytes(base64.b64decode(picture))
        return dom, browser.console()
    finally:
        browser.close()


def png_pixels(path: Path):
    """The RGB pixels of a non-interlaced 8-bit RGB or RGBA PNG (Chromium's
    screenshots), as a set of colours."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    at, chunks, width = 8, b"", 0
    while at < len(data):
        length, kind = struct.unpack(">I4s", data[at:at + 8])
        body = data[at + 8:at + 8 + length]
        if kind == b"IHDR":
            width, height, depth, colour = struct.unpack(">IIBB", body[:10])
            assert depth == 8 and colour in (2, 6), (depth, colour)
            channels = 3 if colour == 2 else 4
        elif kind == b"IDAT":
            chunks += body
        at += 12 + length
    raw = zlib.decompress(chunks)
    stride = width * channels
    previous = bytearray(stride)
    colours = set()
    for row in range(height):
        line = raw[row * (stride + 1):(row + 1) * (stride + 1)]
        kind, current = line[0], bytearray(line[1:])
        for i in range(stride):
            left = current[i - channels] if i >= channels else 0
            up = previous[i]
            corner = previous[i - channels] if i >= channels else 0
            if kind == 1:
                current[i] = (current[i] + left) & 0xFF
            elif kind == 2:
                current[i] = (current[i] + up) & 0xFF
            elif kind == 3:
                current[i] = (current[i] + (left + up) // 2) & 0xFF
            elif kind == 4:
                p = left + up - corner
                pa, pb, pc = abs(p - left), abs(p - up), abs(p - corner)
                predictor = left if pa <= pb and pa <= pc else up if pb <= pc else corner
                current[i] = (current[i] + predictor) & 0xFF
        for i in range(0, stride, channels):
            colours.add(tuple(current[i:i + 3]))
        previous = current
    return colours


def element_text(dom: str, element_id: str) -> str:
    match = re.search(rf'id="{element_id}"[^>]*>(.*?)</(?:pre|div|section)>', dom, re.S)
    assert match, f"no #{element_id} in the page"
    return html.unescape(re.sub(r"<[^>]+>", "\n", match.group(1)))


def table_rows(dom: str, section_id: str):
    match = re.search(rf'<div id="{section_id}">(.*?)</table>', dom, re.S)
    assert match, f"no #{section_id} list in the page"
    rows = re.findall(r"<tr([^>]*)>(.*?)</tr>", match.group(1), re.S)
    return [(attributes, [html.unescape(cell) for cell in re.findall(r"<td>(.*?)</td>", cells, re.S)])
            for attributes, cells in rows[1:]]
