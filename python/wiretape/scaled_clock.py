"""A command on a clock K times faster than real time (``--speed K`` of
``wiretape replay ... -- CMD`` and ``wiretape faults``; DESIGN §22).

CMD runs with the preload shim ``_scaled_clock.so`` (src/shim/scaled_clock.c):
its clock reads, sleeps and timed waits run K times faster, from one anchor
that this module takes and passes in the environment, so CMD and every
process it starts share one scaled clock. K = 1 loads nothing.
"""

from __future__ import annotations

import os
import time
from typing import Dict, List, Mapping, Optional

from . import _core

SHIM_NAME = "_scaled_clock.so"
# The variables the shim reads (src/shim/scaled_clock.c).
ENV_SPEED = "WIRETAPE_CLOCK_SPEED"
ENV_ANCHOR = "WIRETAPE_CLOCK_ANCHOR"

# The clocks the shim scales, in the order of its anchor.
_ANCHOR_CLOCKS = (time.CLOCK_REALTIME, time.CLOCK_MONOTONIC, time.CLOCK_MONOTONIC_RAW,
                  time.CLOCK_BOOTTIME)


def shim_path() -> str:
    """The preload shim, installed next to the extension."""
    path = os.path.join(os.path.dirname(os.path.abspath(_core.__file__)), SHIM_NAME)
    if not os.path.isfile(path):
        raise RuntimeError(f"{path}: the scaled-clock shim is missing "
                           "(it is built on Linux only; rebuild with make)")
    return path


def check_speed(speed: float, flag: str = "--speed") -> float:
    """`speed` as a float, or ValueError naming `flag`: checked as the
    replay key ``speed`` is, by the key table in C++ (a number from 1e-06 to
    1e+06), so that CMD's clock and the replay's run at the same K."""
    try:
        value = _core.option_value("replay", "speed", str(speed))
    except _core.OptionError as error:
        raise ValueError(f"{flag} {speed!r}: {error} (10: ten times faster)") from None
    return float(value)  # type: ignore[arg-type]


def anchor() -> str:
    """The shim's anchor: now, on every clock it scales (nanoseconds)."""
    return ",".join(str(time.clock_gettime_ns(clock)) for clock in _ANCHOR_CLOCKS)


def _number_text(value: float) -> str:
    return repr(float(value))


def environment(speed: float, base: Optional[Mapping[str, str]] = None) -> Dict[str, str]:
    """The environment of a command run at `speed` (a copy of `base`, by
    default os.environ): the shim in LD_PRELOAD before any preload already
    there (the device-redirecting shim, a sanitizer's), K and the anchor.
    At K = 1, `base` unchanged: nothing is loaded. An anchor already in
    `base` is kept: a command started by a scaled command shares its clock."""
    env = dict(os.environ if base is None else base)
    speed = check_speed(speed)
    if speed == 1.0:
        return env
    shim = shim_path()
    preloads: List[str] = [item for item in env.get("LD_PRELOAD", "").replace(":", " ").split()
                           if item != shim]
    env["LD_PRELOAD"] = " ".join([shim] + preloads)
    if not env.get(ENV_ANCHOR) or env.get(ENV_SPEED) != _number_text(speed):
        env[ENV_ANCHOR] = anchor()
    env[ENV_SPEED] = _number_text(speed)
    return env


def real_seconds(seconds: float, speed: float) -> float:
    """How long `seconds` on a clock at `speed` take in real time."""
    return seconds / speed
