"""Fuzzing a Python driver in process from its recording (DESIGN §27,
docs/fuzzing.md "In process").

A recording is read once; each fuzzer input is a *plan*: any bytes, decoded
(in C++, ``_core.FuzzedReplay``) into mutations of what the device sent, with
a profile on its frames and fields, checksums recomputed. Every plan is a
valid replay; an empty plan replays the recording unchanged.

With atheris::

    import atheris, sys
    from wiretape.fuzzing import FuzzedRecording, DRIVER_ERRORS

    recording = FuzzedRecording("recordings/identify.wtape")

    def test_one_input(plan: bytes) -> None:
        with recording.serial(plan):           # serial.Serial opens the mutated replay
            try:
                run_my_driver()
            except (MyDriverError,) + DRIVER_ERRORS:
                pass                           # a driver may refuse a bad answer

    atheris.Setup(sys.argv, test_one_input)
    atheris.Fuzz()

A finding's plan is written with :meth:`FuzzedRecording.write` as a plain
``.wtape`` session (the mutation in its header's ``edits``) that ``wiretape
replay`` plays to the driver with no fuzzer installed.
"""

from __future__ import annotations

import contextlib
import os
from typing import Iterable, Iterator, List, Optional, Union

from serial.serialutil import SerialException

from . import _core

PathLike = Union[str, "os.PathLike[str]"]

# What the replay raises at a driver that met a mutated recording: it asked
# for what the recording does not hold (ReplayMismatch) or read past its end
# (PortClosed); through pyserial a device that went away is a SerialException.
DRIVER_ERRORS = (_core.ReplayMismatch, _core.PortError, SerialException)


class FuzzedRecording:
    """A recording read once, that plans mutate.

    `profile`: a profile name (``wiretape.profiles``) whose frames the plans
    mutate; None: plans act on rx records. `options`: replay keys over the
    fuzzing defaults ``timing=none,at_end=closed,unused=ignore``. Raises
    OptionError for bad options or a profile that does not fit the
    recording, SessionError for a session with no device bytes."""

    def __init__(self, session: PathLike, profile: Optional[str] = None, options: str = ""):
        self.session = os.fspath(session)
        self._replay = _core.FuzzedReplay(self.session, profile or "", options)

    @property
    def units(self) -> int:
        """How many rx frames (with a profile) or rx records a plan's steps index."""
        return self._replay.units

    def open(self, plan: bytes) -> _core.Port:
        """A replay Port of the recording mutated by `plan`."""
        return self._replay.open(bytes(plan))

    def edits(self, plan: bytes) -> List[str]:
        """What `plan` changes, one line a change ("rx frame 1 field len: 0x04 → 0x2c")."""
        return self._replay.edits(bytes(plan))

    def inert(self, plan: bytes) -> bool:
        """Whether `plan` only changes bytes the profile leaves out of
        matching, splits frames across reads or delays them within the
        replay's tolerance: a driver failing on it, even with a clean
        error, has a finding."""
        return self._replay.inert(bytes(plan))

    def write(self, path: PathLike, plan: bytes) -> List[str]:
        """Writes the mutated recording as a .wtape session; returns the edits."""
        return self._replay.write(os.fspath(path), bytes(plan))

    @contextlib.contextmanager
    def serial(self, plan: bytes, paths: Optional[Iterable[str]] = None) -> Iterator[_core.Port]:
        """While in the block, pyserial's ``serial.Serial`` (every name a
        driver bound it to) opens the recording mutated by `plan` instead of
        the device at `paths` (None: any path), as the ``wiretape_serial``
        fixture serves a cassette."""
        from .testing.serial_patch import SerialPatch

        port = self.open(plan)

        def refuse(message: str) -> None:
            raise AssertionError(message)

        patch = SerialPatch(lambda _path, _baud: port, refuse, paths)
        patch.install()
        try:
            yield port
        finally:
            patch.uninstall()
            port.close()
