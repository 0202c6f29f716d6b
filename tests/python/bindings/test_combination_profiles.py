"""The combination property test of DESIGN §25, profiles part (issue 37):
declared profiles with two fixes at once (two echoed fields, an id and a
counter, and a checksum over them) under every framing a declared profile
offers for fixed layouts (`length:`, `fixed:`) and the checksums it
computes, over response frames the recording splits across records, with
frames the profile cannot fix in the response (one it finds broken, a tail
the response ends inside), under match=sequence and match=request,
check=data and check=timing; against an oracle that computes what must be
served from the recording alone (support/session_oracle.py's sessions and
expectations, the clients of support/combination_clients.py), knowing the
rule of docs/replay.md: a fix applies to whole frames only, the others are
served as recorded.

Bounded for `make test`; WIRETAPE_COMBINATION_EXAMPLES raises the number
of examples, which are derandomized unless it is set (as the property test
of test_combinations.py)."""

from __future__ import annotations

import dataclasses
import os
import zlib
from typing import Callable, Dict, List, Sequence

from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import wiretape

from combination_clients import DEADLINE, PortClient, play
from session_oracle import SPLITS, Exchange, Expectation, build_session, layout, write_session

EXAMPLES_FROM_ENV = os.environ.get("WIRETAPE_COMBINATION_EXAMPLES")
EXAMPLES = int(EXAMPLES_FROM_ENV or "30")


# --- the checksums docs/replay.md names, as the oracle computes them -------------------


def _crc16(data: bytes, poly: int, init: int, reflected: bool) -> int:
    crc = init
    for byte in data:
        if reflected:
            crc ^= byte
            for _ in range(8):
                crc = (crc >> 1) ^ poly if crc & 1 else crc >> 1
        else:
            crc ^= byte << 8
            for _ in range(8):
                crc = ((crc << 1) ^ poly) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


CHECKSUMS: Dict[str, Callable[[bytes], bytes]] = {
    "crc16-modbus": lambda d: _crc16(d, 0xA001, 0xFFFF, True).to_bytes(2, "little"),
    "crc16-ccitt": lambda d: _crc16(d, 0x1021, 0xFFFF, False).to_bytes(2, "big"),
    "crc32": lambda d: zlib.crc32(d).to_bytes(4, "little"),
    "sum8": lambda d: bytes([sum(d) & 0xFF]),
    "xor8": lambda d: bytes([_xor(d)]),
}


def _xor(data: bytes) -> int:
    value = 0
    for byte in data:
        value ^= byte
    return value


# --- a declared protocol of two fixes ----------------------------------------------------

ID = (0, 2)  # the frame's id: echoed
COUNTER = (3, 1)  # a sequence counter after the length byte: echoed
HEADER = 4  # id (2), length (1), counter (1)


@dataclasses.dataclass(frozen=True)
class TwoFixes:
    """A declared profile that echoes the id and the counter into each
    response frame and recomputes the checksum at its end over them."""

    checksum: str
    fixed: int = 0  # framing=fixed:N when not 0, else framing=length

    @property
    def size(self) -> int:
        return len(CHECKSUMS[self.checksum](b""))

    @property
    def keys(self) -> str:
        framing = (f"fixed:{self.fixed}" if self.fixed
                   else f"length:2:1:{HEADER - 1 + self.size}")
        return (f"framing={framing},echo={ID[0]}:{ID[1]};{COUNTER[0]}:{COUNTER[1]},"
                f"checksum={self.checksum}@-{self.size}")

    def frame(self, frame_id: bytes, counter: int, payload: bytes) -> bytes:
        """A frame of this protocol, its checksum right: payload padded or
        cut to the fixed size when the framing is fixed."""
        if self.fixed:
            room = self.fixed - HEADER - self.size
            payload = (payload + bytes(room))[:room]
        body = frame_id + bytes([len(payload) + 1, counter]) + payload
        return body + CHECKSUMS[self.checksum](body)

    def whole(self, frame: bytes) -> bool:
        """Whether the profile reads `frame` as one of its frames: its
        length and its checksum right. Others are served as recorded."""
        size = self.fixed or (frame[2] + HEADER - 1 + self.size if len(frame) > 2 else -1)
        if len(frame) != size:
            return False
        return frame[-self.size:] == CHECKSUMS[self.checksum](frame[:-self.size])

    def fix(self, response_frame: bytes, client_request: bytes) -> bytes:
        if not self.whole(response_frame):
            return response_frame
        fixed = bytearray(response_frame)
        for offset, length in (ID, COUNTER):
            fixed[offset:offset + length] = client_request[offset:offset + length]
        body = bytes(fixed[:-self.size])
        return body + CHECKSUMS[self.checksum](body)

    def vary(self, request: bytes, salt: int) -> bytes:
        """The request as a client whose id and counter differ from the
        recording's, its checksum right for them."""
        varied = bytearray(request[:-self.size])
        for offset, length in (ID, COUNTER):
            for i in range(offset, offset + length):
                varied[i] = (varied[i] + 0x5A + salt) & 0xFF
        return bytes(varied) + CHECKSUMS[self.checksum](bytes(varied))

    def key(self, request: bytes) -> bytes:
        """What matching compares: the request without its echoed fields and
        checksum."""
        return request[2:3] + request[HEADER:-self.size]


# --- strategies -----------------------------------------------------------------------------

payloads = st.binary(min_size=1, max_size=8)


@st.composite
def protocols(draw):
    checksum = draw(st.sampled_from(sorted(CHECKSUMS)))
    fixed = draw(st.sampled_from([0, 0, HEADER + 6 + len(CHECKSUMS[checksum](b""))]))
    return TwoFixes(checksum, fixed)


@st.composite
def exchange_of(draw, protocol: TwoFixes, index: int):
    frame_id = bytes([0xA5, index & 0xFF])
    counter = draw(st.integers(0, 255))
    # The payload's first byte tells the requests apart (the key keeps it).
    request = protocol.frame(frame_id, counter, bytes([index]) + draw(payloads))
    responses = [protocol.frame(frame_id, counter, draw(payloads))
                 for _ in range(draw(st.integers(1, 2)))]
    if draw(st.integers(0, 3)) == 0:
        # A frame the device got wrong: its checksum flipped, so broken.
        at = draw(st.integers(0, len(responses) - 1))
        wrong = bytearray(responses[at])
        wrong[-1] ^= 0xFF
        responses[at] = bytes(wrong)
    if draw(st.integers(0, 3)) == 0:
        # The response ends inside a frame: the first bytes of one more.
        whole = protocol.frame(frame_id, counter, draw(payloads))
        responses.append(whole[:draw(st.integers(1, len(whole) - 1))])
    return Exchange(request, tuple(responses))


@st.composite
def combinations(draw):
    protocol = draw(protocols())
    exchanges = [draw(exchange_of(protocol, i)) for i in range(draw(st.integers(1, 4)))]
    match = draw(st.sampled_from(["sequence", "request"]))
    order = (list(draw(st.permutations(range(len(exchanges))))) if match == "request"
             else list(range(len(exchanges))))
    timing = draw(st.sampled_from(["none", "causal"]))
    return dict(protocol=protocol, exchanges=exchanges,
                split=draw(st.sampled_from(SPLITS)),
                cuts=draw(st.lists(st.integers(1, 200), min_size=1, max_size=4)),
                match=match, order=order, timing=timing,
                check=draw(st.sampled_from(["data", "timing"])) if timing == "causal" else "data",
                chunk=draw(st.sampled_from([0, 0, 1, 3])))


# --- the oracle and one combination ----------------------------------------------------------


def expectations(protocol: TwoFixes, exchanges: Sequence[Exchange], order: Sequence[int],
                 requests: Sequence[bytes], match: str) -> List[Expectation]:
    """What each request gets: the recorded exchange it matches (match=
    request: the first unused one of its key; sequence: the next), each
    whole response frame fixed from the client's request, the rest as
    recorded."""
    used: List[int] = []
    expected = []
    for asked, request in zip(order, requests):
        served = asked
        if match == "request":
            served = next(i for i, e in enumerate(exchanges)
                          if i not in used and protocol.key(e.request) == protocol.key(request))
        used.append(served)
        expected.append(Expectation(exact=b"".join(
            protocol.fix(frame, request) for frame in exchanges[served].responses)))
    return expected


def run_combination(tmp_path, protocol, exchanges, split, cuts, match, order, timing, check,
                    chunk) -> None:
    session = build_session([exchanges], split, cuts)
    tmp_path.mkdir(parents=True, exist_ok=True)
    path = write_session(tmp_path / "profiles.wtape", session)
    keys = (f"match={match},timing={timing},unused=error,at_end=closed,{protocol.keys}"
            + (",check=timing,tolerance=5000" if check == "timing" else ""))
    requests = [protocol.vary(exchanges[i].request, salt=i) for i in order]

    def describe():
        return (f"keys: {keys}\nsplit: {split} cuts {cuts}\norder: {order}\nwrites of {chunk}\n"
                f"exchanges: {exchanges}\nrecords: {layout(session)[0]}")

    port = wiretape.open_port(f'type=replay,file="{path}",timeout={DEADLINE},{keys}')
    play(PortClient(port, chunk), requests,
         expectations(protocol, exchanges, order, requests, match), describe)
    port.close()  # unused=error: everything was served


@settings(max_examples=EXAMPLES, deadline=None, derandomize=EXAMPLES_FROM_ENV is None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(combination=combinations())
def test_declared_profiles_with_two_fixes_serve_what_the_recording_says(tmp_path_factory,
                                                                         combination):
    protocol = combination["protocol"]
    event(f"checksum={protocol.checksum} framing={'fixed' if protocol.fixed else 'length'}")
    event(f"match={combination['match']} check={combination['check']} "
          f"split={combination['split']}")
    unfixable = [frame for e in combination["exchanges"] for frame in e.responses
                 if not protocol.whole(frame)]
    event(f"frames served as recorded: {'yes' if unfixable else 'none'}")
    run_combination(tmp_path_factory.mktemp("profiles"), **combination)


# Each dimension once in every bounded run, whatever the property test drew.

ISSUE_PROTOCOL = TwoFixes("sum8", fixed=HEADER + 2 + 1)  # 7-byte frames


def issue_exchange(tail: bytes) -> Exchange:
    request = ISSUE_PROTOCOL.frame(b"\xA5\x00", 9, b"\x00\x01")
    return Exchange(request, (ISSUE_PROTOCOL.frame(b"\xA5\x00", 9, b"ok"), tail))


def test_a_byte_past_the_last_whole_fixed_frame_is_served_as_recorded(tmp_path):
    # issue 37: 8 bytes under fixed:7 with sum8@-1: the eighth, a frame that
    # never completes, is the recorded `j`, not a sum8 of nothing (\x00).
    for match in ("sequence", "request"):
        run_combination(tmp_path / match, ISSUE_PROTOCOL, [issue_exchange(b"j")],
                        "frames-together", [1], match, [0], "none", "data", 0)


def test_every_checksum_with_every_unfixable_frame_split_anyhow(tmp_path):
    for number, checksum in enumerate(sorted(CHECKSUMS)):
        protocol = TwoFixes(checksum)
        frame_id = b"\xA5\x01"
        good = protocol.frame(frame_id, 7, b"good")
        broken = bytearray(protocol.frame(frame_id, 7, b"bad"))
        broken[-1] ^= 0xFF
        tail = protocol.frame(frame_id, 7, b"tail")[:5]
        exchanges = [Exchange(protocol.frame(frame_id, 7, b"\x00?"), (bytes(broken), good, tail)),
                     Exchange(protocol.frame(b"\xA5\x02", 8, b"\x01?"),
                              (protocol.frame(b"\xA5\x02", 8, b"two"),))]
        for match, check in (("sequence", "data"), ("request", "timing")):
            run_combination(tmp_path / f"{number}-{match}", protocol, exchanges, "split-frames",
                            [3, 11, 17], match, [1, 0] if match == "request" else [0, 1],
                            "causal", check, 2)
