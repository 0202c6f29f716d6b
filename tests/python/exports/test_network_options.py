"""The pcapng export's device address comes from the recorded port options,
read by the C++ parser (`_core.parse_options`), not by a parser of its own:
any separator, bare keys, quoted values and flexiport's names of the keys."""

import ipaddress

from wiretape.exports.network import PLACEHOLDER_DEVICE, NetworkSession


def device_of(port_type, port_options):
    session = NetworkSession.of_header({"port_type": port_type, "port_options": port_options})
    return str(session.device[0]), session.device[1]


def test_white_space_and_bare_keys_separate_options_as_they_do_for_open_port():
    # Split on commas only, this read "tcp listen host=10.0.0.5 port=5000" as
    # the value of type, and "listen,host" as a key.
    assert device_of("tcp", "type=tcp listen host=10.0.0.5 port=5000") == ("10.0.0.5", 5000)
    assert device_of("tcp", "type=tcp,listen,host=10.0.0.5,port=5000") == ("10.0.0.5", 5000)


def test_a_quoted_value_with_separators_is_one_value():
    options = 'type=tcp,meta_note="a, b=c",host=10.0.0.6,port=5001'
    assert device_of("tcp", options) == ("10.0.0.6", 5001)


def test_flexiports_names_stand_for_the_keys():
    assert device_of("tcp", "type=tcp,ip=10.0.0.8,port=5002") == ("10.0.0.8", 5002)
    assert device_of("udp", "type=udp,dest_ip=10.0.0.7,dest_port=7000") == ("10.0.0.7", 7000)


def test_a_header_that_is_no_option_string_gets_the_placeholder():
    host, port = device_of("tcp", 'type=tcp,host="unterminated')
    assert ipaddress.ip_address(host) == ipaddress.ip_address(PLACEHOLDER_DEVICE[0])
    assert port == PLACEHOLDER_DEVICE[1]
