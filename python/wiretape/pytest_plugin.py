"""pytest plugin: driver tests that record a device once and replay it in CI.

Registered by the ``pytest11`` entry point ``wiretape``. Every test that uses
one of the fixtures gets a *cassette*, a session file at
``<test dir>/recordings/<module>/<test>.wtape``, and either records it from
the real device or replays it:

``--wiretape-record=none`` (default)
    replay only; a missing cassette is an error naming its path and the
    command that records it.
``--wiretape-record=once``
    record when the cassette is missing, else replay.
``--wiretape-record=rewrite``
    always record anew; a test that fails while recording leaves the previous
    cassette as it was.

Recording needs the device: ``--wiretape-device=OPTS`` (a wiretape option
string; a bare path means ``type=serial,device=PATH``). Both settings can
also come from the marker (``record=``, ``device=``) or the ini file
(``wiretape_record``, ``wiretape_device``); the command line beats the marker,
which beats the ini file.

Marker: ``@pytest.mark.wiretape(cassette=None, device=None, record=None,
**replay_keys)``. ``cassette`` is a path relative to the test file's directory
(or absolute); the replay keys are those of ``type=replay`` (``timing``,
``match``, ``check``, ``unused``, ...). Replays default to ``timing=none``.

Fixtures:
``wiretape_port``     the opened ``wiretape.Port``: the device recording to the
                      cassette, or the replay. Closed when the test ends; what
                      closing raises (``unused=error``) fails the test.
``wiretape_options``  the option string that opens that port.
``wiretape_url``      a pyserial URL for it (``wiretape://`` or
                      ``wiretape+record://``).
``wiretape_pty``      the path of a pseudo-terminal serving the replay (or
                      proxying the device while recording), for drivers that
                      open a device path themselves.
``wiretape_cassette`` what the plugin decided: ``path``, ``recording``,
                      ``options``...

A cassette is written only when the test passes: recording goes to a
temporary file next to the cassette that replaces it at the end.
"""

from __future__ import annotations

import hashlib
import os
import re
import urllib.parse
import warnings
from pathlib import Path
from typing import Any, Dict, List, Optional

import pytest

RECORD_MODES = ("none", "once", "rewrite")
DEFAULT_REPLAY_KEYS = {"timing": "none"}
MAX_NAME_LENGTH = 100

_SESSION_KEY = pytest.StashKey["WiretapeCassette"]()
_REPORTS_KEY = pytest.StashKey[Dict[str, Any]]()


class WiretapeWarning(UserWarning):
    """Something about a cassette deserves a look but does not fail the test."""


# --------------------------------------------------------------------------
# option strings


def quote_option(value) -> str:
    """A value for a wiretape option string, double-quoted if it needs to be."""
    if isinstance(value, bool):
        return "true" if value else "false"
    text = str(value)
    if text and not (set(text) & set(", \t\r\n\"\\=")):
        return text
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _plain(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def device_options(device: str) -> str:
    """The option string for a device setting: a bare path means a serial
    device (``type=serial,device=PATH``)."""
    text = device.strip()
    if "=" not in text:
        return f"type=serial,device={quote_option(text)}"
    return text


# --------------------------------------------------------------------------
# cassette names


def safe_file_name(name: str) -> str:
    """`name` made safe for a file name (letters, digits and ``._-=+`` kept);
    names longer than MAX_NAME_LENGTH are cut and given a hash of the whole
    name, so that distinct tests keep distinct cassettes."""
    safe = re.sub(r"[^A-Za-z0-9._=+-]+", "_", name).strip("_.")
    if not safe:
        safe = "test"
    if len(safe) > MAX_NAME_LENGTH:
        digest = hashlib.sha1(name.encode("utf-8")).hexdigest()[:12]
        safe = safe[: MAX_NAME_LENGTH - 13].rstrip("_.") + "-" + digest
    return safe


def default_cassette_path(item) -> Path:
    test_file = Path(str(item.path if hasattr(item, "path") else item.fspath))
    # nodeid "dir/test_x.py::TestA::test_b[p]" -> "TestA.test_b[p]"
    test_name = item.nodeid.split("::", 1)[1] if "::" in item.nodeid else item.name
    test_name = test_name.replace("::", ".")
    return test_file.parent / "recordings" / test_file.stem / (safe_file_name(test_name) + ".wtape")


# --------------------------------------------------------------------------
# settings: command line > marker > ini


def pytest_addoption(parser):
    group = parser.getgroup("wiretape", "wiretape: record and replay device sessions")
    group.addoption(
        "--wiretape-record", dest="wiretape_record", default=None, choices=RECORD_MODES,
        help="none: replay only (default); once: record missing cassettes; "
             "rewrite: record every cassette anew")
    group.addoption(
        "--wiretape-device", dest="wiretape_device", default=None, metavar="OPTS",
        help="the device to record from: a wiretape option string "
             "(e.g. type=serial,device=/dev/ttyACM0,baud=115200) or a serial device path")
    parser.addini("wiretape_record", "wiretape record mode: none, once or rewrite", default="")
    parser.addini("wiretape_device", "wiretape device option string to record from", default="")


def pytest_configure(config):
    config.addinivalue_line(
        "markers",
        "wiretape(cassette=None, device=None, record=None, **replay_keys): "
        "the wiretape cassette, device and record mode of a test, and replay keys "
        "(timing, match, check, unused...) for its replay")
    try:
        from wiretape import urlhandler
    except ImportError:  # pragma: no cover - the package ships both
        return
    urlhandler.register()


def _marker_settings(item) -> Dict[str, Any]:
    merged: Dict[str, Any] = {}
    for marker in reversed(list(item.iter_markers("wiretape"))):  # closest last: wins
        if len(marker.args) > 1:
            pytest.fail(
                f"{item.nodeid}: @pytest.mark.wiretape takes at most one positional "
                f"argument (the cassette), got {marker.args!r}", pytrace=False)
        if marker.args:
            merged["cassette"] = marker.args[0]
        merged.update(marker.kwargs)
    return merged


def _first_given(*values) -> Optional[str]:
    for value in values:
        if value is not None and value != "":
            return value
    return None


class WiretapeCassette:
    """What the plugin decided for one test, and the cleanup it owes."""

    def __init__(self, item):
        self.item = item
        config = item.config
        marker = _marker_settings(item)
        self.marker = marker

        where = {"command line": config.getoption("wiretape_record"),
                 "marker": marker.pop("record", None),
                 "ini": config.getini("wiretape_record")}
        record = _first_given(*where.values()) or "none"
        if record not in RECORD_MODES:
            source = next(k for k, v in where.items() if v not in (None, ""))
            pytest.fail(
                f"{item.nodeid}: wiretape record mode {record!r} (from the {source}) "
                f"is not one of {', '.join(RECORD_MODES)}", pytrace=False)
        self.record_mode = record
        self.device = _first_given(config.getoption("wiretape_device"),
                                   marker.pop("device", None),
                                   config.getini("wiretape_device"))

        cassette = marker.pop("cassette", None)
        if cassette is None:
            self.path = default_cassette_path(item)
        else:
            self.path = Path(os.fspath(cassette))
            if not self.path.is_absolute():
                self.path = Path(str(item.path)).parent / self.path
        self.replay_keys = dict(DEFAULT_REPLAY_KEYS)
        self.replay_keys.update(marker)  # what is left: replay keys

        if record == "rewrite" or (record == "once" and not self.path.exists()):
            self.recording = True
        else:
            self.recording = False
        self.partial_path = self.path.with_name(f"{self.path.name}.recording-{os.getpid()}")
        self._ports: List[Any] = []
        self._cleanups: List[Any] = []
        self._checked = False

    # -- what fixtures use ---------------------------------------------------
    @property
    def options(self) -> str:
        """The option string that opens the device (recording) or the replay."""
        if self.recording:
            return (device_options(self.device) + ",log=" + quote_option(str(self.partial_path))
                    + ",meta_pytest_node=" + quote_option(self.item.nodeid))
        return "type=replay,file=" + quote_option(str(self.path)) + "," + self.replay_options

    @property
    def replay_options(self) -> str:
        """The replay keys alone (``timing=none,...``)."""
        return ",".join(f"{key}={quote_option(value)}" for key, value in self.replay_keys.items())

    @property
    def url(self) -> str:
        if self.recording:
            query = urllib.parse.urlencode({"options": device_options(self.device)})
            return f"wiretape+record://{urllib.parse.quote(str(self.partial_path))}?{query}"
        query = urllib.parse.urlencode({key: _plain(value)
                                        for key, value in self.replay_keys.items()})
        return f"wiretape://{urllib.parse.quote(str(self.path))}?{query}"

    def record_command(self) -> str:
        device = self.device or "OPTS"
        return (f"pytest --wiretape-record=once --wiretape-device={device!r} "
                f"{self.item.nodeid!r}")

    def prepare(self):
        """Checks that the test can run: a cassette to replay, or a device to
        record from; makes the cassette's directory when recording."""
        if self.recording:
            if not self.device:
                pytest.fail(
                    f"wiretape: cassette {self.path} must be recorded "
                    f"(--wiretape-record={self.record_mode}) but no device is given: "
                    "pass --wiretape-device=OPTS, the marker's device=, or set "
                    "wiretape_device in the ini file", pytrace=False)
            self.path.parent.mkdir(parents=True, exist_ok=True)
            if self.partial_path.exists():
                self.partial_path.unlink()
        elif not self.path.exists():
            pytest.fail(
                f"wiretape: no recording for {self.item.nodeid}: {self.path} does not exist.\n"
                f"Record it from the device with:\n    {self.record_command()}",
                pytrace=False)

    def open_port(self):
        import wiretape

        try:
            port = wiretape.open_port(self.options)
        except wiretape.OptionError as error:
            source = "the device setting" if self.recording else "the marker's replay keys"
            pytest.fail(f"{self.item.nodeid}: bad wiretape options (check {source}): "
                        f"{error}\n    options: {self.options}", pytrace=False)
        self._ports.append(port)
        return port

    def add_cleanup(self, cleanup):
        self._cleanups.append(cleanup)

    def close_ports(self):
        """Closes what the plugin opened; raises what closing raises (a replay
        with unused=error reports unused data here)."""
        errors = []
        while self._cleanups:
            try:
                self._cleanups.pop()()
            except Exception as error:  # keep closing the rest
                errors.append(error)
        while self._ports:
            port = self._ports.pop()
            try:
                if _is_open(port):
                    port.close()
            except Exception as error:
                errors.append(error)
        if errors:
            raise errors[0]

    def close_ports_quietly(self):
        try:
            self.close_ports()
        except Exception:
            pass

    def finish(self, passed: bool):
        """Keeps a recording made by a passing test; otherwise throws it away
        and leaves any previous cassette as it was."""
        self.close_ports_quietly()
        if not self.recording:
            return
        if not passed:
            if self.partial_path.exists():
                self.partial_path.unlink()
            return
        if not self.partial_path.exists():
            warnings.warn(WiretapeWarning(
                f"{self.item.nodeid} passed while recording but opened no port from "
                f"wiretape_options: nothing was written to {self.path}"))
            return
        os.replace(self.partial_path, self.path)

    def describe(self) -> str:
        lines = [f"cassette: {self.path}",
                 f"mode: {'recording' if self.recording else 'replay'} "
                 f"(--wiretape-record={self.record_mode})",
                 f"options: {self.options}"]
        if not self.recording:
            lines.append(f"to record it again: {self.record_command().replace('=once', '=rewrite')}")
        return "\n".join(lines)


# --------------------------------------------------------------------------
# hooks: test outcome, port closing inside the test's call


@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_runtest_makereport(item, call):
    report = yield
    item.stash.setdefault(_REPORTS_KEY, {})[report.when] = report
    session = item.stash.get(_SESSION_KEY, None)
    if session is not None and report.failed and report.when in ("setup", "call"):
        report.sections.append(("wiretape", session.describe()))
    return report


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item):
    session = item.stash.get(_SESSION_KEY, None)
    try:
        result = yield
    except BaseException:
        if session is not None:
            session.close_ports_quietly()
        raise
    if session is not None:
        # Closing may raise (unused recorded data under unused=error): that
        # belongs to the test's result, not to its teardown.
        session.close_ports()
    return result


def _is_open(port) -> bool:
    state = port.is_open
    return bool(state() if callable(state) else state)


def _test_passed(item) -> bool:
    reports = item.stash.get(_REPORTS_KEY, {})
    return all(when in reports and reports[when].passed for when in ("setup", "call"))


# --------------------------------------------------------------------------
# fixtures


@pytest.fixture
def wiretape_cassette(request):
    """The cassette of this test: path, recording or replay, option string."""
    session = WiretapeCassette(request.node)
    session.prepare()
    request.node.stash[_SESSION_KEY] = session
    yield session
    session.finish(_test_passed(request.node))


@pytest.fixture
def wiretape_options(wiretape_cassette) -> str:
    """The option string that opens the device (recording) or the replay."""
    return wiretape_cassette.options


@pytest.fixture
def wiretape_port(wiretape_cassette):
    """The opened port: the device recording to the cassette, or the replay."""
    port = wiretape_cassette.open_port()
    yield port
    try:
        if _is_open(port):
            port.close()
    except Exception:
        pass  # already reported by the call, or the test failed anyway


@pytest.fixture
def wiretape_url(wiretape_cassette) -> str:
    """A pyserial URL (``serial.serial_for_url``) for the device or the replay.
    Close the pyserial port before the test ends."""
    return wiretape_cassette.url


@pytest.fixture
def wiretape_pty(wiretape_cassette, tmp_path_factory) -> str:
    """The path of a pseudo-terminal serving the replay, or, while recording,
    proxying the device; for drivers that open a device path themselves."""
    from wiretape import bridge

    link = tmp_path_factory.mktemp("wiretape-pty") / "tty"
    try:
        if wiretape_cassette.recording:
            handle = bridge.record(device_options(wiretape_cassette.device),
                                   str(wiretape_cassette.partial_path), pty=str(link))
        else:
            handle = bridge.serve_replay(str(wiretape_cassette.path), pty=str(link),
                                         replay_options=wiretape_cassette.replay_options)
    except NotImplementedError as error:
        pytest.skip(f"wiretape_pty needs wiretape.bridge, which this build lacks: {error}")

    def stop():
        handle.stop()
        handle.wait(10)
        result = handle.result()
        if not result.ok:
            raise AssertionError(f"wiretape_pty ({result.outcome}): {result.message or result}")

    wiretape_cassette.add_cleanup(stop)
    for name in ("pty_path", "pty"):
        path = getattr(handle, name, None)
        if callable(path):
            path = path()
        if path:
            break
    return str(path or link)
