"""Bridges between a device and a client: the record proxy, the port server
and virtual devices (replay on a pty, TCP or UDP).

Each function starts the bridge and returns a running :class:`BridgeHandle`
at once; the caller waits on it in short slices (so Ctrl-C works) and stops
it::

    handle = record("/dev/ttyUSB0", "run.wtape", pty="/tmp/ttyV0")
    try:
        while not handle.wait(0.2):
            pass
    except KeyboardInterrupt:
        handle.stop()
        handle.wait()
    print(handle.result())

``result()`` is a :class:`BridgeResult`: ``outcome`` (``running``,
``stopped``, ``finished``, ``device_closed``, ``mismatch``, ``failed``), ``ok``
(False for a mismatch or a failure: the CLI exits 1 or 3), ``message`` (the
mismatch report or error), ``nothing_served`` (a replay whose recording has
rx but that served none of it says why: ``wiretape replay`` exits 1 then) and
``stats``, a :class:`BridgeStats` of counters (``bytes_to_device``,
``clients_accepted``...; ``stats.items()`` lists them).

A pty the bridge creates is mode 0660, group ``dialout`` where that group
exists (else the process's group), as a real serial device is, so that a
client that drops root can open it; ``pty_mode`` (an int, e.g. ``0o666``) and
``pty_group`` (a name or a gid) change that.

``udp="HOST:PORT"`` (``record``, ``serve_replay``) is a datagram client side:
the driver sends to HOST:PORT; each datagram is one write to the device (one
``tx`` record) and each read of the device goes back as one datagram (one
``rx`` record) to the last sender, or to ``peer`` (``serve_replay``). A client
that floods faster than the device takes its datagrams loses the excess:
``stats.datagrams_dropped`` counts them (never recorded, never forwarded).
"""

from __future__ import annotations

import os
from typing import List, Mapping, Optional, Tuple, Union

from . import _core
from ._core import BridgeResult, BridgeStats
from .options import join_options

__all__ = [
    "DEFAULT_MAX_MONITORS",
    "DEFAULT_PTY_MODE",
    "BridgeHandle",
    "BridgeResult",
    "BridgeStats",
    "device_options",
    "parse_listen",
    "parse_udp_address",
    "record",
    "serve",
    "serve_replay",
]


# A bare path means type=serial,device=PATH.
device_options = _core.device_options


def _split_address(text: str, what: str, default_host: Optional[str],
                   minimum_port: int) -> Tuple[str, int]:
    """``HOST:PORT`` or ``[v6]:PORT`` (or ``PORT`` alone where
    ``default_host`` is given) as (host, port); ``what`` names the option in
    the ValueError."""
    if text.startswith("["):
        close = text.find("]")
        if close < 0 or not text[close + 1:].startswith(":"):
            raise ValueError(f"{what} address {text!r}: expected [HOST]:PORT")
        host, port_text = text[1:close], text[close + 2:]
    elif ":" in text:
        host, port_text = text.rsplit(":", 1)
    elif default_host is not None:
        host, port_text = default_host, text
    else:
        raise ValueError(f"{what} address {text!r}: expected HOST:PORT (the port is missing)")
    host = host or (default_host or "")
    if not host:
        raise ValueError(f"{what} address {text!r}: expected HOST:PORT (the host is missing)")
    try:
        port = int(port_text)
    except ValueError:
        raise ValueError(
            f"{what} address {text!r}: the port must be a number (HOST:PORT)") from None
    if not minimum_port <= port <= 65535:
        raise ValueError(
            f"{what} address {text!r}: port {port} is out of range ({minimum_port}-65535)")
    return host, port


def parse_listen(listen: Union[str, int]) -> Tuple[str, int]:
    """``HOST:PORT``, ``[v6]:PORT`` or ``PORT`` (on 127.0.0.1) as (host, port).
    Port 0 picks a free port."""
    return _split_address(str(listen).strip(), "listen", "127.0.0.1", 0)


def parse_udp_address(address: str, what: str = "udp", minimum_port: int = 0) -> Tuple[str, int]:
    """``HOST:PORT`` or ``[v6]:PORT`` as (host, port) for a UDP side; both
    parts are needed and the host must resolve. ``what`` names the option in
    the error (a ValueError). Port 0 (where ``minimum_port`` allows it)
    picks a free port."""
    import socket  # UDP only: not on every command's start-up

    text = str(address).strip()
    host, port = _split_address(text, what, None, minimum_port)
    try:
        socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)
    except (socket.gaierror, UnicodeError) as error:
        raise ValueError(f"{what} address {text!r}: host {host!r} does not resolve "
                         f"({error})") from None
    return host, port


class BridgeHandle:
    """A running bridge."""

    def __init__(self, bridge: "_core.Bridge"):
        self._bridge = bridge

    def wait(self, timeout: Optional[float] = None) -> bool:
        """True once the bridge has ended; False if ``timeout`` seconds
        passed first. Interruptible by Ctrl-C."""
        return self._bridge.wait(timeout)

    def stop(self) -> None:
        """Ends the bridge (thread-safe); the session file is left complete."""
        self._bridge.stop()

    def result(self) -> BridgeResult:
        return self._bridge.result()

    def stats(self) -> BridgeStats:
        return self._bridge.stats()

    @property
    def running(self) -> bool:
        return self._bridge.running

    @property
    def pty_path(self) -> Optional[str]:
        """The terminal a client opens (pty side), e.g. ``/dev/pts/7``."""
        return self._bridge.pty_path or None

    @property
    def address(self) -> Optional[str]:
        """``HOST:PORT`` clients connect to (TCP side) or send datagrams to
        (UDP side)."""
        return self._bridge.listen_address or None

    listen_address = address

    @property
    def device_description(self) -> str:
        return self._bridge.device_description

    def messages(self) -> List[str]:
        """The diagnostics printed so far (client connects, device loss...)."""
        return self._bridge.messages()

    def __enter__(self) -> "BridgeHandle":
        return self

    def __exit__(self, *exc) -> None:
        self.stop()
        self.wait()


PtyGroup = Union[str, int, None]
# A serial device's permission bits: owner and group read and write.
DEFAULT_PTY_MODE = 0o660


def _start(device: str, *, pty, listen, udp=None, peer=None,
           backlog: Optional[int] = None, pty_mode: Optional[int] = None,
           pty_group: PtyGroup = None, **options) -> BridgeHandle:
    if sum(side is not None for side in (pty, listen, udp)) != 1:
        raise ValueError("give exactly one client side: pty=PATH, listen=HOST:PORT "
                         "or udp=HOST:PORT")
    if peer is not None and udp is None:
        raise ValueError("peer is where a UDP side sends: give udp=HOST:PORT too")
    if backlog is not None and listen is None:
        raise ValueError("backlog is the queue of TCP connections: give listen=HOST:PORT")
    if pty is None and (pty_mode is not None or pty_group is not None):
        raise ValueError("pty_mode and pty_group set who may open a pty: give pty=PATH")
    if pty is not None:
        link = "" if pty is True else os.fspath(pty)
        bridge = _core.Bridge(device, client_side="pty", pty_link=link,
                              pty_mode=DEFAULT_PTY_MODE if pty_mode is None else pty_mode,
                              pty_group="" if pty_group is None else str(pty_group),
                              **options)
    elif udp is not None:
        host, port = parse_udp_address(udp, "udp")
        peer_host, peer_port = ("", 0) if peer is None else parse_udp_address(peer, "peer", 1)
        bridge = _core.Bridge(device, client_side="udp", listen_host=host, listen_port=port,
                              udp_peer_host=peer_host, udp_peer_port=peer_port, **options)
    else:
        host, port = parse_listen(listen)
        if backlog is not None:
            options["listen_backlog"] = backlog
        bridge = _core.Bridge(device, client_side="tcp", listen_host=host,
                              listen_port=port, **options)
    bridge.start()
    return BridgeHandle(bridge)


def record(device: str, output, *, pty=None, listen=None, udp=None,
           backlog: Optional[int] = None, duration: Optional[float] = None,
           meta: Optional[Mapping[str, str]] = None,
           quiet: bool = False, pty_mode: Optional[int] = None,
           pty_group: PtyGroup = None, line_channel: str = "", peer=None,
           recorder=None, channel: str = "", compress: str = "none") -> BridgeHandle:
    """``wiretape record``: a transparent proxy between ``device`` and a pty
    at ``pty`` (a symlink path; True for none) or a TCP listener at
    ``listen`` or a UDP socket at ``udp`` (a datagram proxy: replies go to
    the last sender); every byte both ways is recorded to ``output``
    (capture=wire). On a pty, the terminal settings the client sets are
    applied to the device; ``pty_mode``/``pty_group`` set who may open it
    (default 0o660, group dialout). ``backlog``: the TCP listen queue (see
    ``serve``). ``line_channel``: the socket the ``--as`` shim tells the
    client's serial lines through (``wiretape.redirect``). ``peer``: with
    ``udp``, where the device's datagrams go from the start. ``recorder``
    (a ``wiretape.Recorder``) and ``channel`` (a name): record into that
    channel of the recorder's file instead of opening ``output`` (whose
    ``compress`` then applies). ``compress="zstd"``: ``output`` in
    compressed chunks (format 2.0)."""
    path = os.fspath(output)
    if not path.strip():
        raise ValueError("output: the file name is empty; give the session file to record to")
    if recorder is not None:
        # One file for several bridges: the recorder's (DESIGN.md section 19).
        return _start(device_options(device), pty=pty, listen=listen, udp=udp, peer=peer,
                      backlog=backlog, recorder=recorder, channel=channel,
                      duration=duration, quiet=quiet, pty_mode=pty_mode,
                      pty_group=pty_group, line_channel=line_channel)
    return _start(device_options(device), pty=pty, listen=listen, udp=udp, peer=peer,
                  backlog=backlog, output=path, metadata=dict(meta or {}),
                  duration=duration, quiet=quiet, pty_mode=pty_mode, pty_group=pty_group,
                  line_channel=line_channel, compress=compress)


def proxy(device: str, *, pty=None, listen=None, udp=None, quiet: bool = True,
          pty_mode: Optional[int] = None, pty_group: PtyGroup = None) -> BridgeHandle:
    """``record`` without a file: the client side (``pty``, ``listen`` or
    ``udp``) forwards to ``device`` and nothing is recorded (the pytest
    plugin's ``--wiretape-live``)."""
    return _start(device_options(device), pty=pty, listen=listen, udp=udp, quiet=quiet,
                  pty_mode=pty_mode, pty_group=pty_group)


DEFAULT_MAX_MONITORS = 16


def serve(device: str, listen, *, output=None, protocol: str = "raw",
          shared: bool = False, max_monitors: int = DEFAULT_MAX_MONITORS,
          reopen: bool = False, backlog: Optional[int] = None,
          quiet: bool = False, compress: str = "none") -> BridgeHandle:
    """``wiretape serve``: shares ``device`` with TCP clients at ``listen``
    (127.0.0.1 unless a host is given), raw or RFC 2217, one controlling
    client at a time (``shared``: later ones, up to ``max_monitors``, get
    read-only monitoring), recording server-side to ``output`` if given;
    ``reopen`` waits for a device that went away to come back. ``backlog``
    is how many connections the kernel completes before the bridge accepts
    them (default 4096, capped by the kernel at net.core.somaxconn)."""
    if shared and max_monitors < 1:
        raise ValueError(f"max_monitors must be at least 1, not {max_monitors}")
    return _start(device_options(device), pty=None, listen=listen,
                  output=os.fspath(output) if output else "", protocol=protocol,
                  shared=shared, max_monitors=max_monitors, reopen=reopen, backlog=backlog,
                  quiet=quiet, compress=compress)


def serve_replay(file, *, pty=None, listen=None, udp=None, peer=None,
                 replay_options: str = "", backlog: Optional[int] = None,
                 protocol: str = "raw",
                 restart: bool = False, output=None,
                 quiet: bool = False, pty_mode: Optional[int] = None,
                 pty_group: PtyGroup = None, line_channel: str = "") -> BridgeHandle:
    """``wiretape replay --pty/--listen``: the recording ``file`` becomes a
    virtual device. ``replay_options`` are replay keys (``"timing=none,
    check=data"``). Each connection is a client session (DESIGN §12:
    in match=sequence the k-th starts at the recording's k-th client_connect,
    in match=request connection order is free); ``restart`` starts the
    recording over for each new client (TCP, or pty on Linux). The result is ok,
    or ``outcome == "mismatch"`` with the report in ``message``; a recording
    with rx that no client was served leaves the reason in
    ``nothing_served``. ``pty_mode``/``pty_group`` set who may open the pty
    (default 0o660, group dialout). ``udp="HOST:PORT"`` answers request
    datagrams there with the recorded rx datagrams and sends unprompted ones
    to the last sender, or from the start to ``peer="HOST:PORT"``.
    ``protocol="rfc2217"`` (with ``listen``) serves pyserial's ``rfc2217://``
    clients: the recorded modem lines, and their line changes checked."""
    if protocol != "raw" and listen is None:
        raise ValueError(f"protocol {protocol!r} is spoken over TCP: give listen=HOST:PORT")
    options = join_options(_core.option_string([("type", "replay"), ("file", file)]),
                           replay_options)
    # Bad keys are refused before anything is opened: no listener, no pty,
    # no replay whose closing would warn about unused data.
    _core.check_replay_options(options)
    # The terminal settings the client sets are applied to the replay, as to
    # a device: under check=timing they must match the recorded settings
    # events in order with the writes (docs/replay.md "Events"), as the
    # command that made the recording made them.
    return _start(options, pty=pty, listen=listen, udp=udp, peer=peer, backlog=backlog,
                  restart=restart, protocol=protocol,
                  output=os.fspath(output) if output else "",
                  mirror_settings=True, quiet=quiet, pty_mode=pty_mode, pty_group=pty_group,
                  line_channel=line_channel)
