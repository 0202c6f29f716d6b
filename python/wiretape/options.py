"""Option strings from Python: thin views of the C++ key table and parser
(``include/wiretape/options.hpp``). Nothing here splits or builds an option
string or knows a key of its own; docs/options.md lists the keys. Every
option string Python makes is built by ``option_string`` (C++: values quoted,
numbers written by one rule, keys checked).
"""

from __future__ import annotations

from typing import Dict, List, Optional, Tuple

from . import _core

__all__ = ["default_of", "has_line_settings", "join_options", "option_keys", "option_string",
           "option_values", "parse_options", "replay_keys"]

parse_options = _core.parse_options
option_string = _core.option_string


def join_options(*texts: str) -> str:
    """Option strings as one, in order, empty ones left out: each read by
    parse_options and the pairs written again by option_string, so a bad
    string or a key given in two of them is an OptionError naming it."""
    return _core.option_string([pair for text in texts for pair in _core.parse_options(text)])


def option_keys(port_type: Optional[str] = None) -> List[_core.OptionKey]:
    """The rows of the key table, or those that apply to ``port_type``."""
    return [key for key in _core.option_keys()
            if port_type is None or key.applies_to(port_type)]


def has_line_settings(port_type: str) -> bool:
    """Whether a port of ``port_type`` is a serial line whose settings a
    driver sets (rate, framing, flow; lines and break come with them): the
    types the key table gives ``baud`` to, a local one (serial) or one
    exported over the network (rfc2217). A driver's rate and settings are
    passed on to these, and their recordings are of one kind of device."""
    return any(key.name == "baud" and not key.prefix for key in option_keys(port_type))


def default_of(name: str, port_type: str) -> Optional[str]:
    """The default of key ``name`` of ``port_type``, as written in an option
    string; None when it has none."""
    for key in option_keys(port_type):
        if key.name == name and not key.prefix:
            return key.default
    raise KeyError(f"the key table has no key {name!r} for type={port_type}")


def option_values(options: str, port_type: Optional[str] = None) -> Dict[str, str]:
    """An option string's values by key. With ``port_type``, flexiport's
    names of that type's keys are given under the key they stand for
    (``ip`` as ``host``); the key's own name wins when both are there."""
    values = dict(_core.parse_options(options))
    if port_type is not None:
        for key in option_keys(port_type):
            if key.alias_of and key.name in values:
                values.setdefault(key.alias_of, values[key.name])
    return values


def replay_keys() -> Tuple[str, ...]:
    """The replay keys that the CLI's ``replay`` mirrors as a flag of the
    same name (``--at-end`` for ``at_end``), its value given as the key's;
    ``faults`` has a flag of its own (``--fault``, repeatable)."""
    return tuple(key.name for key in option_keys("replay")
                 if key.flag == "--" + key.name.replace("_", "-"))
