"""wiretape.tools.edit_scrub: what --redact scrubs besides rx and tx: the
header (host cleared, by-id serial numbers, the patterns over its text) and
every string of every event."""

import json

from wiretape import _core
from wiretape.tools.edit_scrub import scrub_header, scrubbed_event
from wiretape.tools.edit_specs import parse_redaction


def test_the_header_loses_its_host_and_by_id_serials_and_matches():
    header = _core.SessionHeader(port_type="serial", host="alices-laptop",
                                 port_options="type=serial,device=/dev/serial/by-id/"
                                              "usb-FTDI_FT232R_A12345-if00-port0",
                                 metadata={"site": "alice's lab"})
    scrub_header(header, [parse_redaction("alice")])
    assert header.host == ""
    assert header.port_options == "type=serial,device=/dev/serial/by-id/redacted"
    assert header.metadata == {"site": "*****'s lab"}


def test_an_events_strings_are_scrubbed_and_its_payload_made_anew():
    payload = _core.event_payload("client_connect", {"peer": "10.0.0.7:4711", "role": "control"})
    scrubbed = scrubbed_event("client_connect", payload, [parse_redaction(r"10\.0\.0\.7")])
    assert json.loads(scrubbed)["peer"] == "********:4711"
    assert _core.record_content_problem("client_connect", 0, scrubbed) is None


def test_an_event_without_a_match_is_left_as_it_was():
    payload = _core.event_payload("client_connect", {"peer": "10.0.0.7:4711", "role": "control"})
    assert scrubbed_event("client_connect", payload, [parse_redaction("nobody")]) is payload
