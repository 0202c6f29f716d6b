"""Running a program whose device path is hard-coded against a virtual
device: ``wiretape record ... -- CMD`` and ``wiretape replay ... --as PATH
-- CMD`` (DESIGN §12, "Hard-coded device paths").

CMD runs with the preload shim ``_redirect_device.so`` (src/shim/), which
rewrites the path in CMD's open and stat calls to the bridge's pty; it
reaches dynamically linked programs. A CMD that opens several hard-coded
paths (a session of several channels) has each redirected to its own pty
(:class:`RedirectedDevice`; up to :data:`MAX_REDIRECTED_DEVICES`). Where the shim cannot reach (static
programs, programs that scan /dev), CMD also runs in a private mount
namespace with the pty bind-mounted over the path, when wiretape runs as
root and the path exists (a bind mount needs something to cover).

Under ``replay``, the recording's device identity (DESIGN §20, "Identity")
is presented too: the shim redirects its ``/dev/serial/by-id`` name and
answers pyserial's ``list_ports`` lookups from a small sysfs tree written
to a temporary folder (``_core.present_device_identity``).

A pty has no modem lines, break or custom baud: the shim emulates them on
the redirected descriptor and tells the bridge through a side channel, a
Unix socket made by :class:`LineChannelPath` (DESIGN §20).
"""

from __future__ import annotations

import os
import sys
from typing import Dict, List, Optional, Sequence, Tuple

from . import _core, scaled_clock
from .children import Child, CommandNotStarted, SanitizerWatch, ValueFields, sanitizer_report

SHIM_NAME = "_redirect_device.so"
# The variables the shim reads (src/shim/redirect_device.c).
ENV_FROM = "WIRETAPE_REDIRECT_FROM"
ENV_TO = "WIRETAPE_REDIRECT_TO"
ENV_HITS = "WIRETAPE_REDIRECT_HITS"
# The side channel's socket (src/shim/line_protocol.h, WT_LINE_ENV).
ENV_LINE_CHANNEL = "WIRETAPE_LINE_CHANNEL"
# How many paths the shim redirects at once (WIRETAPE_SHIM_DEVICES in
# src/shim/serial_lines.h): device 0 reads the variables above, device N
# the same names ending in _N (device_variable).
MAX_REDIRECTED_DEVICES = 8


def device_variable(name: str, device: int) -> str:
    """The shim's variable `name` for redirected device number `device`."""
    return name if device == 0 else f"{name}_{device}"


class RedirectedDevice(ValueFields):
    """One path CMD opens, redirected to `pty_path`: the recorded `identity`
    presented for it, its serial lines told to the bridge at `line_channel`.
    (Not a dataclass: ``dataclasses`` imports ``inspect``, ``ast`` and
    ``dis``, 7 ms of every ``-- CMD``'s start-up; equal and shown as one.)"""

    _FIELDS = ("path", "pty_path", "identity", "line_channel")

    def __init__(self, path: str, pty_path: str, identity: Optional[Dict[str, str]] = None,
                 line_channel: Optional[str] = None):
        self.path = path
        self.pty_path = pty_path
        self.identity = identity
        self.line_channel = line_channel


# Private files and folders of a command's run (the side channel's folder,
# the hits files) are made as tempfile.mkdtemp and mkstemp make them, in
# tempfile.gettempdir(), but without importing tempfile unless the process
# has already: it imports shutil, and shutil bz2 and lzma, 4 ms of the
# start-up of every -- CMD (replay_as_overhead_ratio, docs/benchmarks.md).
_TEMPORARY_FOLDER: Optional[str] = None


def _temporary_folder() -> str:
    """tempfile.gettempdir(): the first of $TMPDIR, $TEMP, $TMP, /tmp,
    /var/tmp, /usr/tmp and the working directory where a file can be made
    (tempfile's own answer, its ``tempdir`` included, once it is imported)."""
    global _TEMPORARY_FOLDER
    loaded = sys.modules.get("tempfile")
    if loaded is not None:
        return loaded.gettempdir()
    if _TEMPORARY_FOLDER is None:
        candidates = [os.environ[name] for name in ("TMPDIR", "TEMP", "TMP")
                      if os.environ.get(name)]
        candidates += ["/tmp", "/var/tmp", "/usr/tmp"]
        try:
            candidates.append(os.getcwd())
        except OSError:
            candidates.append(os.curdir)
        for folder in candidates:
            folder = os.path.abspath(folder) if folder != os.curdir else folder
            try:  # tempfile's test: a file made and written there, else the next
                fd, probe = _make_file(folder, "wiretape-probe-")
                try:
                    try:
                        os.write(fd, b"blat")
                    finally:
                        os.close(fd)
                finally:
                    os.unlink(probe)
            except OSError:
                continue
            _TEMPORARY_FOLDER = folder
            break
        else:
            import tempfile  # none will do: tempfile's own error

            return tempfile.gettempdir()
    return _TEMPORARY_FOLDER


def _names(prefix: str):
    """Names to try, as tempfile's: the prefix and random characters."""
    for _ in range(10000):
        yield prefix + os.urandom(6).hex()


def _make_file(folder: str, prefix: str):
    """(descriptor, path) of a new file in `folder`, readable and writable
    by its owner alone (tempfile.mkstemp's flags and mode)."""
    flags = os.O_RDWR | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0) | \
        getattr(os, "O_CLOEXEC", 0)
    for name in _names(prefix):
        path = os.path.join(folder, name)
        try:
            return os.open(path, flags, 0o600), os.path.abspath(path)
        except FileExistsError:
            continue
    raise FileExistsError(f"no name left for a file {prefix}... in {folder}")


def make_private_file(prefix: str) -> str:
    """tempfile.mkstemp(prefix=prefix)'s file, closed: its path."""
    loaded = sys.modules.get("tempfile")
    if loaded is not None:
        fd, path = loaded.mkstemp(prefix=prefix)
    else:
        fd, path = _make_file(_temporary_folder(), prefix)
    os.close(fd)
    return path


def make_private_folder(prefix: str) -> str:
    """tempfile.mkdtemp(prefix=prefix): a new folder that its owner alone
    can enter; its absolute path."""
    loaded = sys.modules.get("tempfile")
    if loaded is not None:
        return loaded.mkdtemp(prefix=prefix)
    folder = _temporary_folder()
    for name in _names(prefix):
        path = os.path.join(folder, name)
        try:
            os.mkdir(path, 0o700)
        except FileExistsError:
            continue
        return os.path.abspath(path)
    raise FileExistsError(f"no name left for a folder {prefix}... in {folder}")


class LineChannelPath:
    """A path for the side channel's socket, in a private directory of its
    own (the bridge creates the socket there); removed by :meth:`close`."""

    def __init__(self) -> None:
        self._directory = make_private_folder("wiretape-lines-")
        self.path = os.path.join(self._directory, "lines")

    def close(self) -> None:
        for remove in (lambda: os.unlink(self.path), lambda: os.rmdir(self._directory)):
            try:
                remove()
            except OSError:
                pass

    def __enter__(self) -> "LineChannelPath":
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()
# The presented identity's (src/shim/device_identity.c).
ENV_IDENTITY_TTY = "WIRETAPE_IDENTITY_TTY"
ENV_IDENTITY_SYSFS = "WIRETAPE_IDENTITY_SYSFS"
ENV_IDENTITY_BY_ID = "WIRETAPE_IDENTITY_BY_ID"


def shim_path() -> str:
    """The preload shim, installed next to the extension."""
    path = os.path.join(os.path.dirname(os.path.abspath(_core.__file__)), SHIM_NAME)
    if not os.path.isfile(path):
        raise RuntimeError(f"{path}: the device-redirecting shim is missing "
                           "(it is built on Linux only; rebuild with make)")
    return path


def device_path_of(options: str) -> Optional[str]:
    """The device path an option string opens (``device=``, as of
    ``type=serial``), or None when it names none (TCP, UDP, ...). Raises
    OptionError for a string that is not an option string."""
    return dict(_core.parse_options(options)).get("device") or None


def _recorded_channel(session_file: str, channel: Optional[str]):
    """The header's channel `channel` (the first when None)."""
    with _core.SessionReader(session_file) as reader:
        channels = reader.header.channel_list()
    if channel is None:
        return channels[0]
    for recorded in channels:
        if recorded.name == channel:
            return recorded
    raise ValueError(f"{session_file}: no channel {channel!r}")


def recorded_device_path(session_file: str, channel: Optional[str] = None) -> Optional[str]:
    """The device path a recording's channel (its first by default) was
    made on (its port options), or None (a TCP or UDP device, a flexiport
    log without one)."""
    return device_path_of(_recorded_channel(session_file, channel).port_options)


def recorded_identity(session_file: str, channel: Optional[str] = None) -> Dict[str, str]:
    """The device identity a recording's channel (its first by default)
    holds ({} when it has none)."""
    return dict(_recorded_channel(session_file, channel).device_identity)


# <sched.h> and <sys/mount.h>: Python 3.11 has no os.unshare or os.mount.
_CLONE_NEWNS = 0x00020000
_MS_BIND = 4096
_MS_REC = 16384
_MS_PRIVATE = 1 << 18


def can_bind_mount(device_path: str) -> bool:
    """A private mount namespace is tried as root over a path that exists
    and is not a directory (a terminal can only cover a file)."""
    return (hasattr(os, "geteuid") and os.geteuid() == 0 and os.path.exists(device_path)
            and not os.path.isdir(device_path))


def _bind_mount_in_private_namespace(binds: Sequence[Tuple[str, str]]):
    """The preexec function of CMD: a mount namespace of its own, nothing
    propagated back to the host, each (pty, device path) pty bound over its
    device path. A step that fails leaves CMD to the shim alone (the kernel
    or the container may refuse namespaces); wiretape still sees whether
    CMD opened the pty."""
    import ctypes  # as root over an existing path only: not on every -- CMD's start-up

    libc = ctypes.CDLL(None, use_errno=True)  # loaded before the fork
    unshare, mount = libc.unshare, libc.mount
    encoded = [(os.fsencode(pty_path), os.fsencode(device_path))
               for pty_path, device_path in binds]

    def in_child() -> None:
        if unshare(_CLONE_NEWNS) != 0:
            return
        if mount(None, b"/", None, _MS_REC | _MS_PRIVATE, None) != 0:
            return  # a bind now could show on the host: none
        for source, target in encoded:
            mount(source, target, None, _MS_BIND, None)

    return in_child


def _binary(stream):
    """The byte stream under a text stream (a test's capture may have none)."""
    stream.flush()
    return getattr(stream, "buffer", None) or _TextRelay(stream)


class _TextRelay:
    """Writes bytes to a text stream that has no byte stream under it."""

    def __init__(self, stream):
        self._stream = stream

    def write(self, data: bytes) -> None:
        self._stream.write(data.decode("utf-8", "replace"))

    def flush(self) -> None:
        self._stream.flush()


# A relayed CMD's output is seen as it comes; only so much of its end is
# kept (bytes of each of stdout and stderr).
_RELAYED_OUTPUT_KEPT = 1 << 20


class RedirectedCommand:
    """CMD running with ``device_path`` redirected to ``pty_path``, as a
    :class:`~wiretape.children.Child`: its output captured (stderr with
    stdout), ended with its whole group. With ``relay``, stdout and stderr
    are captured apart and relayed as they come to this process's own
    stdout and stderr, and CMD reads this process's stdin. A recorded
    device ``identity`` (SessionHeader.device_identity) is presented to CMD:
    its by-id name is redirected too, and pyserial's ``list_ports`` finds
    the device by its USB ids. ``line_channel``: the bridge's side-channel
    socket for the serial lines (without it the shim emulates them in CMD
    alone). `more_devices`: the other paths CMD opens, each redirected to
    its own pty (a session of several channels)."""

    def __init__(self, argv: Sequence[str], device_path: str, pty_path: str,
                 relay: bool = False, identity: Optional[Dict[str, str]] = None,
                 line_channel: Optional[str] = None, speed: float = 1.0,
                 more_devices: Sequence[RedirectedDevice] = ()):
        self.argv = list(argv)
        self.device_path = device_path
        self.devices: List[RedirectedDevice] = [
            RedirectedDevice(device_path, pty_path, identity, line_channel), *more_devices]
        if len(self.devices) > MAX_REDIRECTED_DEVICES:
            raise ValueError(f"{len(self.devices)} device paths to redirect: the shim "
                             f"redirects at most {MAX_REDIRECTED_DEVICES}")
        self._watches: Tuple[SanitizerWatch, ...] = ()
        self._identity_tree: Optional[str] = None
        # Each process of CMD that uses a path appends a line to its file.
        self._hits_files: List[str] = []
        # --speed K: CMD's clock runs K times faster (wiretape.scaled_clock).
        env = scaled_clock.environment(speed)
        preload = env.get("LD_PRELOAD", "").strip()
        env["LD_PRELOAD"] = shim_path() + (" " + preload if preload else "")
        try:
            for number in range(MAX_REDIRECTED_DEVICES):
                # A wiretape run inside another must not inherit its devices.
                for name in (ENV_FROM, ENV_TO, ENV_HITS, ENV_LINE_CHANNEL, ENV_IDENTITY_TTY,
                             ENV_IDENTITY_SYSFS, ENV_IDENTITY_BY_ID):
                    env.pop(device_variable(name, number), None)
            for number, device in enumerate(self.devices):
                hits_file = make_private_file("wiretape-redirect-")
                self._hits_files.append(hits_file)
                env[device_variable(ENV_FROM, number)] = device.path
                env[device_variable(ENV_TO, number)] = device.pty_path
                env[device_variable(ENV_HITS, number)] = hits_file
                if device.line_channel:
                    env[device_variable(ENV_LINE_CHANNEL, number)] = device.line_channel
                if device.identity:
                    env.update(self._present(device, number))
        except BaseException:
            self._remove_files()
            raise
        binds = [(device.pty_path, device.path) for device in self.devices
                 if can_bind_mount(device.path)]
        self.bind_mounted = bool(binds)
        preexec = _bind_mount_in_private_namespace(binds) if binds else None
        try:
            if relay:
                self._watches = (SanitizerWatch(_binary(sys.stdout)),
                                 SanitizerWatch(_binary(sys.stderr)))
                self.child = Child(self.argv, env=env, preexec_fn=preexec,
                                   separate_stderr=True, relay=self._watches[0],
                                   relay_stderr=self._watches[1], stdin=None,
                                   keep=_RELAYED_OUTPUT_KEPT)
            else:
                self.child = Child(self.argv, env=env, preexec_fn=preexec)
        except CommandNotStarted:
            self._remove_files()
            raise

    def _present(self, device: RedirectedDevice, number: int) -> Dict[str, str]:
        """The shim's variables that present the identity of device
        `number`, its tree written (device N's in a folder of its own)."""
        if self._identity_tree is None:
            self._identity_tree = make_private_folder("wiretape-identity-")
        folder = self._identity_tree
        if number:
            folder = os.path.join(folder, f"device-{number}")
            os.mkdir(folder)
        tty_name, presented, by_id = _core.present_device_identity(
            device.identity or {}, folder, device.path)
        env = ({device_variable(ENV_IDENTITY_TTY, number): tty_name,
                device_variable(ENV_IDENTITY_SYSFS, number): presented} if tty_name else {})
        if by_id:
            env[device_variable(ENV_IDENTITY_BY_ID, number)] = by_id
        return env

    @property
    def name(self) -> str:
        return self.child.name

    def poll(self) -> Optional[int]:
        return self.child.poll()

    def end(self) -> None:
        """Ends CMD and what it started (SIGTERM, then SIGKILL after a grace
        period) and reaps it."""
        self.child.end()

    def exit_status(self) -> int:
        """CMD's exit status as a shell reports it (128+N for signal N)."""
        self.child.wait()
        status = self.child.exit_status
        assert status is not None  # it has exited
        return status

    def sanitizer_report(self) -> Optional[str]:
        """The first line of a sanitizer report CMD printed, or None (once
        CMD has ended)."""
        if self._watches:
            return self._watches[0].finish() or self._watches[1].finish()
        return sanitizer_report(self.child.stdout)

    def used_device_path(self, number: int = 0) -> bool:
        """True once any process of CMD opened (or looked at) the path of
        device `number` (the first by default)."""
        try:
            return os.path.getsize(self._hits_files[number]) > 0
        except (OSError, IndexError):
            return False

    def close(self) -> None:
        self._remove_files()

    def _remove_files(self) -> None:
        for hits_file in self._hits_files:
            try:
                os.unlink(hits_file)
            except OSError:
                pass
        self._hits_files = []
        if self._identity_tree is not None:
            import shutil  # a presented identity's tree only

            shutil.rmtree(self._identity_tree, ignore_errors=True)
            self._identity_tree = None
