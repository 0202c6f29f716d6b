"""What the pytest plugin keeps of a test run on the real device (DESIGN §28).

Under ``--wiretape-live`` and ``--wiretape-drift`` a test talks to the real
device and its session is recorded to a scratch file in pytest's temporary
directory, never next to the cassettes:

- a test that fails keeps it: moved to ``DIR/<module>/<test>.wtape``
  (``DIR`` is ``--wiretape-failures=DIR``, else ``wiretape-failures`` next
  to the ``--junitxml`` report, else in the rootdir), and the report gives
  the one command that replays it:
  ``pytest 'NODE' --wiretape-cassette=DIR/<module>/<test>.wtape``;
- a test that passes throws it away;
- under ``--wiretape-drift`` the recording is then compared with the test's
  cassette by exchange (tools/diff.py, through the profile of the marker's
  replay keys or the cassette's ``profile`` metadata: a field the profile
  leaves out never drifts); a drift fails the test with the report, and the
  recording is kept as a failing test's.
"""

from __future__ import annotations

import os
import shlex
import shutil
from pathlib import Path
from typing import Any, Mapping, Optional

import pytest

#: The replay keys that declare a profile of one's own (docs/replay.md).
_DECLARED_PROFILE_KEYS = ("framing", "ignore", "echo", "checksum")
#: Divergences a drift report shows one by one (all are counted).
DIVERGENCES_SHOWN = 10


def failures_dir(config: pytest.Config) -> Path:
    """Where failing live tests' recordings are kept."""
    given = config.getoption("wiretape_failures", None) or config.getini("wiretape_failures")
    if given:
        return Path(given).absolute()
    junit = getattr(config.option, "xmlpath", None)
    if junit:
        return Path(junit).absolute().parent / "wiretape-failures"
    return Path(config.rootpath) / "wiretape-failures"


def replay_command(nodeid: str, recording: Path) -> str:
    """The one command that replays a kept recording as the test's cassette."""
    return (f"pytest {shlex.quote(nodeid)} "
            f"--wiretape-cassette={shlex.quote(str(recording))}")


def profile_spec(replay_keys: Mapping[str, Any], cassette: Path) -> Optional[str]:
    """The profile a drift check compares through: the marker's ``profile=``
    or declared profile keys, else the cassette's ``profile`` metadata
    (wiretape.session.chosen_profile); None for none."""
    from .. import _core
    from ..session import NO_PROFILE, chosen_profile, open_session

    declared = [(key, replay_keys[key]) for key in _DECLARED_PROFILE_KEYS if key in replay_keys]
    if declared:
        given: Optional[str] = _core.option_string([(k, str(v)) for k, v in declared])
    elif replay_keys.get("profile") is not None:
        given = str(replay_keys["profile"])
    else:
        given = None
    headers = []
    if given is None:
        with open_session(str(cassette)) as reader:
            headers.append(reader.header)
    spec = chosen_profile(given, *headers).spec
    return None if spec in (None, NO_PROFILE) else spec


def drift_report(cassette: Path, recording: Path, profile: Optional[str]) -> Optional[str]:
    """None when the device answered as the cassette recorded (through the
    profile's masks), else the report of where it answers differently."""
    from ..tools.diff import diff

    result = diff(str(cassette), str(recording), profile=profile,
                  max_divergences=DIVERGENCES_SHOWN)
    if result.identical and not result.damaged:
        return None
    through = f" through profile {profile}" if profile else ""
    lines = [f"wiretape drift: the device now answers differently from {cassette}{through}"]
    for line in result.report().splitlines():
        if line in ("sessions differ", "sessions are identical"):
            continue
        if line.startswith("A: "):
            line = "A (cassette): " + line[3:]
        elif line.startswith("B: "):
            line = "B (device now): " + line[3:]
        lines.append(line)
    return "\n".join(lines)


class LiveRecording:
    """The scratch recording of one live test, and where it is kept if the
    test fails."""

    def __init__(self, scratch: Path, kept: Path):
        self.scratch = scratch
        self.kept = kept
        self.was_kept = False

    def finish(self, keep: bool) -> None:
        """Keeps the recording (a failing test) or throws it away."""
        if not self.scratch.exists():
            return
        if not keep:
            self.scratch.unlink()
            return
        self.kept.parent.mkdir(parents=True, exist_ok=True)
        partial = self.kept.with_name(f"{self.kept.name}.keeping-{os.getpid()}")
        shutil.move(str(self.scratch), partial)
        os.replace(partial, self.kept)
        self.was_kept = True
