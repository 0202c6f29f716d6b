"""The endpoints of ``record`` and ``replay``: the ``NAME=`` prefixes of
``--device``, ``--pty``, ``--listen``, ``--udp``, ``--peer`` and ``--as``
(DESIGN.md section 19), grouped into one :class:`Endpoint` per channel, and
the usage errors of that grouping.

``NAME=`` is a prefix only when NAME is a good channel name (the C++ rule,
``channel_name_problem``): option keys are refused as names, so
``--device type=tcp,host=h,port=1`` stays an option string, and a path
(``/tmp/a=b``) is not a name either. One unnamed endpoint set is the
single-port form; named ones are a channel each; the two do not mix.
"""

from __future__ import annotations

from typing import Dict, List, Optional, Sequence, Tuple

from .errors import UsageError

# The endpoint flags: argparse dest -> the flag as the user writes it.
ENDPOINT_FLAGS = {
    "device": "--device",
    "pty": "--pty",
    "listen": "--listen",
    "udp": "--udp",
    "peer": "--peer",
    "redirect_path": "--as",
}
# Where a client reaches a channel: one of these per channel.
CLIENT_SIDES = ("pty", "listen", "udp")


def _name_problem(name: str) -> Optional[str]:
    from .. import _core

    return _core.channel_name_problem(name)


def split_name(value: str) -> Tuple[str, str]:
    """(NAME, rest) of ``NAME=rest`` when NAME is a channel name, else
    ("", value): the value stands unnamed."""
    name, sep, rest = value.partition("=")
    if sep and name and _name_problem(name) is None:
        return name, rest
    return "", value


class Endpoint:
    """One channel's flags (each None when not given); ``name`` "" is the
    single unnamed channel. (Not a dataclass: see session.ProfileChoice.)"""

    def __init__(self, name: str, values: Optional[Dict[str, str]] = None):
        self.name = name
        self.values: Dict[str, str] = {} if values is None else values

    def __repr__(self) -> str:
        return f"Endpoint({self.name!r}, {self.values!r})"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Endpoint):
            return NotImplemented
        return (self.name, self.values) == (other.name, other.values)

    __hash__ = None  # type: ignore[assignment]  # mutable, as the dataclass was

    def get(self, dest: str) -> Optional[str]:
        return self.values.get(dest)

    @property
    def device(self) -> Optional[str]:
        return self.values.get("device")

    @property
    def pty(self) -> Optional[str]:
        return self.values.get("pty")

    @property
    def listen(self) -> Optional[str]:
        return self.values.get("listen")

    @property
    def udp(self) -> Optional[str]:
        return self.values.get("udp")

    @property
    def peer(self) -> Optional[str]:
        return self.values.get("peer")

    @property
    def redirect_path(self) -> Optional[str]:
        return self.values.get("redirect_path")

    @property
    def client_sides(self) -> List[str]:
        return [dest for dest in CLIENT_SIDES if dest in self.values]

    @property
    def streams_to_peer(self) -> bool:
        """``record --udp NAME=LISTEN --peer NAME=DRIVER`` without a
        device: the device streams datagrams to LISTEN and each is forwarded
        to the driver at DRIVER (and recorded as rx)."""
        return self.device is None and self.udp is not None and self.peer is not None

    def flag(self, dest: str) -> str:
        """The flag as given: ``--pty gps=/tmp/gps`` or ``--pty /tmp/gps``."""
        value = self.values[dest]
        prefix = f"{self.name}=" if self.name else ""
        return f"{ENDPOINT_FLAGS[dest]} {prefix}{value}"


def collect(args, dests: Sequence[str]) -> List[Endpoint]:
    """The endpoints of `args` (each endpoint flag a list, argparse's
    append), one per channel in the order the names first appear. Two
    values of one flag for one name, and named and unnamed values together,
    are usage errors naming the flags."""
    endpoints: Dict[str, Endpoint] = {}
    named_flag: Optional[str] = None
    unnamed_flag: Optional[str] = None
    for dest in dests:
        for value in getattr(args, dest, None) or []:
            name, rest = split_name(value)
            shown = f"{ENDPOINT_FLAGS[dest]} {value}"
            if name:
                named_flag = named_flag or shown
            else:
                unnamed_flag = unnamed_flag or shown
            endpoint = endpoints.setdefault(name, Endpoint(name))
            if dest in endpoint.values:
                what = f"channel {name!r}" if name else "the one unnamed channel"
                raise UsageError(
                    f"{ENDPOINT_FLAGS[dest]} is given twice for {what} "
                    f"({endpoint.flag(dest)} and {shown}): give each channel one "
                    f"{ENDPOINT_FLAGS[dest]}, with its own NAME=")
            endpoint.values[dest] = rest
    if named_flag and unnamed_flag:
        raise UsageError(
            f"{unnamed_flag} has no NAME= while {named_flag} has one: with several "
            "channels every endpoint flag names its channel (NAME=VALUE)")
    return list(endpoints.values())


def check_record(endpoints: List[Endpoint], with_command: bool) -> None:
    """Every channel of ``record`` has a device (or streams to its --peer)
    and one client side (with -- CMD the pty is implied)."""
    for endpoint in endpoints:
        _check_one_client_side(endpoint, required=not with_command)
        if endpoint.device is None and not endpoint.streams_to_peer:
            given = ", ".join(endpoint.flag(dest) for dest in endpoint.values)
            if endpoint.name:
                raise UsageError(
                    f"channel {endpoint.name!r} has no device ({given}): give "
                    f"--device {endpoint.name}=OPTS (or, for a device streaming "
                    f"datagrams, --udp {endpoint.name}=LISTEN --peer "
                    f"{endpoint.name}=DRIVER_ADDR)")
            raise UsageError("the following arguments are required: --device")
        _check_peer(endpoint)


def check_replay(endpoints: List[Endpoint], with_command: bool,
                 channel_names: Sequence[str], file: str) -> None:
    """Every channel of ``replay`` is one of the file's and has one client
    side; a file of several channels needs them named."""
    named_channels = [name for name in channel_names if name]
    for endpoint in endpoints:
        _check_one_client_side(endpoint, required=not with_command)
        _check_peer(endpoint)
        if not endpoint.name:
            if len(channel_names) > 1:
                first = next(iter(endpoint.values))
                raise UsageError(
                    f"{endpoint.flag(first)}: {file} has {len(channel_names)} channels "
                    f"({', '.join(named_channels)}): name the channel of each endpoint "
                    f"({ENDPOINT_FLAGS[first]} {named_channels[0]}=...)")
            continue
        if endpoint.name not in named_channels:
            first = next(iter(endpoint.values))
            if named_channels:
                import difflib  # only a usage error needs it

                close = difflib.get_close_matches(endpoint.name, named_channels, n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                has = f"its channels are {', '.join(named_channels)}"
            else:
                hint = ""
                has = "it has one unnamed channel: give the flags without NAME="
            raise UsageError(f"{endpoint.flag(first)}: {file} has no channel "
                             f"{endpoint.name!r}{hint}; {has}")


def _check_one_client_side(endpoint: Endpoint, required: bool) -> None:
    sides = endpoint.client_sides
    if len(sides) > 1:
        raise UsageError(f"{endpoint.flag(sides[1])}: not allowed with "
                         f"{endpoint.flag(sides[0])} (one client side per channel)")
    if sides or not required:
        return
    if endpoint.name:
        given = ", ".join(endpoint.flag(dest) for dest in endpoint.values)
        raise UsageError(
            f"channel {endpoint.name!r} has no client side ({given}): give --pty "
            f"{endpoint.name}=PATH, --listen {endpoint.name}=HOST:PORT or --udp "
            f"{endpoint.name}=HOST:PORT")
    raise UsageError("give where the client connects: --pty PATH or --listen HOST:PORT "
                     "(datagrams: --udp HOST:PORT)")


def _check_peer(endpoint: Endpoint) -> None:
    if endpoint.peer is not None and endpoint.udp is None:
        if endpoint.name:
            raise UsageError(f"{endpoint.flag('peer')} is where --udp sends datagrams: give "
                             f"--udp {endpoint.name}=HOST:PORT too")
        raise UsageError("--peer is where --udp sends datagrams: give --udp HOST:PORT too")


def single(args, endpoints: List[Endpoint]) -> None:
    """The single-port form: the one unnamed endpoint's values set back on
    `args` as plain values (None where not given), as the single-port code
    reads them."""
    endpoint = endpoints[0] if endpoints else Endpoint("")
    for dest in ENDPOINT_FLAGS:
        if hasattr(args, dest):
            setattr(args, dest, endpoint.get(dest))


def is_single(endpoints: List[Endpoint]) -> bool:
    """The single-port form: at most one endpoint set, unnamed. Its one
    client side is checked here (argparse's "not allowed with" of old)."""
    if len(endpoints) == 1 and not endpoints[0].name:
        _check_one_client_side(endpoints[0], required=False)
    return len(endpoints) <= 1 and all(not endpoint.name for endpoint in endpoints)
