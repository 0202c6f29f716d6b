"""Exports of a session: Wireshark (pcapng), Foxglove (mcap) and JSON Lines.

pcapng and mcap keep every record of the session, in order, stamped with wall-clock time
(the session's start time plus the record's offset since the device opened).

pcapng (open with Wireshark or ``tshark -r``):
  * link type ``LINKTYPE_USER0`` (147): the payload is the bytes as they
    crossed the wire, with no framing added; Wireshark shows them as data
    (hex + ASCII), or decodes them if you map DLT User 0 to a dissector
    (Preferences > Protocols > DLT_USER);
  * except for TCP and UDP sessions: their rx and tx interfaces have link
    type ``LINKTYPE_RAW`` (101), IP packets with the recorded addresses
    and ports (a made-up handshake and sequence numbers for TCP), which
    Wireshark's own dissectors decode (exports.network);
  * three interfaces: 0 ``rx`` (device to host), 1 ``tx`` (host to device)
    and 2 ``events`` (open, close, settings changes...: the payload is the
    event's name, a space and its JSON); filter with ``frame.interface_id``
    or ``frame.interface_name``;
  * each packet also carries the pcapng direction flag (inbound for rx,
    outbound for tx) and, for events, a comment;
  * timestamps in nanoseconds (``if_tsresol`` = 9); the section header's
    comment holds the session header (JSON): a header longer than one
    option holds (64 KiB) is cut at character boundaries into several
    comments, in order, which joined are the JSON (Wireshark lists them
    all); an interface description that long is cut, ending in an ellipsis.

mcap (open with Foxglove):
  * topics ``/wiretape/rx``, ``/wiretape/tx`` and ``/wiretape/events``;
  * message encoding ``json`` with a JSON Schema (schema encoding
    ``jsonschema``), one message per record::

        {"t_ns": 1200, "kind": "rx", "size": 3,
         "data": "AQID",            # base64 (contentEncoding: base64)
         "text": "\\x01\\x02\\x03"}  # the bytes, printable ASCII kept,
                                    # the rest escaped, for reading in
                                    # Foxglove's Raw Messages panel

    events carry their JSON object in ``event`` as well;
  * log and publish time: the record's wall-clock time in nanoseconds;
  * a metadata record ``wiretape`` holds the session header's fields.

A session of several named channels (DESIGN §19: its header lists
``channels``) is laid out by channel rather than by direction:
  * pcapng: one interface per channel, named after it, holding its rx
    (inbound) and tx (outbound) and its events; the link type per channel
    as above (a TCP or UDP channel's interface holds IP packets, so its
    events, not IP, have an interface of their own, ``NAME events``);
  * mcap: one topic per channel, ``/wiretape/NAME`` (channel_topic), with
    one schema, ``wiretape.Record`` (the members of Bytes or of Event, as
    ``kind`` says, and ``channel``, the channel's name).

jsonl (wiretape.exports.jsonl): a header line, then one JSON object per
record (with ``channel``, its channel's name, in a session of named
channels); ``wiretape convert`` writes and reads it.
"""

from ..session import escape_bytes
from .mcap import MCAP_TOPICS, channel_topic, write_mcap
from .pcapng import LINKTYPE_RAW, LINKTYPE_USER0, write_pcapng

__all__ = ["write_pcapng", "write_mcap", "LINKTYPE_USER0", "LINKTYPE_RAW", "MCAP_TOPICS",
           "channel_topic", "escape_bytes"]
