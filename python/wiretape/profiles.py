"""Protocol profiles with Python callables (DESIGN §13).

``callable_profile(base, match_key=..., fix_response=...)`` registers a
profile that frames and names as the profile ``base`` does (a built-in such
as ``"modbus-tcp"`` or ``"lines"``) and matches requests by
``match_key(request: bytes) -> bytes`` and fixes served responses with
``fix_response(recorded_request, actual_request, response) -> bytes``; it
returns the name to give as ``profile=``::

    name = wiretape.profiles.callable_profile("lines", match_key=lambda r: r.upper())
    port = wiretape.open_port(f"type=replay,file=run.wtape,match=request,profile={name}")

The pytest marker takes the same callables: ``@pytest.mark.wiretape(
match="request", profile="lines", match_key=fn)``.
"""

from __future__ import annotations

import itertools
from typing import Callable, Optional

from . import _core

MatchKey = Callable[[bytes], bytes]
FixResponse = Callable[[bytes, bytes, bytes], bytes]

_numbers = itertools.count(1)


def callable_profile(base: str, match_key: Optional[MatchKey] = None,
                     fix_response: Optional[FixResponse] = None) -> str:
    """Registers a profile of ``base``'s framing with these callables; returns
    its name (``base+python-N``) for ``profile=``. Raises OptionError for an
    unknown ``base``, TypeError for a callable that is not one."""
    if match_key is None and fix_response is None:
        return base
    name = f"{base}+python-{next(_numbers)}"
    _core.register_callable_profile(name, base, match_key, fix_response)
    return name


__all__ = ["callable_profile"]
