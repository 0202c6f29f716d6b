"""What ``wiretape edit --redact`` scrubs besides the rx and tx bytes
(DESIGN §23): the header's host, the device identity's serial number, the
serial numbers of ``/dev/serial/by-id`` paths, and the patterns over the
header's text and every string of every event."""

from __future__ import annotations

import re
from typing import Optional, Sequence

from .. import _core
from ..session import event_payload
from .edit_specs import Redaction

__all__ = ["scrub_header", "scrubbed_event"]

#: A by-id link names the adapter's serial number: what identifies a user.
_BY_ID = re.compile(r"(/dev/serial/by-(?:id|path)/)[^,\s\"]+")
_BY_ID_REPLACEMENT = r"\1redacted"


def _scrub_text(text: str, redactions: Sequence[Redaction]) -> str:
    return _apply_patterns(_BY_ID.sub(_BY_ID_REPLACEMENT, text), redactions)


def _apply_patterns(text: str, redactions: Sequence[Redaction]) -> str:
    data = text.encode("utf-8", "surrogatepass")
    for redaction in redactions:
        data = redaction.pattern.sub(lambda m: redaction.scrub(len(m.group(0))), data)
    return data.decode("utf-8", "replace")


def _scrub_value(value, redactions: Sequence[Redaction]):
    """Every string in a JSON value scrubbed (lists and objects walked)."""
    if isinstance(value, str):
        return _scrub_text(value, redactions)
    if isinstance(value, list):
        return [_scrub_value(item, redactions) for item in value]
    if isinstance(value, dict):
        return {key: _scrub_value(item, redactions) for key, item in value.items()}
    return value


def scrub_header(header, redactions: Sequence[Redaction],
                  chosen: Optional[frozenset] = None) -> None:
    """Every header field that can name the device, the machine or a user:
    the host is cleared, and so is the device identity's serial number
    with its part of the by-id name (DESIGN §20); the port options, the
    device's address, metadata values, the rest of the device identity and
    where an import came from are scrubbed."""
    header.host = ""
    if chosen is None or 0 in chosen:
        _scrub_port(header, redactions)
    if header.channels:
        # A session of several ports: each chosen channel's port members
        # (the top-level ones are channel 0's, written from it).
        channels = list(header.channels)
        for channel in channels:
            if chosen is None or channel.id in chosen:
                _scrub_port(channel, redactions)
        header.channels = channels
    header.metadata = {key: _scrub_text(value, redactions)
                       for key, value in header.metadata.items()}
    header.source_files = [_scrub_text(name, redactions) for name in header.source_files]
    header.source_details = {key: _scrub_text(value, redactions)
                             for key, value in header.source_details.items()}


def _scrub_port(port, redactions: Sequence[Redaction]) -> None:
    """A header's (or a channel's) port members: the identity's serial
    number cleared by the session model's rule, the rest scrubbed."""
    if isinstance(port, _core.SessionHeader):
        port.clear_device_serial()
        identity = port.device_identity
    elif port.device_identity is not None:
        # The rule of clearing the serial number lives in SessionHeader.
        holder = _core.SessionHeader()
        holder.device_identity = port.device_identity
        holder.clear_device_serial()
        identity = holder.device_identity
    else:
        identity = None
    if identity is not None:
        # The by-id name keeps what is not the serial number (vendor, model,
        # interface), so that replay still presents it: only the patterns apply.
        port.device_identity = {key: _apply_patterns(value, redactions)
                                for key, value in dict(identity).items()}
    port.port_options = _scrub_text(port.port_options, redactions)
    port.device_address = _scrub_text(port.device_address, redactions)


def scrubbed_event(kind: str, data: bytes, redactions: Sequence[Redaction]) -> bytes:
    """An event's payload with every string in it scrubbed: the open's
    description, a client's peer address, a device_lost's error... (by-id
    serial numbers and the patterns), made anew by the record-kind table (a
    member it does not know is a ValueError naming it). A payload that is
    not JSON has the patterns applied to its bytes."""
    payload = event_payload(data)
    if payload is None:
        for redaction in redactions:
            data = redaction.pattern.sub(lambda m: redaction.scrub(len(m.group(0))), data)
        return data
    if not payload:
        return data
    changed = _scrub_value(payload, redactions)
    if changed == payload:
        return data
    return _core.event_payload(kind, changed)

