"""pytest plugin: driver tests that record a device once and replay it in CI.

Registered by the ``pytest11`` entry point ``wiretape``. Every test that uses
one of the fixtures gets a *cassette* (wiretape.testing.cassette), a session
file at ``<test dir>/recordings/<module>/<test>.wtape``, and either records
it from the real device or replays it:

``--wiretape-record=none`` (default)
    replay only; a missing cassette is an error naming its path and the
    command that records it.
``--wiretape-record=once``
    record when the cassette is missing, else replay.
``--wiretape-record=new_episodes``
    for a test with several ports (the marker's ``ports=``), the episode is
    a port: replay the channels the cassette holds, record the ports it
    lacks and append them to it when the test passes (episodes.py). A
    cassette of one port is recorded as under ``once``: inside one port's
    session the device that never saw the replayed part is in another state.
``--wiretape-record=rewrite`` (or ``all``, VCR's name)
    always record anew; a test that fails while recording leaves the previous
    cassette as it was.
``--wiretape-live``
    hardware in the loop: every test talks to the real device
    (``--wiretape-device``, or the path a ``wiretape_serial`` driver opens);
    nothing is replayed, cassettes are neither needed nor touched. Its
    session is recorded to a scratch file: a failing test keeps it under
    ``--wiretape-failures=DIR`` and its report prints the one command that
    replays it (``pytest NODE --wiretape-cassette=FILE``); live.py.
``--wiretape-drift``
    live, and each test's recording is compared with its cassette through
    the profile's masks: a test whose device now answers differently fails
    with where, and keeps its recording as a failing live test does.
``--wiretape-cassette=FILE``
    replay FILE as the cassette of the tests run (a kept recording).

The run ends with a summary: cassettes replayed, recorded, appended to
(new_episodes), not kept (the test failed while recording), run live, and the cassettes in the test
files' recording folders that no collected test names (left by a renamed or
removed test).

Recording needs the device: ``--wiretape-device=OPTS`` (a wiretape option
string; a bare path means ``type=serial,device=PATH``). Both settings can
also come from the marker (``record=``, ``device=``), the ``wiretape_config``
fixture or the ini file (``wiretape_record``, ``wiretape_device``); the
command line beats the marker, which beats ``wiretape_config``, which beats
the ini file.

Marker: ``@pytest.mark.wiretape(cassette=None, device=None, record=None,
serial_port=None, ports=None, **replay_keys)``. ``cassette`` is a path relative to the
test file's directory (or absolute); ``serial_port`` the path (or list of
paths of one device) that ``wiretape_serial`` serves; the replay keys are
those of ``type=replay`` (``timing``, ``match``, ``check``, ``unused``, ...).
Replays default to ``timing=none``. ``ports`` gives a test several ports
and one cassette (a session of several ports, DESIGN §19): a dict of
channel name to device (``{"gps": "/dev/ttyUSB0", "rtk":
"type=tcp,host=caster,port=2101"}``); ``wiretape_ports`` opens them.

Fixtures a conftest overrides to change what the plugin does:
``wiretape_config``       a dict of settings for the test, with the marker's
                          keys: the defaults of the tests it applies to.
``wiretape_cassette_dir`` the directory of the test's cassette (default
                          ``<test dir>/recordings/<module>``).

Fixtures tests use:
``wiretape_port``     the opened ``wiretape.Port``: the device recording to the
                      cassette, or the replay. Closed when the test ends; what
                      closing raises (``unused=error``) fails the test.
``wiretape_ports``    with the marker's ``ports=``: the opened ports by channel
                      name, recording into one cassette on one clock
                      (``wiretape.Recorder``) or replaying its channels
                      (``channel=NAME``, one clock). Closed when the test ends.
``wiretape_options``  the option string that opens that port.
``wiretape_url``      a pyserial URL for it (``wiretape://`` or
                      ``wiretape+record://``).
``wiretape_pty``      the path of a pseudo-terminal serving the replay (or
                      proxying the device while recording), for drivers that
                      open a device path themselves.
``wiretape_udp``      ``HOST:PORT`` of a UDP virtual device serving the replay
                      (or proxying the device while recording): a driver
                      sends its datagrams there and gets the answers back.
``wiretape_serial``   pyserial's ``serial.Serial`` patched for the test, so a
                      driver that builds ``serial.Serial("/dev/ttyUSB0", ...)``
                      itself is served by the cassette (recording: the real
                      device at the path the driver opens, or
                      ``--wiretape-device``). The marker's ``serial_port=``
                      names the path (or paths) served; by default the first
                      path the test opens. Gives the patch (serial_patch).
``wiretape_cassette`` what the plugin decided: ``path``, ``recording``,
                      ``options``...

A cassette is written only when the test passes: recording goes to a
temporary file next to the cassette that replaces it at the end.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Dict, Iterator

import pytest

import wiretape
from wiretape import bridge, urlhandler

from .._core import device_options, option_string, parse_options
from ..options import has_line_settings, join_options
from .cassette import RECORD_MODES, WiretapeCassette, cassette_file_name, default_cassette_dir
from .live import LiveRecording, failures_dir
from .summary import CassetteSummary
from .serial_patch import SerialPatch, fail_test, served_paths

_CASSETTE_KEY = pytest.StashKey[WiretapeCassette]()
_REPORTS_KEY = pytest.StashKey[Dict[str, pytest.TestReport]]()
_SUMMARY_KEY = pytest.StashKey[CassetteSummary]()


def _summary(config) -> CassetteSummary:
    if _SUMMARY_KEY not in config.stash:
        config.stash[_SUMMARY_KEY] = CassetteSummary()
    return config.stash[_SUMMARY_KEY]


# --------------------------------------------------------------------------
# options, ini keys and the marker


def pytest_addoption(parser):
    group = parser.getgroup("wiretape", "wiretape: record and replay device sessions")
    group.addoption(
        "--wiretape-record", dest="wiretape_record", default=None, choices=RECORD_MODES,
        help="none: replay only (default); once: record missing cassettes; "
             "new_episodes: as once, and with several ports (the marker's ports=) record "
             "the ports a cassette lacks and append them to it; "
             "rewrite (or all): record every cassette anew")
    group.addoption(
        "--wiretape-live", dest="wiretape_live", action="store_true", default=False,
        help="hardware in the loop: every test talks to the real device "
             "(--wiretape-device); nothing is replayed or recorded")
    group.addoption(
        "--wiretape-drift", dest="wiretape_drift", action="store_true", default=False,
        help="drift: run live on the real device and fail each test whose device now "
             "answers differently from its cassette (through the profile's masks)")
    group.addoption(
        "--wiretape-cassette", dest="wiretape_cassette", default=None, metavar="FILE",
        help="replay FILE as the cassette of the tests run (the recording a failing "
             "live test kept)")
    group.addoption(
        "--wiretape-failures", dest="wiretape_failures", default=None, metavar="DIR",
        help="where a failing live or drift test keeps its recording (default: "
             "wiretape-failures next to the --junitxml report, else in the rootdir)")
    group.addoption(
        "--wiretape-device", dest="wiretape_device", default=None, metavar="OPTS",
        help="the device to record from: a wiretape option string "
             "(e.g. type=serial,device=/dev/ttyACM0,baud=115200) or a serial device path")
    parser.addini("wiretape_record", "wiretape record mode: none, once, new_episodes, rewrite or all",
                  default="")
    parser.addini("wiretape_live", "true: run against the real device, record nothing",
                  default="")
    parser.addini("wiretape_device", "wiretape device option string to record from", default="")
    parser.addini("wiretape_failures", "where failing live tests keep their recordings",
                  default="")


def pytest_configure(config):
    config.addinivalue_line(
        "markers",
        "wiretape(cassette=None, device=None, record=None, serial_port=None, ports=None, "
        "**replay_keys): the wiretape cassette, device and record mode of a test, the path(s) "
        "wiretape_serial serves, its several ports by channel name (ports={'gps': OPTS}), "
        "and replay keys (timing, match, check, unused...) for its replay")
    urlhandler.register()


def pytest_collection_modifyitems(session, config, items):
    # Before deselection (-k, -m): every test the files hold names its
    # cassette, so a cassette no test names is an orphan, whatever ran.
    summary = _summary(config)
    for item in items:
        summary.note_collected(item)


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    lines = _summary(config).lines()
    if lines:
        terminalreporter.write_sep("-", "wiretape")
        for line in lines:
            terminalreporter.write_line(line)


# --------------------------------------------------------------------------
# hooks: test outcome, port closing inside the test's call


@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_runtest_makereport(item, call):
    report = yield
    item.stash.setdefault(_REPORTS_KEY, {})[report.when] = report
    cassette = item.stash.get(_CASSETTE_KEY, None)
    if cassette is not None and report.failed and report.when in ("setup", "call"):
        report.sections.append(("wiretape", cassette.describe()))
    return report


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item):
    __tracebackhide__ = True  # wiretape's frames, not the test's
    cassette = item.stash.get(_CASSETTE_KEY, None)
    try:
        result = yield
    except BaseException:
        if cassette is not None:
            cassette.close_ports_quietly()
        raise
    if cassette is not None:
        # Closing may raise (unused recorded data under unused=error): that
        # belongs to the test's result, not to its teardown.
        cassette.close_ports()
        if cassette.drift:
            _check_drift(cassette)
    return result


def _check_drift(cassette: WiretapeCassette) -> None:
    """--wiretape-drift: the test's recording against its cassette; a drift
    fails the test with the report (and the command that replays it)."""
    __tracebackhide__ = True  # wiretape's frames, not the test's
    from .live import drift_report, profile_spec, replay_command

    recording = cassette.live_recording
    if recording is None or not recording.scratch.exists():
        pytest.fail(f"{cassette.item.nodeid}: --wiretape-drift: the test opened no wiretape "
                    "port, so nothing was recorded to compare with its cassette", pytrace=False)
    profile = profile_spec(cassette.replay_keys, cassette.path)
    cassette.drift_found = drift_report(cassette.path, recording.scratch, profile)
    if cassette.drift_found is not None:
        pytest.fail(f"{cassette.drift_found}\nthe recording is kept as {recording.kept}; "
                    f"replay it: {replay_command(cassette.item.nodeid, recording.kept)}",
                    pytrace=False)


def _test_passed(item) -> bool:
    reports = item.stash.get(_REPORTS_KEY, {})
    return all(when in reports and reports[when].passed for when in ("setup", "call"))


# --------------------------------------------------------------------------
# fixtures


@pytest.fixture
def wiretape_config() -> Dict[str, Any]:
    """Settings for the test's cassette, with the marker's keys (``record``,
    ``device``, ``cassette`` and replay keys such as ``timing``). Override it
    in a conftest to give a directory's tests their defaults; the marker and
    the command line still win."""
    return {}


@pytest.fixture
def wiretape_cassette_dir(request: pytest.FixtureRequest) -> Path:
    """The directory of the test's cassette: ``<test dir>/recordings/<module>``.
    Override it in a conftest to keep cassettes elsewhere."""
    return default_cassette_dir(request.node)


@pytest.fixture
def wiretape_cassette(request: pytest.FixtureRequest, wiretape_config: Dict[str, Any],
                      wiretape_cassette_dir: Path,
                      tmp_path_factory: pytest.TempPathFactory) -> Iterator[WiretapeCassette]:
    """The cassette of this test: path, recording or replay, option string."""
    cassette = WiretapeCassette(request.node, wiretape_config, Path(wiretape_cassette_dir))
    if cassette.live and cassette.ports is None:
        # live.py: recorded to scratch, kept if the test fails
        name = cassette_file_name(request.node)
        cassette.live_recording = LiveRecording(
            tmp_path_factory.mktemp("wiretape-live") / name,
            failures_dir(request.config) / default_cassette_dir(request.node).name / name)
    # wiretape_serial records from the path the driver opens: no device needed.
    cassette.prepare(device_from_driver="wiretape_serial" in request.fixturenames)
    request.node.stash[_CASSETTE_KEY] = cassette
    yield cassette
    passed = _test_passed(request.node)
    cassette.finish(passed)
    _summary(request.config).note(cassette, passed)


@pytest.fixture
def wiretape_options(wiretape_cassette: WiretapeCassette) -> str:
    """The option string that opens the device (recording) or the replay."""
    return wiretape_cassette.options


@pytest.fixture
def wiretape_port(wiretape_cassette: WiretapeCassette) -> Iterator[wiretape.Port]:
    """The opened port: the device recording to the cassette, or the replay."""
    if wiretape_cassette.ports is not None:
        pytest.fail(f"{wiretape_cassette.item.nodeid}: the marker gives several ports "
                    "(ports=): use the wiretape_ports fixture", pytrace=False)
    port = wiretape_cassette.open_port()
    yield port
    try:
        if port.is_open:
            port.close()
    except Exception:
        pass  # already reported by the call, or the test failed anyway


@pytest.fixture
def wiretape_ports(wiretape_cassette: WiretapeCassette) -> Dict[str, wiretape.Port]:
    """The marker's ``ports=`` opened, by channel name: each device
    recording into its channel of the one cassette, or each channel's
    replay (one clock). Closed when the test ends, as wiretape_port is."""
    return wiretape_cassette.open_ports()


@pytest.fixture
def wiretape_url(wiretape_cassette: WiretapeCassette) -> str:
    """A pyserial URL (``serial.serial_for_url``) for the device or the replay.
    Close the pyserial port before the test ends."""
    return wiretape_cassette.url


@pytest.fixture
def wiretape_serial(wiretape_cassette: WiretapeCassette) -> Iterator[SerialPatch]:
    """pyserial's ``serial.Serial`` (the class, whatever name a driver bound
    it to) served by the cassette for this test: the replay, or, while
    recording, the real device at the path the driver opens (or the device
    setting) recording to the cassette. Undone when the test ends."""
    try:
        import serial  # noqa: F401
    except ImportError:
        pytest.skip("wiretape_serial needs pyserial (pip install pyserial)")
    cassette = wiretape_cassette
    try:
        paths = served_paths(cassette.serial_port)
    except ValueError as error:
        fail_test(f"{cassette.item.nodeid}: wiretape marker: {error}")

    def open_port(path, baud):
        if not cassette.recording and not cassette.live:
            return cassette.open_port()
        device = device_options(cassette.device or path)
        keys = dict(parse_options(device))
        if baud and has_line_settings(keys.get("type", "")) and "baud" not in keys:
            # The rate the driver opens at, not a settings change after open.
            device = join_options(device, option_string([("baud", int(baud))]))
        return cassette.open_port(device)

    patch = SerialPatch(open_port, fail_test, paths)
    patch.install()
    try:
        yield patch
    finally:
        patch.uninstall()


@pytest.fixture
def wiretape_pty(wiretape_cassette: WiretapeCassette, tmp_path_factory) -> str:
    """The path of a pseudo-terminal serving the replay, or, while recording,
    proxying the device; for drivers that open a device path themselves."""
    link = tmp_path_factory.mktemp("wiretape-pty") / "tty"
    handle = _virtual_device(wiretape_cassette, "wiretape_pty", pty=str(link))
    return str(handle.pty_path or link)


@pytest.fixture
def wiretape_udp(wiretape_cassette: WiretapeCassette) -> str:
    """``HOST:PORT`` of a UDP virtual device on the loopback interface serving
    the replay, or, while recording, proxying the device (one datagram one
    record); the driver sends there and gets the answers back."""
    handle = _virtual_device(wiretape_cassette, "wiretape_udp", udp="127.0.0.1:0")
    return str(handle.address)


def _virtual_device(cassette: WiretapeCassette, fixture: str, **client_side):
    """A bridge serving the cassette's replay, or recording its device, on
    `client_side`; stopped, and its verdict checked, when the test ends."""
    if cassette.live and cassette.live_recording is not None:
        handle = bridge.record(device_options(cassette.device),
                               str(cassette.live_recording.scratch), **client_side)
    elif cassette.live:
        handle = bridge.proxy(device_options(cassette.device), **client_side)
    elif cassette.recording:
        handle = bridge.record(device_options(cassette.device), str(cassette.partial_path),
                               **client_side)
    else:
        handle = bridge.serve_replay(str(cassette.path), replay_options=cassette.replay_options,
                                     **client_side)

    def stop():
        __tracebackhide__ = True  # wiretape's frames, not the test's
        handle.stop()
        handle.wait(10)
        result = handle.result()
        if not result.ok:
            raise AssertionError(f"{fixture} ({result.outcome}): {result.message or result}")

    cassette.add_cleanup(stop)
    return handle
