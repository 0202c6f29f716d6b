"""The cassette of one test: where its recording lives, whether the test
records it or replays it, and the option string that opens either.

Settings come from, strongest first: the command line
(``--wiretape-record``, ``--wiretape-device``), the test's
``@pytest.mark.wiretape`` marker, the ``wiretape_config`` fixture (which a
conftest overrides to give a directory's tests their defaults), the ini file
(``wiretape_record``, ``wiretape_device``), and the defaults: record mode
``none``, replay ``timing=none``.
"""

from __future__ import annotations

import datetime
import os
import re
import shlex
import time
import urllib.parse
import warnings
from pathlib import Path
from typing import Any, Callable, Dict, List, Mapping

import pytest

import wiretape
from wiretape import _core
from wiretape._core import device_options, option_string
from wiretape.options import join_options

from .episodes import append_channels

RECORD_MODES = ("none", "once", "new_episodes", "rewrite", "all")
#: VCR's names for ours.
RECORD_MODE_ALIASES = {"all": "rewrite"}
DEFAULT_REPLAY_KEYS = {"timing": "none"}
MAX_NAME_LENGTH = _core.MAX_CASSETTE_NAME_LENGTH


class WiretapeWarning(UserWarning):
    """Something about a cassette deserves a look but does not fail the test."""


# --------------------------------------------------------------------------
# option strings


def _option_value(value: Any) -> Any:
    """A marker or ini value for option_string: a number, a boolean, text or
    a path as it is (C++ writes them), anything else as its text."""
    if isinstance(value, (str, int, float, bool, os.PathLike)):
        return value
    return str(value)


# --------------------------------------------------------------------------
# publishing a recording


def publish_recording(recording: Path, cassette: Path) -> None:
    """Moves a finished recording to `cassette`, its header naming the
    cassette (``log=t.wtape``) instead of this machine's temporary path
    (``log=/tmp/pytest-of-me/.../t.wtape.recording-4242``); the GoogleTest
    helper's rule (wiretape/cassette_names.hpp), bound. A recording that is
    damaged (a failed write) is moved as it is, so that nothing it holds is
    lost."""
    _core.publish_recording(recording, cassette)


#: A recording in progress beside its cassette: ``NAME.recording-PID``
#: (and ``.header``, publish_recording's rewrite of it), PID the recorder's.
_PARTIAL_RECORDING = re.compile(r"^(?P<cassette>.+)\.recording-(?P<pid>[0-9]+)(?:\.header)?$")


def _process_exists(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return pid > 0  # another user's process (or a PID no process has)
    return True


def remove_stale_recordings(folder: Path) -> List[Path]:
    """Removes the recordings in progress in `folder` whose process is gone
    (a pytest ended by SIGKILL, or SIGTERM, never reaches its clean-up) and
    returns them. A recording of a live process is left alone (another
    pytest recording beside this one, or this one)."""
    removed = []
    try:
        names = sorted(os.listdir(folder))
    except OSError:
        return removed
    for name in names:
        found = _PARTIAL_RECORDING.match(name)
        if found is None or _process_exists(int(found["pid"])):
            continue
        path = folder / name
        try:
            if path.is_file() and not path.is_symlink():
                path.unlink()
                removed.append(path)
        except OSError:
            pass  # not ours to remove after all: left as it is
    return removed


# --------------------------------------------------------------------------
# cassette names


# The rules are the C++ ones (wiretape/cassette_names.hpp), shared with the
# GoogleTest helper: a test gets the same name from either.
safe_file_name = _core.safe_file_name


def source_file_of(item: pytest.Item) -> Path:
    return Path(str(item.path))


def default_cassette_dir(item: pytest.Item) -> Path:
    """``<test dir>/recordings/<test module>``: next to the test file."""
    return Path(_core.cassette_directory(source_file_of(item)))


def cassette_file_name(item: pytest.Item) -> str:
    """The test's cassette file name: nodeid ``dir/test_x.py::TestA::test_b``
    gives ``TestA.test_b.wtape``; a name that must change to be a file name
    (``test_b[p 1]``) ends with a hash of the whole name (safe_file_name)."""
    return _core.cassette_file_name(_name_parts(item))


def _name_parts(item: pytest.Item) -> List[str]:
    """The classes holding the test, then the test's name with its
    parameters. Only the part of the nodeid before the name is split at
    ``::``: a parameter id may hold ``::`` itself (``test_f[a::b]`` is not the
    class ``test_f[a`` and the test ``b]``, which would be read as
    ``test_f[a.b]``, another test's cassette)."""
    nodeid, name = item.nodeid, item.name
    if not nodeid.endswith(name):
        return [name]
    return nodeid[:len(nodeid) - len(name)].split("::")[1:-1] + [name]


# --------------------------------------------------------------------------
# settings


def marker_settings(item: pytest.Item) -> Dict[str, Any]:
    """The keys of the test's wiretape markers, the closest marker winning."""
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


def _first_given(*values):
    for value in values:
        if value is not None and value != "":
            return value
    return None


def _ini_flag(config, name: str) -> bool:
    return str(config.getini(name)).strip().lower() in ("1", "true", "yes", "on")


def _live_url(device: str, nodeid: str) -> str:
    """pyserial's own URL for a device wiretape_url opens live (pyserial's
    clients apply the driver's settings to the serial lines)."""
    options = dict(_core.parse_options(device))
    kind = options.get("type")
    if kind == "serial" and options.get("device"):
        return options["device"]
    if kind in ("rfc2217", "tcp") and options.get("host") and options.get("port"):
        host = f"[{options['host']}]" if ":" in options["host"] else options["host"]
        scheme = "rfc2217" if kind == "rfc2217" else "socket"
        return f"{scheme}://{host}:{options['port']}"
    pytest.fail(f"{nodeid}: wiretape_url under --wiretape-live opens serial, RFC 2217 and TCP "
                f"devices (pyserial's own URLs); {device!r} is none of them: use "
                "wiretape_port", pytrace=False)


def _checked_ports(ports: Any, nodeid: str):
    """The marker's ``ports=``: a dict of channel name to device (an
    option string or a serial device path), names as channels take them
    (``_core.channel_name_problem``); None when not given."""
    if ports is None:
        return None
    if not isinstance(ports, Mapping) or not ports:
        pytest.fail(f"{nodeid}: wiretape marker: ports= takes a dict of channel name to "
                    "device (ports={'gps': '/dev/ttyUSB0', 'rtk': 'type=tcp,...'}), not "
                    f"{ports!r}", pytrace=False)
    checked: Dict[str, str] = {}
    for name, device in ports.items():
        problem = _core.channel_name_problem(name) if isinstance(name, str) else "not a string"
        if problem is not None:
            pytest.fail(f"{nodeid}: wiretape marker: ports= channel name {name!r}: {problem}",
                        pytrace=False)
        try:
            checked[name] = device_options(os.fspath(device))
        except (TypeError, ValueError, wiretape.OptionError) as error:
            pytest.fail(f"{nodeid}: wiretape marker: ports= {name!r}: {error}", pytrace=False)
    return checked


class WiretapeCassette:
    """What the plugin decided for one test, and the cleanup it owes.

    `settings` are the ``wiretape_config`` fixture's (the same keys as the
    marker's); `cassette_dir` is the ``wiretape_cassette_dir`` fixture's.
    """

    def __init__(self, item: pytest.Item, settings: Mapping[str, Any], cassette_dir: Path):
        if not isinstance(settings, Mapping):
            pytest.fail(f"{item.nodeid}: the wiretape_config fixture must return a dict of "
                        f"settings, not {type(settings).__name__}", pytrace=False)
        self.item = item
        config = item.config
        marker = marker_settings(item)
        defaults = dict(settings)
        self.marker = marker

        where = {"command line": config.getoption("wiretape_record"),
                 "marker": marker.pop("record", None),
                 "wiretape_config fixture": defaults.pop("record", None),
                 "ini": config.getini("wiretape_record")}
        # A kept recording replayed as the test's cassette (live.replay_command).
        replayed_file = config.getoption("wiretape_cassette", None)
        if replayed_file:
            where["command line"] = "none"
        record = _first_given(*where.values()) or "none"
        if record not in RECORD_MODES:
            source = next(k for k, v in where.items() if v not in (None, ""))
            pytest.fail(
                f"{item.nodeid}: wiretape record mode {record!r} (from the {source}) "
                f"is not one of {', '.join(RECORD_MODES)}", pytrace=False)
        self.record_mode = RECORD_MODE_ALIASES.get(record, record)
        # Hardware in the loop: the real device, nothing recorded or replayed.
        self.live = bool(config.getoption("wiretape_live")) or _ini_flag(config, "wiretape_live")
        # Drift: live, and the recording compared with the cassette (live.py).
        self.drift = bool(config.getoption("wiretape_drift", False)) and not replayed_file
        self.live = (self.live or self.drift) and not replayed_file
        self.live_recording = None  # a live.LiveRecording once record_live() is called
        self.drift_found = None  # the drift report, when the device answered otherwise
        self.device = _first_given(config.getoption("wiretape_device"),
                                   marker.pop("device", None),
                                   defaults.pop("device", None),
                                   config.getini("wiretape_device"))

        # The paths wiretape_serial serves (serial_patch); not a replay key.
        self.serial_port = _first_given(marker.pop("serial_port", None),
                                        defaults.pop("serial_port", None))
        # Several ports, one cassette (DESIGN §19): channel name -> device.
        self.ports = _checked_ports(_first_given(marker.pop("ports", None),
                                                 defaults.pop("ports", None)), item.nodeid)

        cassette = _first_given(marker.pop("cassette", None), defaults.pop("cassette", None))
        if replayed_file:
            self.path = Path(replayed_file).absolute()
        elif cassette is None:
            self.path = Path(cassette_dir) / cassette_file_name(item)
        else:
            self.path = Path(os.fspath(cassette))
            if not self.path.is_absolute():
                self.path = source_file_of(item).parent / self.path
        # What is left of both are replay keys; the marker's win.
        self.replay_keys = {**DEFAULT_REPLAY_KEYS, **defaults, **marker}
        # Python callables of a profile become a registered profile's name.
        callables = {key: self.replay_keys.pop(key) for key in ("match_key", "fix_response")
                     if key in self.replay_keys}
        if callables:
            from ..profiles import callable_profile
            base = self.replay_keys.get("profile")
            if base is None:
                pytest.fail(f"{item.nodeid}: wiretape {' and '.join(callables)} need "
                            "profile= (the profile whose framing they go with)", pytrace=False)
            self.replay_keys["profile"] = callable_profile(str(base), **callables)

        cassette_exists = self.path.exists()
        self.recording = not self.live and (
            self.record_mode == "rewrite"
            or (self.record_mode in ("once", "new_episodes") and not cassette_exists))
        # new_episodes on a cassette of several ports: the episode is a port
        # (episodes.py); the ports the cassette lacks are recorded, the others
        # replayed. On a cassette of one port it is `once`.
        self.appending = (not self.live and self.record_mode == "new_episodes"
                          and self.ports is not None and cassette_exists)
        self.channels_to_record: List[str] = []  # appending: the ports recorded
        self.appended: List[str] = []  # the channels appended when the test passed
        self._replay_start_ns = None  # appending: monotonic ns of the replay's first open
        self._recorder_start_ns = None  # appending: monotonic ns of the Recorder's time 0
        self.partial_path = self.path.with_name(f"{self.path.name}.recording-{os.getpid()}")
        self.device_from_driver = False
        self.opened_device = None  # what open_port(device) was given
        self._ports: List[wiretape.Port] = []
        self._cleanups: List[Callable[[], None]] = []
        self._recorder = None  # wiretape.Recorder of a cassette of several ports
        # What the closed replays left of the cassette (Port.left_unused), for
        # the summary: unused=ignore, the default, says nothing else.
        self.left_unused: List[str] = []

    # -- what fixtures use ---------------------------------------------------
    @property
    def options(self) -> str:
        """The option string that opens the device (recording) or the replay."""
        return self.options_for(self.opened_device or self.device)

    @property
    def mode(self) -> str:
        """What the test does with its cassette: live, recording or replay."""
        if self.appending:
            return "replay, recording the ports the cassette lacks"
        return "live" if self.live else "recording" if self.recording else "replay"

    def options_for(self, device: Any) -> str:
        """`options`, recording from `device` (an option string or a path)."""
        if self.live:
            if not device:
                return "(none yet: the device is the path the driver opens)"
            if self.live_recording is None:
                return device_options(device)
            return join_options(device_options(device),
                                option_string([("log", self.live_recording.scratch),
                                               ("meta_pytest_node", self.item.nodeid)]))
        if self.recording:
            if not device:
                return "(none yet: the device is the path the driver opens)"
            return join_options(device_options(device),
                                option_string([("log", self.partial_path),
                                               ("meta_pytest_node", self.item.nodeid)]))
        return join_options(option_string([("type", "replay"), ("file", self.path)]),
                            self.replay_options)

    @property
    def replay_options(self) -> str:
        """The replay keys alone (``timing=none,...``)."""
        return option_string([(key, _option_value(value))
                              for key, value in self.replay_keys.items()])

    @property
    def url(self) -> str:
        if self.live:
            return _live_url(device_options(self.device), self.item.nodeid)
        if self.recording:
            query = urllib.parse.urlencode({"options": device_options(self.device)})
            return f"wiretape+record://{urllib.parse.quote(str(self.partial_path))}?{query}"
        query = urllib.parse.urlencode(_core.parse_options(self.replay_options))
        return f"wiretape://{urllib.parse.quote(str(self.path))}?{query}"

    def record_command(self) -> str:
        """The shell command that records the cassette: the device setting,
        else the device the cassette's header says it was recorded from,
        else OPTS."""
        test = shlex.quote(self.item.nodeid)
        device = self.device or self._recorded_device()
        if (self.device_from_driver or self.ports is not None) and not device:
            # wiretape_serial records from the path the driver opens.
            return f"pytest --wiretape-record=once {test}"
        device = shlex.quote(device) if device else "OPTS"
        return f"pytest --wiretape-record=once --wiretape-device={device} {test}"

    def _recorded_device(self) -> str:
        """The device the cassette's header names (``_core.recorded_device``);
        '' for a missing or unreadable cassette, or one of several ports
        (their devices are the marker's ``ports=``)."""
        try:
            header = wiretape.SessionReader(str(self.path)).header
        except (OSError, wiretape.SessionError):
            return ""
        if header.channels:
            return ""
        return _core.recorded_device(header.port_options)

    def channel_options(self, name: str) -> str:
        """The option string that replays channel `name` of the cassette."""
        return join_options(option_string([("type", "replay"), ("file", self.path),
                                           ("channel", name)]), self.replay_options)

    def open_ports(self) -> Dict[str, wiretape.Port]:
        """The ports of the marker's ``ports=`` by name: each device
        recording into its channel of the one cassette (one clock), or each
        channel's replay (one clock from the first open), or live."""
        __tracebackhide__ = True  # wiretape's frames, not the test's
        if self.ports is None:
            pytest.fail(f"{self.item.nodeid}: wiretape_ports needs the marker's ports= "
                        "(@pytest.mark.wiretape(ports={'gps': 'OPTS', ...}))", pytrace=False)
        if self.appending:
            return self._open_ports_appending()
        opened: Dict[str, wiretape.Port] = {}
        try:
            if self.recording and self._recorder is None:
                self._recorder = self._new_recorder()
            if not self.recording and not self.live:
                self._check_channels()
            for name, device in self.ports.items():
                if self.live:
                    port = wiretape.open_port(device)
                elif self.recording:
                    port = self._recorder.open_port(
                        join_options(option_string([("name", name)]), device))
                else:
                    port = wiretape.open_port(self.channel_options(name))
                opened[name] = port
                self._ports.append(port)
        except wiretape.OptionError as error:
            source = "the marker's ports=" if self.recording or self.live else \
                "the marker's replay keys"
            pytest.fail(f"{self.item.nodeid}: bad wiretape options (check {source}): {error}",
                        pytrace=False)
        return opened

    def _new_recorder(self) -> wiretape.Recorder:
        header = wiretape.SessionHeader.starting_now()
        header.metadata = {"pytest_node": self.item.nodeid}
        return wiretape.Recorder(str(self.partial_path), header)

    def _open_ports_appending(self) -> Dict[str, wiretape.Port]:
        """new_episodes: the channels the cassette holds replayed, then the
        other ports recorded by a Recorder of their own. The replays open
        first, so that the replay's clock (time 0: its first open) starts
        before the Recorder's and the recorded times move forward onto it;
        both starts are read on the monotonic clock here (to the
        microseconds an open takes)."""
        opened: Dict[str, wiretape.Port] = {}
        replayed = [name for name in self.ports if name not in self.channels_to_record]
        try:
            for name in replayed:
                if self._replay_start_ns is None:
                    self._replay_start_ns = time.monotonic_ns()
                opened[name] = wiretape.open_port(self.channel_options(name))
                self._ports.append(opened[name])
        except wiretape.OptionError as error:
            pytest.fail(f"{self.item.nodeid}: bad wiretape options (check the marker's "
                        f"replay keys): {error}", pytrace=False)
        try:
            for name in self.channels_to_record:
                if self._recorder is None:
                    self._recorder = self._new_recorder()
                port = self._recorder.open_port(
                    join_options(option_string([("name", name)]), self.ports[name]))
                if self._recorder_start_ns is None:
                    self._recorder_start_ns = time.monotonic_ns() - self._recorder.now_ns()
                opened[name] = port
                self._ports.append(port)
        except wiretape.OptionError as error:
            pytest.fail(f"{self.item.nodeid}: bad wiretape options (check the marker's "
                        f"ports=): {error}", pytrace=False)
        # The test sees its ports in the marker's order.
        return {name: opened[name] for name in self.ports}

    def _check_channels(self) -> None:
        """The cassette holds a channel of each name the marker gives."""
        header = wiretape.SessionReader(str(self.path)).header
        known = [channel.name for channel in header.channel_list() if channel.name]
        missing = [name for name in self.ports if header.find_channel(name) is None]
        if self.appending:
            if not header.channels:
                pytest.fail(f"{self.item.nodeid}: cassette {self.path} is a session of one "
                            "port: --wiretape-record=new_episodes appends the ports it lacks "
                            "to a cassette of several ports (named channels) only; record "
                            f"it again: {self.record_command().replace('=once', '=rewrite')}",
                            pytrace=False)
            self.channels_to_record = missing
            return
        if missing:
            pytest.fail(f"{self.item.nodeid}: cassette {self.path} has no channel "
                        + ", ".join(repr(name) for name in missing) + " (its channels: "
                        + (", ".join(known) or "one unnamed: a cassette of one port") + "); "
                        f"record it again: {self.record_command().replace('=once', '=rewrite')}",
                        pytrace=False)

    def prepare(self, device_from_driver: bool = False) -> None:
        """Checks that the test can run: a cassette to replay, or a device to
        record from (`device_from_driver`: the driver names it when it opens
        it, as wiretape_serial's do); makes the cassette's directory when
        recording."""
        self.device_from_driver = device_from_driver
        if self.appending:
            self._check_channels()
            if self.partial_path.exists():
                self.partial_path.unlink()
            return
        if self.ports is not None and (self.live or self.recording):
            # each port names its own device
            if self.recording:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                if self.partial_path.exists():
                    self.partial_path.unlink()
            return
        if self.live:
            flag = "--wiretape-drift" if self.drift else "--wiretape-live"
            if not self.device and not device_from_driver:
                pytest.fail(
                    f"wiretape: {self.item.nodeid} runs live ({flag}) but no device "
                    "is given: pass --wiretape-device=OPTS, the marker's device=, or set "
                    "wiretape_device in the ini file", pytrace=False)
            if self.drift and not self.path.exists():
                pytest.fail(
                    f"wiretape: {self.item.nodeid}: --wiretape-drift compares with the "
                    f"cassette {self.path}, which does not exist.\nRecord it from the "
                    f"device with:\n    {self.record_command()}", pytrace=False)
            return
        if self.recording:
            if not self.device and not device_from_driver:
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

    def open_port(self, device: Any = None) -> wiretape.Port:
        """Opens the replay, or the device recording to the cassette: `device`,
        or else the device setting."""
        __tracebackhide__ = True  # wiretape's frames, not the test's
        if device:
            self.opened_device = device
        options = self.options
        try:
            port = wiretape.open_port(options)
        except wiretape.OptionError as error:
            source = "the device setting" if self.recording else "the marker's replay keys"
            pytest.fail(f"{self.item.nodeid}: bad wiretape options (check {source}): "
                        f"{error}\n    options: {options}", pytrace=False)
        self._ports.append(port)
        return port

    def add_cleanup(self, cleanup: Callable[[], None]) -> None:
        self._cleanups.append(cleanup)

    def close_ports(self) -> None:
        """Closes what the plugin opened; raises what closing raises (a replay
        with unused=error reports unused data here)."""
        __tracebackhide__ = True  # wiretape's frames, not the test's
        errors = []
        while self._cleanups:
            try:
                self._cleanups.pop()()
            except Exception as error:  # keep closing the rest
                errors.append(error)
        while self._ports:
            port = self._ports.pop()
            try:
                if port.is_open:
                    port.close()
            except Exception as error:
                errors.append(error)
            if port.left_unused:
                self.left_unused.append(port.left_unused)
        recorder, self._recorder = self._recorder, None
        close = getattr(recorder, "close", None)
        if close is not None:
            try:
                close()
            except Exception as error:
                errors.append(error)
        if errors:
            raise errors[0]

    def close_ports_quietly(self) -> None:
        try:
            self.close_ports()
        except Exception:
            pass

    def finish(self, passed: bool) -> None:
        """Keeps a recording made by a passing test; otherwise throws it away
        and leaves any previous cassette as it was."""
        self.close_ports_quietly()
        if self.live_recording is not None:
            self.live_recording.finish(keep=not passed or self.drift_found is not None)
            return
        if self.appending:
            self._finish_appending(passed)
            return
        if not self.recording:
            return
        if not passed:
            if self.partial_path.exists():
                self.partial_path.unlink()
            return
        if not self.partial_path.exists():
            warnings.warn(WiretapeWarning(
                f"{self.item.nodeid} passed while recording but opened no port from "
                f"{'wiretape_serial' if self.device_from_driver else 'wiretape_options'}: "
                f"nothing was written to {self.path}"))
            return
        publish_recording(self.partial_path, self.path)

    def _finish_appending(self, passed: bool) -> None:
        """Appends the ports recorded to the cassette when the test passed
        (episodes.append_channels); a failing test appends nothing."""
        if not self.partial_path.exists():
            return
        try:
            if passed and self._recorder_start_ns is not None:
                # No replay opened (every channel recorded): the Recorder's clock.
                replay_start_ns = (self._recorder_start_ns if self._replay_start_ns is None
                                   else self._replay_start_ns)
                offset_ns = self._recorder_start_ns - replay_start_ns
                when = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
                names = ", ".join(self.channels_to_record)
                note = (f"appended channel{'s' if len(self.channels_to_record) > 1 else ''} "
                        f"{names} at {when} (pytest --wiretape-record=new_episodes, "
                        f"{self.item.nodeid}; their times moved by {offset_ns} ns onto the "
                        "replay's clock, to the microseconds of an open)")
                self.appended = append_channels(self.path, self.partial_path, offset_ns, note)
        finally:
            if self.partial_path.exists():
                self.partial_path.unlink()

    def describe(self) -> str:
        if self.live:
            return self._describe_live()
        lines = [f"cassette: {self.path}",
                 f"mode: {self.mode} (--wiretape-record={self.record_mode})"]
        if self.ports is None:
            lines.append(f"options: {self.options}")
        else:
            recorded = set(self.channels_to_record) if not self.recording else set(self.ports)
            lines += [f"port {name}: "
                      + (device if name in recorded else self.channel_options(name))
                      for name, device in self.ports.items()]
        if self.appending:
            replayed = [name for name in self.ports if name not in self.channels_to_record]
            if replayed:
                lines.append("new_episodes replays the channels the cassette holds ("
                             + ", ".join(replayed) + "): a mismatch there fails the test "
                             "and is never re-recorded")
        if not self.recording:
            lines.append(f"to record it again: {self.record_command().replace('=once', '=rewrite')}")
        return "\n".join(lines)

    def _describe_live(self) -> str:
        flag = "--wiretape-drift" if self.drift else "--wiretape-live"
        recording = self.live_recording
        if recording is None or not (recording.scratch.exists() or recording.was_kept):
            return f"live ({flag}): nothing recorded\noptions: {self.options}"
        from .live import replay_command

        kept = self.live_recording.kept
        lines = [f"live ({flag}): recorded, kept as {kept} (the test failed)",
                 f"options: {self.options}",
                 f"replay it: {replay_command(self.item.nodeid, kept)}"]
        if self.drift_found:
            lines.append(self.drift_found)
        return "\n".join(lines)
