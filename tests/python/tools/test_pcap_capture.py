"""wiretape.tools.pcap_capture: what is read of a capture through tshark,
and the text it is read from (the import itself: test_pcap_import.py)."""

import pytest

from wiretape.tools.pcap_capture import (address_text, is_capture, parse_address,
                                         parse_epoch_ns, seconds_text)


def test_a_tshark_time_is_exact_nanoseconds():
    assert parse_epoch_ns("1795482638.583698988") == 1795482638583698988
    assert parse_epoch_ns("1795482638.5") == 1795482638500000000
    assert parse_epoch_ns(" 7\n") == 7_000_000_000


def test_addresses_read_and_write_ipv6_in_brackets():
    assert parse_address("[::1]:502") == ("::1", 502)
    assert parse_address("10.0.0.7:502") == ("10.0.0.7", 502)
    assert address_text("::1", 502) == "[::1]:502"
    for bad in ("10.0.0.7", "10.0.0.7:70000", ":502"):
        with pytest.raises(ValueError, match="expected IP:PORT"):
            parse_address(bad)


def test_a_huge_time_is_said_in_digits():
    assert seconds_text(1_500_000_000) == "1.5"
    assert seconds_text(10**40) == "1e+31"


def test_a_capture_is_known_by_its_magic(tmp_path):
    pcapng = tmp_path / "a.bin"
    pcapng.write_bytes(b"\x0a\x0d\x0d\x0a" + bytes(28))
    other = tmp_path / "b.bin"
    other.write_bytes(b"WTAP" + bytes(28))
    assert is_capture(str(pcapng)) and not is_capture(str(other))
