"""wiretape.tools.edit_redact: the redactor scrubs each direction's byte
stream (a match may span records) and hands records on in order once their
bytes are settled; the resealer recomputes the checksums of the frames
holding scrubbed bytes."""

from wiretape import _core
from wiretape.tools.edit_redact import Entry, Redactor, Resealer, merged_marks
from wiretape.tools.edit_specs import parse_redaction


def run(redactor, entries):
    for entry in entries:
        redactor.add(entry)
    redactor.finish()


def test_a_match_across_records_is_scrubbed_in_both_and_marked():
    out = []
    redactor = Redactor([parse_redaction("secret")], out.append)
    run(redactor, [Entry("tx", 1, b"pw=sec"), Entry("rx", 2, b"ok"), Entry("tx", 3, b"ret;")])
    assert [(e.kind, bytes(e.data), e.marks) for e in out] == [
        ("tx", b"pw=***", [(3, 3)]), ("rx", b"ok", []), ("tx", b"***;", [(0, 3)])]
    assert redactor.matches == 1


def test_channels_and_directions_are_searched_apart():
    out = []
    redactor = Redactor([parse_redaction("ab")], out.append)
    run(redactor, [Entry("tx", 1, b"a", channel=0), Entry("tx", 2, b"b", channel=1),
                   Entry("rx", 3, b"b", channel=0)])
    assert [bytes(e.data) for e in out] == [b"a", b"b", b"b"]
    assert redactor.matches == 0


def test_records_not_redacted_pass_in_order():
    out = []
    redactor = Redactor([parse_redaction("x")], out.append)
    redactor.add(Entry("tx", 1, b"x"))
    redactor.add(Entry("tx", 2, b"x"), redact=False)
    redactor.add(Entry("open", 0, b"{}"))
    redactor.finish()
    assert [(e.t_ns, bytes(e.data)) for e in out] == [(1, b"*"), (2, b"x"), (0, b"{}")]


def _nmea(body: bytes) -> bytes:
    checksum = 0
    for byte in body:
        checksum ^= byte
    return b"$" + body + b"*%02X\r\n" % checksum


def test_the_resealer_recomputes_a_scrubbed_frames_checksum_across_records():
    out = []
    resealer = Resealer(_core.profile_from_spec("nmea"), out.append)
    redactor = Redactor([parse_redaction("alice")], resealer.add)
    sentence = _nmea(b"PXYZ,alice")
    run(redactor, [Entry("rx", 1, sentence[:8]), Entry("rx", 2, sentence[8:])])
    resealer.finish()
    assert b"".join(bytes(e.data) for e in out) == _nmea(b"PXYZ,*****")
    assert (resealer.frames, resealer.missed) == (1, 0)


def test_marks_that_touch_or_overlap_merge():
    assert merged_marks([(5, 2), (0, 3), (3, 1), (6, 4)]) == [(0, 4), (5, 5)]
