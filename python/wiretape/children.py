"""Child processes: every command wiretape runs (CMD of ``record/replay --
CMD``, a fault campaign's driver, the demo's simulator, recorder and
scanner) is started and ended one way (DESIGN §17, "Child processes").

A :class:`Child` runs in a process group of its own (a new session), so
that ending it reaches what it started: SIGTERM to the whole group, SIGKILL
to the whole group after a grace period. It ends with this process however
this process ends (SIGKILL of wiretape by a CI job's timeout included):
Linux's parent-death signal, set between fork and exec (see
:func:`_ending_with_parent`). Its output is captured (and
relayed as it comes, if asked) by a reader thread, or passed through.
Reading stops once the direct child has exited and its group has been
ended, not at the end of the pipe: a grandchild of another session that
keeps the pipe open cannot stall the caller.
"""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import threading
import time
from typing import IO, Callable, Dict, List, Mapping, Optional, Protocol, Sequence, Union

__all__ = ["Child", "Outcome", "CommandNotStarted", "GRACE_S", "sanitizer_report",
           "SanitizerWatch",
           "EXIT_COMMAND_NOT_EXECUTABLE", "EXIT_COMMAND_NOT_FOUND"]

#: How long a child asked to end (SIGTERM) has before its group is killed.
GRACE_S = 5.0
# Shell conventions for a command that could not be started.
EXIT_COMMAND_NOT_EXECUTABLE = 126
EXIT_COMMAND_NOT_FOUND = 127
# How often the members of an ended group are looked for while they may
# still be ending (there is no event for a process group becoming empty).
_GROUP_POLL_S = 0.01
# How often a running child's caller looks at its stop event.
_STOP_POLL_S = 0.05
# Without a pidfd (a kernel before 5.3), how often a wait that also watches
# a descriptor looks at the exit.
_NO_PIDFD_POLL_S = 0.01
_CHUNK = 65536
# A pipe holds at most 1 MiB (Linux's default pipe-max-size): so many reads
# take all it held when the reading stops.
_PIPE_CHUNKS = (1 << 20) // _CHUNK


# What sanitizers print when they find something: a crash even if the
# program then exits with a plain error code, or 0 (UBSan goes on).
SANITIZER_MARKERS = ("ERROR: AddressSanitizer", "ERROR: LeakSanitizer",
                     "ERROR: MemorySanitizer", "WARNING: ThreadSanitizer",
                     "runtime error:", "ERROR: UndefinedBehaviorSanitizer")


def sanitizer_report(output: Union[bytes, str]) -> Optional[str]:
    """The first line of a sanitizer's report in a command's output, or
    None when there is none."""
    text = output.decode("utf-8", "replace") if isinstance(output, bytes) else output
    for line in text.splitlines():
        if any(marker in line for marker in SANITIZER_MARKERS):
            return line.strip()
    return None


class SanitizerWatch:
    """A relay (``write``/``flush``) that passes a command's output on and
    looks at each of its lines for a sanitizer's report: ``report`` is the
    first such line, however much output came before or after."""

    # A longer line is looked at in pieces of this size.
    _LONGEST_LINE = 65536

    def __init__(self, relay: Optional[Relay] = None):
        self._relay = relay
        self._partial = b""
        self.report: Optional[str] = None

    def write(self, data: bytes) -> None:
        if self._relay is not None:
            try:
                self._relay.write(data)
            except (OSError, ValueError):
                self._relay = None  # whoever reads it went away: still looked at
        if self.report is not None:
            return
        *lines, self._partial = (self._partial + data).split(b"\n")
        if len(self._partial) > self._LONGEST_LINE:
            lines.append(self._partial)
            self._partial = self._partial[-256:]  # a marker cut in two is still seen
        for line in lines:
            self.report = sanitizer_report(line)
            if self.report is not None:
                return

    def flush(self) -> None:
        if self._relay is not None:
            try:
                self._relay.flush()
            except (OSError, ValueError):
                self._relay = None

    def finish(self) -> Optional[str]:
        """The report, the last unended line included."""
        if self.report is None and self._partial:
            self.report = sanitizer_report(self._partial)
        return self.report


def _ending_with_parent(then: Optional[Callable[[], None]] = None
                        ) -> Optional[Callable[[], None]]:
    """What a child runs between fork and exec so that it ends (SIGKILL) when
    this process does, however it ends, then `then` (the caller's own
    preexec_fn). Linux only (prctl PR_SET_PDEATHSIG); elsewhere `then` alone.

    The signal comes when the *thread* that forked the child ends, so a
    Child is started by a thread that outlives it (the main thread, or a
    campaign's worker, which runs its child to the end). A parent that ended
    before the call cannot signal any more: the child then ends at once
    instead of running as an orphan. SIGKILL, not SIGTERM: nobody is left to
    escalate to SIGKILL should CMD ignore SIGTERM."""
    if not sys.platform.startswith("linux"):
        return then
    # The extension's prctl, not ctypes': importing ctypes was 2 ms of the
    # start-up of every -- CMD (replay_as_overhead_ratio).
    from ._core import set_parent_death_signal

    parent = os.getpid()

    def preexec() -> None:
        set_parent_death_signal(int(signal.SIGKILL))
        if os.getppid() != parent:  # the parent ended before the call
            os._exit(128 + int(signal.SIGKILL))
        if then is not None:
            then()
    return preexec


class CommandNotStarted(Exception):
    """The command could not be run; ``exit_code`` is 127 (not found) or
    126 (not executable, or another reason), as a shell says."""

    def __init__(self, message: str, exit_code: int):
        super().__init__(message)
        self.exit_code = exit_code


Output = Union[bytes, str]


class Relay(Protocol):
    """Where a child's output is relayed: a binary stream, or a filter."""

    def write(self, data: bytes) -> object: ...

    def flush(self) -> None: ...


class ValueFields:
    """Equality and repr by the values of ``_FIELDS``, as a dataclass gives
    them; for the classes of the ``-- CMD`` path, which cannot be
    dataclasses (``dataclasses`` imports ``inspect``, ``ast`` and ``dis``,
    7 ms of every ``-- CMD``'s start-up)."""

    _FIELDS: tuple = ()

    def _values(self) -> tuple:
        return tuple(getattr(self, name) for name in self._FIELDS)

    def __eq__(self, other: object) -> bool:
        if other.__class__ is not self.__class__:
            return NotImplemented
        return self._values() == other._values()  # type: ignore[attr-defined]

    __hash__ = None  # type: ignore[assignment]  # equal by value; a subclass may hash

    def __repr__(self) -> str:
        return (f"{type(self).__qualname__}("
                + ", ".join(f"{name}={getattr(self, name)!r}" for name in self._FIELDS) + ")")


class Outcome(ValueFields):
    """How a child ended. ``returncode`` as subprocess has it (minus N for
    a death by signal N); ``timed_out``: it was still running at its
    timeout and was ended; ``stdout`` the captured output (stderr included
    unless it was captured apart, in ``stderr``); ``stopped``: the caller's
    ``stop`` event ended it before it exited or timed out.

    Read-only, equal, hashed and shown by its values, as a frozen
    dataclass; not one, because ``dataclasses`` imports ``inspect``,
    ``ast`` and ``dis``, 7 ms of every ``-- CMD``'s start-up."""

    _FIELDS = ("argv", "returncode", "timed_out", "stdout", "stderr", "stopped")

    argv: Sequence[str]
    returncode: int
    timed_out: bool
    stdout: Output
    stderr: Output
    stopped: bool

    def __init__(self, argv: Sequence[str], returncode: int, timed_out: bool, stdout: Output,
                 stderr: Output, stopped: bool = False):
        for name, value in zip(self._FIELDS, (argv, returncode, timed_out, stdout, stderr,
                                              stopped)):
            object.__setattr__(self, name, value)

    def __setattr__(self, name: str, value: object) -> None:
        raise AttributeError(f"cannot assign to field {name!r}")

    def __delattr__(self, name: str) -> None:
        raise AttributeError(f"cannot delete field {name!r}")

    def __hash__(self) -> int:
        return hash(self._values())

    @property
    def exit_status(self) -> int:
        """The exit status as a shell reports it (128+N for signal N)."""
        return 128 - self.returncode if self.returncode < 0 else self.returncode

    @property
    def text(self) -> str:
        """stdout as text (UTF-8, undecodable bytes replaced)."""
        if isinstance(self.stdout, str):
            return self.stdout
        return self.stdout.decode("utf-8", "replace")

    @property
    def signal(self) -> Optional[int]:
        """The signal that ended the child, or None when it exited."""
        return -self.returncode if self.returncode < 0 else None


class _Reader:
    """A thread reading the child's pipes into buffers (and relaying them)
    until told to stop; then it takes what is already in the pipes, without
    waiting for their end."""

    def __init__(self, pipes: Dict[int, IO[bytes]], relays: Dict[int, Relay],
                 keep: Optional[int] = None):
        self._pipes = pipes  # file descriptor -> pipe
        self._keep = keep  # at most this many of the last bytes of each pipe
        self._relays = dict(relays)  # file descriptor -> where its output is relayed
        self.buffers: Dict[int, bytearray] = {fd: bytearray() for fd in pipes}
        self.changed = threading.Condition()
        self.done = False
        self._wake_read, self._wake_write = os.pipe()
        for fd in pipes:
            os.set_blocking(fd, False)
        self._thread = threading.Thread(target=self._run, name="wiretape-child-output",
                                        daemon=True)
        self._thread.start()

    def _take(self, fd: int, chunks: int = 1) -> bool:
        """Reads what `fd` holds now, at most `chunks` reads; False at its
        end."""
        for _ in range(chunks):
            try:
                chunk = os.read(fd, _CHUNK)
            except BlockingIOError:
                return True
            except OSError:
                return False
            if not chunk:
                return False
            with self.changed:
                buffer = self.buffers[fd]
                buffer += chunk
                if self._keep is not None and len(buffer) > self._keep:
                    del buffer[:len(buffer) - self._keep]
                self.changed.notify_all()
            relay = self._relays.get(fd)
            if relay is not None:
                try:
                    relay.write(chunk)
                    relay.flush()
                except (OSError, ValueError):
                    del self._relays[fd]  # whoever reads our relay went away
        return True

    def _run(self) -> None:
        poller = select.poll()
        poller.register(self._wake_read, select.POLLIN)
        open_fds = set(self._pipes)
        for fd in open_fds:
            poller.register(fd, select.POLLIN)
        try:
            while open_fds:
                events = poller.poll()
                stopping = any(fd == self._wake_read for fd, _ in events)
                ready = sorted(open_fds) if stopping else \
                    [fd for fd, _ in events if fd in open_fds]
                for fd in ready:
                    # At the stop, what the pipe held; a writer that goes on
                    # (a grandchild of another session) cannot keep us here.
                    if not self._take(fd, _PIPE_CHUNKS if stopping else 1):
                        open_fds.discard(fd)
                        poller.unregister(fd)
                if stopping:
                    break
        finally:
            for pipe in self._pipes.values():
                pipe.close()
            with self.changed:
                self.done = True
                self.changed.notify_all()

    def stop(self) -> None:
        """Takes what the pipes hold now and stops reading."""
        if self._wake_write < 0:
            return
        os.write(self._wake_write, b"x")  # the thread may have ended: a pipe holds it
        self._thread.join()
        os.close(self._wake_write)
        os.close(self._wake_read)
        self._wake_write = self._wake_read = -1


class Child:
    """A command running in a process group of its own.

    ``capture``: stdout and stderr are read into :attr:`stdout` (and
    :attr:`stderr`, with ``separate_stderr``), and written to ``relay`` as
    they arrive when one is given (stderr captured apart to
    ``relay_stderr``, when given); with ``keep``, only the last ``keep``
    bytes of each are kept (a long-running command that is relayed); otherwise
    they are passed through (the
    child writes where this process writes). ``stdin`` as subprocess takes
    it (default: nothing to read). ``preexec_fn`` runs in the child after it
    has left this session. The child ends (SIGKILL) should this process end
    before it (see :func:`_ending_with_parent`: start it from a thread that
    outlives it). A command that cannot be started raises
    :class:`CommandNotStarted`.
    """

    def __init__(self, argv: Sequence[str], *, capture: bool = True,
                 separate_stderr: bool = False, relay: Optional[Relay] = None,
                 relay_stderr: Optional[Relay] = None, keep: Optional[int] = None,
                 text: bool = False, stdin=subprocess.DEVNULL,
                 env: Optional[Mapping[str, str]] = None, cwd=None,
                 preexec_fn: Optional[Callable[[], None]] = None,
                 grace: float = GRACE_S):
        self.argv: List[str] = [os.fspath(arg) for arg in argv]
        self.grace = grace
        self._text = text
        self._ended = False
        self._timed_out = False
        try:
            self.process = subprocess.Popen(
                self.argv, stdin=stdin, env=None if env is None else dict(env), cwd=cwd,
                stdout=subprocess.PIPE if capture else None,
                stderr=(subprocess.PIPE if separate_stderr else subprocess.STDOUT)
                if capture else None,
                start_new_session=True, preexec_fn=_ending_with_parent(preexec_fn))
        except FileNotFoundError:
            raise CommandNotStarted(f"{self.argv[0]}: command not found",
                                    EXIT_COMMAND_NOT_FOUND) from None
        except PermissionError:
            raise CommandNotStarted(f"{self.argv[0]}: permission denied (not executable)",
                                    EXIT_COMMAND_NOT_EXECUTABLE) from None
        except OSError as error:
            raise CommandNotStarted(f"{self.argv[0]}: cannot be run: {error.strerror or error}",
                                    EXIT_COMMAND_NOT_EXECUTABLE) from None
        self.pid = self.process.pid
        self._exit_event = _ExitEvent(self.process)
        self._reader: Optional[_Reader] = None
        self._stdout_fd: Optional[int] = None
        self._stderr_fd: Optional[int] = None
        if capture:
            assert self.process.stdout is not None
            pipes = {self.process.stdout.fileno(): self.process.stdout}
            self._stdout_fd = self.process.stdout.fileno()
            if separate_stderr:
                assert self.process.stderr is not None
                pipes[self.process.stderr.fileno()] = self.process.stderr
                self._stderr_fd = self.process.stderr.fileno()
            relays: Dict[int, Relay] = {}
            if relay is not None:
                relays[self._stdout_fd] = relay
            stderr_relay = relay_stderr if relay_stderr is not None else relay
            if self._stderr_fd is not None and stderr_relay is not None:
                relays[self._stderr_fd] = stderr_relay
            self._reader = _Reader(pipes, relays, keep)

    @property
    def name(self) -> str:
        """The command's program name, for messages."""
        return os.path.basename(self.argv[0]) or self.argv[0]

    # -- state -------------------------------------------------------------

    def poll(self) -> Optional[int]:
        """The direct child's return code once it has exited, else None."""
        code = self.process.poll()
        if code is not None:
            self._exit_event.close()
        return code

    @property
    def running(self) -> bool:
        return self.poll() is None

    @property
    def returncode(self) -> Optional[int]:
        return self.process.returncode

    @property
    def exit_status(self) -> Optional[int]:
        """The exit status as a shell reports it (128+N for signal N), or
        None while the child runs."""
        code = self.poll()
        if code is None:
            return None
        return 128 - code if code < 0 else code

    def wait(self, timeout: Optional[float] = None,
             wake_fd: Optional[int] = None) -> Optional[int]:
        """Waits up to `timeout` seconds (None: for ever) for the direct
        child to exit, or, when `wake_fd` is given, for that descriptor to
        become readable (another event to wait for together with the exit);
        its return code, or None if it still runs. Its group is left alone
        (see :meth:`end`)."""
        if self._exit_event.wait(timeout, wake_fd):
            self.process.wait()
        return self.poll()

    # -- output ------------------------------------------------------------

    def _buffer(self, fd: Optional[int]) -> Output:
        if self._reader is None or fd is None:
            return "" if self._text else b""
        with self._reader.changed:
            data = bytes(self._reader.buffers[fd])
        return data.decode("utf-8", "replace") if self._text else data

    @property
    def stdout(self) -> Output:
        """The output captured so far (stderr included unless apart)."""
        return self._buffer(self._stdout_fd)

    @property
    def stderr(self) -> Output:
        """stderr captured so far, when captured apart."""
        return self._buffer(self._stderr_fd)

    def wait_for_output(self, found: Callable[[Output], bool], timeout: float) -> bool:
        """Waits until ``found(stdout so far)`` holds (True), or the output
        has ended or `timeout` seconds have passed (False)."""
        if self._reader is None:
            raise ValueError("the output of this child is not captured")
        end = time.monotonic() + timeout
        with self._reader.changed:
            while True:
                if found(self.stdout):
                    return True
                left = end - time.monotonic()
                if self._reader.done or left <= 0:
                    return False
                self._reader.changed.wait(left)

    # -- ending --------------------------------------------------------------

    def _signal_group(self, signum: int) -> bool:
        """Sends `signum` to the child's group; False when it has none left."""
        try:
            os.killpg(self.pid, signum)
            return True
        except ProcessLookupError:
            return False
        except PermissionError:  # a member changed its credentials (setuid)
            return True

    def _group_ends_by(self, deadline: float) -> bool:
        """Waits until the group has no members left (True) or `deadline`."""
        while self._signal_group(0):
            if time.monotonic() >= deadline:
                return False
            time.sleep(_GROUP_POLL_S)
        return True

    def end(self, grace: Optional[float] = None) -> int:
        """Ends the child and everything in its group: SIGTERM to the group,
        SIGKILL to the group if any of it is left after `grace` seconds
        (default: the child's). Then stops reading its output and returns
        the direct child's return code. Ending an ended child only reaps."""
        if not self._ended:
            self._ended = True
            grace = self.grace if grace is None else grace
            deadline = time.monotonic() + grace
            # The group's id (the direct child's pid) is not handed out again
            # while any member of the group, a zombie included, is left.
            if self._signal_group(signal.SIGTERM):
                self._exit_event.wait(max(deadline - time.monotonic(), 0))
                if self.process.poll() is None or not self._group_ends_by(deadline):
                    self._signal_group(signal.SIGKILL)
            self.process.wait()
            self._exit_event.close()
            if self._reader is not None:
                self._reader.stop()
        return self.process.wait()

    def run(self, timeout: Optional[float] = None,
            stop: Optional[threading.Event] = None) -> Outcome:
        """Waits for the direct child to exit, ending it at `timeout`
        seconds (then ``timed_out``) or once `stop` is set (then
        ``stopped``: another thread was interrupted); then ends what is left
        of its group and returns the :class:`Outcome`."""
        stopped = False
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            left = None if deadline is None else max(deadline - time.monotonic(), 0.0)
            # A threading.Event has no descriptor to poll with the exit:
            # it is looked at this often.
            step = left if stop is None else min(_STOP_POLL_S, _STOP_POLL_S if left is None
                                                 else left)
            if self.wait(step) is not None:
                break
            if stop is not None and stop.is_set():
                stopped = True
                break
            if left is not None and step is not None and left <= step:
                self._timed_out = True
                break
        returncode = self.end()
        return Outcome(tuple(self.argv), returncode, self._timed_out, self.stdout, self.stderr,
                       stopped)

    def __enter__(self) -> "Child":
        return self

    def __exit__(self, *exc) -> None:
        self.end()


class _ExitEvent:
    """The direct child's exit as an event to wait on without reaping it: a
    pidfd where the system has them, else subprocess's own wait."""

    def __init__(self, process: subprocess.Popen):
        self._process = process
        self._pidfd: Optional[int] = None
        pidfd_open = getattr(os, "pidfd_open", None)
        if pidfd_open is not None:
            try:
                self._pidfd = pidfd_open(process.pid)
            except OSError:  # an older kernel
                self._pidfd = None

    def wait(self, timeout: Optional[float], wake_fd: Optional[int] = None) -> bool:
        """True once the child has exited (it may be unreaped), False at
        `timeout` or as soon as `wake_fd` (when given) is readable."""
        if self._process.returncode is not None:
            return True
        if self._pidfd is None and wake_fd is None:
            try:
                self._process.wait(timeout)
                return True
            except subprocess.TimeoutExpired:
                return False
        poller = select.poll()
        if self._pidfd is not None:
            poller.register(self._pidfd, select.POLLIN)
        if wake_fd is not None:
            poller.register(wake_fd, select.POLLIN)
        end = None if timeout is None else time.monotonic() + timeout
        while True:
            left = None if end is None else max(end - time.monotonic(), 0)
            step = left
            if self._pidfd is None:  # no descriptor for the exit: looked at this often
                step = _NO_PIDFD_POLL_S if left is None else min(left, _NO_PIDFD_POLL_S)
            ready = {fd for fd, _ in poller.poll(None if step is None else step * 1000)}
            if self._pidfd is not None and self._pidfd in ready:
                return True
            if self._pidfd is None and self._process.poll() is not None:
                return True
            if wake_fd is not None and wake_fd in ready:
                return False
            if left is not None and left <= 0:
                return False

    def close(self) -> None:
        if self._pidfd is not None:
            os.close(self._pidfd)
            self._pidfd = None
