"""``wiretape verify``: checks every record of a session (length and CRC)."""

from __future__ import annotations

import dataclasses
import os
from typing import Any, Dict, Optional

from .. import _core
from ..session import SessionPath, open_session

__all__ = ["verify", "VerifyResult"]


@dataclasses.dataclass(frozen=True)
class VerifyResult:
    """The outcome of verify(); ``to_json()`` is what ``verify --json`` prints."""

    ok: bool
    path: str
    records: int  # the good records before the damage (all of them when ok)
    offset: Optional[int]  # where reading stopped (None when ok)
    message: Optional[str]  # why (None when ok)

    def to_json(self) -> Dict[str, Any]:
        return dataclasses.asdict(self)


def verify(path: SessionPath) -> VerifyResult:
    """Checks every record's CRC and length. Never raises for a bad file: the
    result says where and why reading stopped."""
    name = os.fspath(path)
    try:
        reader = open_session(path)
    except _core.SessionError as error:
        return VerifyResult(ok=False, path=name, records=0, offset=error.offset,
                            message=str(error))
    records = sum(1 for _ in reader)
    damage = reader.damage
    if damage is not None:
        return VerifyResult(ok=False, path=name, records=records, offset=damage.offset,
                            message=damage.message)
    return VerifyResult(ok=True, path=name, records=records, offset=None, message=None)
