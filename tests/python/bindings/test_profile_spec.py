"""_core.profile_from_spec: every --profile value read by the replay's rule,
a built-in name and a declared profile alike."""

import pytest

from wiretape import _core, OptionError


@pytest.mark.parametrize("name", _core.profile_names())
def test_a_name_is_the_built_in_profile(name):
    profile = _core.profile_from_spec(name)
    assert profile.name == _core.find_profile(name).name
    assert _core.parse_options(profile.options) == [("profile", name)]


def test_a_declared_spec_is_the_profile_a_replay_declares():
    spec = "framing=length:2:1:3,echo=0:2,checksum=crc16-modbus@-2"
    profile = _core.profile_from_spec(spec)
    assert profile.name == _core.declared_profile(spec).name
    assert _core.parse_options(profile.options) == _core.parse_options(spec)
    # The same keys in a replay's option string are taken without complaint.
    _core.check_replay_options("type=replay,file=s.wtape,match=request," + profile.options)


def test_profile_equals_name_and_surrounding_space_are_read_too():
    assert _core.profile_from_spec("profile=modbus-tcp").name == "modbus-tcp"
    assert _core.profile_from_spec("  lines\n").name == "lines"


@pytest.mark.parametrize("spec, key", [
    ("", "profile"),
    ("   ", "profile"),
    ("no-such-profile", "profile"),
    ("framing=fixed:4,match=request", "match"),
    ("echo=0:2", "echo"),
    ("profile=scip,framing=fixed:4", "framing"),
    ("framing=bogus", "framing"),
])
def test_a_bad_spec_is_an_option_error_naming_the_key(spec, key):
    with pytest.raises(OptionError) as caught:
        _core.profile_from_spec(spec)
    assert caught.value.key == key
