"""wiretape's C++ core"""

from collections.abc import Iterable, Mapping, Sequence
import datetime
import os

from wiretape import (
    OptionError as OptionError,
    PortClosed as PortClosed,
    PortError as PortError,
    ReplayMismatch as ReplayMismatch,
    SessionError as SessionError
)


class Port:
    """
    A connection to a device: serial line, TCP, UDP,
    pseudo-terminal, in-memory loopback, or a replayed recording. Made by open_port().

    Reads follow wiretape's (C++) semantics: read(size) returns what is there,
    at least one byte and at most size, or b"" when the timeout expires; the
    compound reads (read_exactly, read_until, read_line, skip_until) return what
    they have when the timeout expires and never raise on a timeout.

    Every `timeout` argument is in seconds (a float, or a datetime.timedelta):
    None blocks, 0 polls; omitted means
    the port's own `timeout`. Ctrl-C interrupts a blocked read. One reader and
    one writer may run at once on different threads; close() from another thread
    wakes a blocked read, which then raises PortClosed.
    """

    def read(self, size: int = 1, timeout: float | datetime.timedelta | None = ...) -> bytes:
        """
        What is there, at least one byte and at most `size`; b"" when the timeout expires.
        """

    def read_exactly(self, count: int, timeout: float | datetime.timedelta | None = ...) -> bytes:
        """Exactly `count` bytes, or what came before the timeout expired."""

    def read_until(self, expected: bytes = b"\n", size: int | None = None, timeout: float | datetime.timedelta | None = ...) -> bytes:
        """
        Up to and including `expected`, or `size` bytes, or what came before the timeout expired. Nothing past `expected` is consumed.
        """

    def read_line(self, size: int | None = None, timeout: float | datetime.timedelta | None = ...) -> bytes:
        """Up to and including b"\\n" (see read_until)."""

    def skip(self, count: int, timeout: float | datetime.timedelta | None = ...) -> int:
        """Discards up to `count` bytes; returns how many were discarded."""

    def skip_until(self, delimiter: bytes, timeout: float | datetime.timedelta | None = ...) -> bool:
        """Discards through `delimiter`; False if the timeout expired first."""

    def available(self) -> int:
        """Bytes that a read would return at once."""

    @property
    def in_waiting(self) -> int:
        """Bytes that a read would return at once (pyserial's name)."""

    def wait_readable(self, timeout: float | datetime.timedelta | None = ...) -> bool:
        """
        True once a read would not block (data, or the device is gone); False when the timeout expired.
        """

    def write(self, data: bytes) -> int:
        """
        Writes what the device accepts, at least one byte, or 0 when the port's timeout expires; returns the count written.
        """

    def write_all(self, data: bytes) -> int:
        """
        Writes everything; returns less than len(data) only when the port's timeout expired.
        """

    def flush_input(self) -> None:
        """Drops what was received and not yet read."""

    def flush_output(self) -> None:
        """Drops what was written and not yet sent."""

    def drain(self) -> None:
        """Waits until written data has left."""

    @property
    def timeout(self) -> float | None:
        """
        The port's timeout in seconds (or a datetime.timedelta): None blocks, 0 polls.
        """

    @timeout.setter
    def timeout(self, value: float | datetime.timedelta | None, /) -> None: ...

    def close(self) -> None:
        """Closes the port; a read blocked in another thread raises PortClosed."""

    @property
    def is_open(self) -> bool: ...

    @property
    def description(self) -> str:
        """Human-readable, e.g. 'serial /dev/ttyUSB0 @ 115200 8N1'."""

    @property
    def type(self) -> str:
        """The port's type as in the option string: 'serial', 'tcp', ..."""

    @property
    def left_unused(self) -> str:
        """
        A replay, once closed: what its client left of the recording, as unused= words it ('' when it used it all), whatever unused= says; '' before close() and for other ports.
        """

    @property
    def access(self) -> str:
        """'readwrite', 'readonly' or 'writeonly'."""

    def fileno(self) -> int:
        """
        A file descriptor that polls readable exactly when available() > 0 (for select, selectors, asyncio). Raises PortClosed after close().
        """

    def native_handle(self) -> int:
        """As fileno(), but -1 after close()."""

    def set_baud(self, baud: int) -> None: ...

    @property
    def baud(self) -> int:
        """The line rate; PortError (ENOTSUP) on a port without one."""

    @baud.setter
    def baud(self, arg: int, /) -> None: ...

    def configure(self, *, baud: int | None = None, databits: int | None = None, stopbits: int | None = None, parity: str | None = None, flow: str | None = None) -> None:
        """Changes the given line settings, keeping the others."""

    def serial_settings(self) -> dict:
        """The line settings: {'baud', 'databits', 'stopbits', 'parity', 'flow'}."""

    def set_dtr(self, level: bool) -> None: ...

    def set_rts(self, level: bool) -> None: ...

    @property
    def dtr(self) -> bool:
        """
        DTR: the level last set (True before any: the OS raises it at open); settable.
        """

    @dtr.setter
    def dtr(self, arg: bool, /) -> None: ...

    @property
    def rts(self) -> bool:
        """
        RTS: the level last set (True before any: the OS raises it at open); settable.
        """

    @rts.setter
    def rts(self, arg: bool, /) -> None: ...

    @property
    def cts(self) -> bool:
        """CTS as the device drives it."""

    @property
    def dsr(self) -> bool:
        """DSR as the device drives it."""

    @property
    def ri(self) -> bool:
        """RI (ring indicator) as the device drives it."""

    @property
    def cd(self) -> bool:
        """CD (carrier detect) as the device drives it."""

    def send_break(self, duration: float = 0.25) -> None:
        """Holds the line in break for `duration` seconds."""

    def __enter__(self) -> Port: ...

    def __exit__(self, arg0: object | None, arg1: object | None, arg2: object | None, /) -> None: ...

    def __repr__(self) -> str: ...

def open_port(options: str) -> Port:
    """
    Opens the port an option string describes, e.g. 'type=serial,device=/dev/ttyUSB0,baud=115200'. Raises OptionError for a bad string, PortError when the device cannot be opened.
    """

def check_replay_options(options: str) -> None:
    """
    Checks a replay's option string ('type=replay,file=...,timing=none') as open_port() would, opening nothing, not even the session file. Raises OptionError naming the key.
    """

def replay_speed_applies(options: str) -> bool:
    """
    Whether a replay of these keys has something for speed= to scale: a clock (timing=session or causal) or an injected wait (delay, stall, trickle, reconnect). open_port() refuses speed= where it has not.
    """

def quote_option_value(value: str) -> str:
    """
    A value as it is written in an option string: as is, or in double quotes with \\" and \\\\ escaped when it is empty or holds a separator, '=', '"' or '\\\\'.
    """

def option_value(port_type: str, name: str, text: str) -> bool | int | float | str | None:
    """
    `text` read as a port of `port_type` reads its key `name`, checked against the key table (type, range, choices): a bool, int, float (seconds: None for forever) or str. OptionError naming the key for a bad value or a key that is not one of the type's.
    """

def option_string(pairs: Iterable[tuple[str, str | int | float | bool | os.PathLike[str]]]) -> str:
    """
    'key=value,...' of (key, value) pairs in order: values quoted as quote_option_value() quotes them, numbers and booleans written by the one rule of the C++ option strings (2.0 as 2, 0.25, 1e-06; True as true), a path as its text. parse_options() gives the pairs back (as text). Raises OptionError naming the key for a key that is not one, a key given twice, a NUL byte or a number that is not finite; TypeError for another type of value.
    """

class OptionKey:
    """
    One row of the key table: a key of one or more port types (docs/options.md).
    """

    @property
    def name(self) -> str:
        """the key; with prefix, the prefix ('meta_' for meta_KEY)"""

    @property
    def port_types(self) -> list[str]:
        """the port types the key applies to"""

    @property
    def type(self) -> str:
        """boolean, integer, number, seconds, choice, text or path"""

    @property
    def choices(self) -> list[str]:
        """the valid values of a choice"""

    @property
    def default(self) -> str | None:
        """
        the value when the key is not given, as written in an option string; None when it has none
        """

    @property
    def required(self) -> bool: ...

    @property
    def prefix(self) -> bool:
        """the key stands for every key starting with name (meta_KEY)"""

    @property
    def minimum(self) -> object:
        """the smallest valid integer, number or seconds; None for other types"""

    @property
    def maximum(self) -> object:
        """the largest valid integer, number or seconds; None for other types"""

    @property
    def alias_of(self) -> str:
        """the key this is flexiport's name of; '' when none"""

    @property
    def flag(self) -> str:
        """the wiretape CLI flag that mirrors the key; '' when none"""

    @property
    def help(self) -> str: ...

    def applies_to(self, port_type: str) -> bool: ...

    def __repr__(self) -> str: ...

def option_keys() -> list[OptionKey]:
    """Every key of every port type (the key table), common keys first."""

def port_types() -> list[str]:
    """
    The port types an option string can open (type= after flexiport's spellings).
    """

def parse_options(text: str) -> list[tuple[str, str]]:
    """
    An option string's (key, value) pairs in order, values unquoted, a bare key as '1'. Raises OptionError as open_port() would for bad syntax (a key given twice included).
    """

def suggest_key(name: str, port_type: str) -> str | None:
    """The key of port_type nearest to the unknown name (a typo), or None."""

def device_options(device: str) -> str:
    """
    The option string a device setting stands for: a bare path (no '=') means type=serial,device=PATH; an option string is returned as given. Raises OptionError when the setting is empty.
    """

class Channel:
    """
    One port of a session of several ports (format 1.2, docs/session-format.md, "channels"): its id (what its records carry), name and what the header says of a port. Channel(**members) with the members to_dict() names.
    """

    def __init__(self, **members: object) -> None: ...

    @property
    def id(self) -> int:
        """what the channel's records carry in Record.channel"""

    @id.setter
    def id(self, arg: int, /) -> None: ...

    @property
    def name(self) -> str:
        """
        the channel's name ('' only for the one channel of a session without named channels)
        """

    @name.setter
    def name(self, arg: str, /) -> None: ...

    @property
    def port_options(self) -> str: ...

    @port_options.setter
    def port_options(self, arg: str, /) -> None: ...

    @property
    def port_type(self) -> str: ...

    @port_type.setter
    def port_type(self, arg: str, /) -> None: ...

    @property
    def capture(self) -> str:
        """'client' or 'wire'"""

    @capture.setter
    def capture(self, arg: str, /) -> None: ...

    @property
    def device_address(self) -> str: ...

    @device_address.setter
    def device_address(self, arg: str, /) -> None: ...

    @property
    def device_identity(self) -> dict:
        """the serial device's identity, as SessionHeader.device_identity"""

    @device_identity.setter
    def device_identity(self, arg: dict, /) -> None: ...

    def to_dict(self) -> dict:
        """the members as a dict"""

    def __eq__(self, arg: Channel, /) -> bool: ...

    def __copy__(self) -> Channel: ...

    def __deepcopy__(self, memo: object) -> Channel: ...

    def __repr__(self) -> str: ...

def channel_name_problem(name: str) -> str | None:
    """
    Why NAME cannot name a channel (not an identifier of at most 64 characters of letters, digits, '_' and '-'; or an option key), or None when it can.
    """

class SessionHeader:
    """
    A session file's header (docs/session-format.md): what was recorded, where, when and how; the one type for reading (SessionReader.header) and writing (SessionWriter). SessionHeader(**members): members by their attribute names, checked (an unknown member or a wrong type raises); the others keep their defaults (start_utc and host empty: not known). SessionHeader.from_dict(d) takes the file's header JSON as a dict, as to_dict() gives it.
    """

    def __init__(self, **members: object) -> None: ...

    @staticmethod
    def from_dict(layout: dict) -> SessionHeader:
        """
        A header from the file's header JSON as a dict (as to_dict() gives it, json.loads of a header's to_json()), checked: a member the layout lacks or of the wrong type raises. Its version is SESSION_VERSION, what a writer writes.
        """

    @staticmethod
    def starting_now() -> SessionHeader:
        """
        A header for a session that starts now on this machine: start_utc now, host this machine's name (what recorders write).
        """

    @property
    def version_major(self) -> int:
        """
        the file's format version, as read (0.0 for a flexiport log); writers write their own
        """

    @version_major.setter
    def version_major(self, arg: int, /) -> None: ...

    @property
    def version_minor(self) -> int: ...

    @version_minor.setter
    def version_minor(self, arg: int, /) -> None: ...

    @property
    def port_options(self) -> str:
        """the option string the port was opened with"""

    @port_options.setter
    def port_options(self, arg: str, /) -> None: ...

    @property
    def port_type(self) -> str:
        """serial, tcp, udp, pty, loopback, ..."""

    @port_type.setter
    def port_type(self, arg: str, /) -> None: ...

    @property
    def start_utc(self) -> str:
        """when the device was opened, ISO 8601 UTC ('' when not known)"""

    @start_utc.setter
    def start_utc(self, arg: str, /) -> None: ...

    @property
    def wiretape_version(self) -> str:
        """the version of wiretape that wrote the file"""

    @wiretape_version.setter
    def wiretape_version(self, arg: str, /) -> None: ...

    @property
    def host(self) -> str:
        """the recording machine's name ('' when not known)"""

    @host.setter
    def host(self, arg: str, /) -> None: ...

    @property
    def capture(self) -> str:
        """'client' (library recording) or 'wire' (proxy recording)"""

    @capture.setter
    def capture(self, arg: str, /) -> None: ...

    @property
    def source_format(self) -> str:
        """
        'wiretape' (recorded by wiretape) or the format it was imported from: 'flexiport', 'pcap', 'reserial', 'umockdev', ...
        """

    @source_format.setter
    def source_format(self, arg: str, /) -> None: ...

    @property
    def source_files(self) -> list[str]:
        """an imported session's original file names"""

    @source_files.setter
    def source_files(self, arg: Sequence[str], /) -> None: ...

    @property
    def source_details(self) -> dict[str, str]:
        """what else the import noted (the stream, the test, the logs' formats)"""

    @source_details.setter
    def source_details(self, arg: Mapping[str, str], /) -> None: ...

    @property
    def device_address(self) -> str:
        """host:port of a network device, when known"""

    @device_address.setter
    def device_address(self, arg: str, /) -> None: ...

    @property
    def edits(self) -> list[str]:
        """what wiretape edit changed, in order"""

    @edits.setter
    def edits(self, arg: Sequence[str], /) -> None: ...

    @property
    def metadata(self) -> dict[str, str]:
        """the free user metadata (--meta)"""

    @metadata.setter
    def metadata(self, arg: Mapping[str, str], /) -> None: ...

    @property
    def device_identity(self) -> dict:
        """
        the serial device's identity (format 1.2; docs/session-format.md): a dict of kernel_name, subsystem, vendor_id, product_id, serial_number, manufacturer, product, interface, location, by_id ('' when not known); {} when the recording has none (a pty, a network device)
        """

    @device_identity.setter
    def device_identity(self, arg: dict, /) -> None: ...

    @property
    def attached(self, /) -> dict[str, object] | None:
        """
        a recording made by attaching to a running program (record --attach): a dict of pid, command, utc, descriptors, device and warnings; None otherwise
        """

    @attached.setter
    def attached(self, value: dict[str, object] | None, /) -> None: ...

    def clear_device_serial(self) -> None:
        """
        Clears the device identity's serial number and its part of the by-id name (what edit --redact does).
        """

    @property
    def channels(self, /) -> list[Channel]:
        """
        format 1.2: the session's ports (Channel objects, or dicts of their members when set), ids 0..n-1 in order; [] for a session of one unnamed port, which the port members describe. With channels, the port members are channel 0's.
        """

    @channels.setter
    def channels(self, value: list[Channel] | list[dict[str, object]], /) -> None: ...

    def channel_list(self) -> list[Channel]:
        """
        Every channel: channels, or the one unnamed channel 0 the port members describe.
        """

    def find_channel(self, name: str) -> Channel | None:
        """The channel named NAME, or None."""

    @property
    def metadata_json(self) -> str:
        """the header's JSON as stored (read) or written; to_json() makes it anew"""

    @metadata_json.setter
    def metadata_json(self, arg: str, /) -> None: ...

    def to_json(self) -> str:
        """
        The header's JSON object as a writer writes it. Raises OptionError naming the member a reader would refuse (not UTF-8, a start_utc out of range).
        """

    def to_dict(self) -> dict:
        """
        The header as the file holds it: json.loads(to_json()), the one layout commands print and write (docs/session-format.md, "Metadata"; no version, which is the file's, not the header JSON's). Raises OptionError as to_json() does.
        """

    def __copy__(self) -> SessionHeader: ...

    def __deepcopy__(self, memo: object) -> SessionHeader: ...

    def __eq__(self, arg: SessionHeader, /) -> bool: ...

    def __repr__(self) -> str: ...

def read_device_identity(device: str, sysfs_root: str = '/sys', dev_root: str = '/dev') -> dict:
    """
    The identity of the serial device at `device` as record stores it (a dict as SessionHeader.device_identity; {} for a pty or a path with no device in sysfs).
    """

def present_device_identity(identity: dict, root: str, device_path: str) -> tuple:
    """
    Writes under `root` the sysfs folders that present `identity` (as SessionHeader.device_identity) to a command that opens `device_path`: returns (tty_name, folder, by_id), the kernel name presented (device_path's own name when it is directly under /dev, else the recorded one), the folder that stands for /sys/class/tty/TTY_NAME (tty_name and folder '' when no name can be presented) and the by-id name to redirect ('' when none).
    """

SESSION_MAGIC: bytes = ...

SESSION_VERSION: tuple = (1, 3)

FILE_HEADER_FIXED_SIZE: int = 16

MAX_HEADER_JSON: int = 16777216

RECORD_HEADER_SIZE: int = 16

CRC_SIZE: int = 4

FILE_HEADER_OVERHEAD: int = 20

RECORD_OVERHEAD: int = 20

MAX_RECORD_T_NS: int = 4294967295999999999

RECORD_KINDS: tuple = ...

def start_utc_problem(start_utc: str) -> str | None:
    """
    Why a session header's start_utc would be refused (not YYYY-MM-DDTHH:MM:SS[.frac]Z, out of range), or None.
    """

def record_content_problem(kind: object, t_ns: int, data: bytes) -> str | None:
    """
    Why a reader would stop at this record although its CRC matches (a time past MAX_RECORD_T_NS, an event payload that is not a JSON object within the limits), or None: the rule the writer and every reader apply.
    """

def flexiport_prefix(path: object) -> str | None:
    """
    The 'name.log' prefix PATH stands for when it is a flexiport log ('name.log', 'name.logr' or 'name.logw' with the pair on disk), else None.
    """

class Record:
    """One record of a session: t_ns, kind, data."""

    def __init__(self, t_ns: int, kind: object, data: bytes = ..., channel: int = 0) -> None: ...

    @property
    def t_ns(self) -> int:
        """nanoseconds since the device was opened"""

    @property
    def kind(self) -> str:
        """'rx' (device to host), 'tx' (host to device), or an event name"""

    @property
    def kind_code(self) -> int: ...

    @property
    def channel(self) -> int:
        """
        the id of the record's channel (SessionHeader.channels); 0 in a session of one port
        """

    @property
    def data(self) -> bytes:
        """the bytes (rx, tx) or the event's JSON object as bytes"""

    def __eq__(self, arg: Record, /) -> bool: ...

    def __repr__(self) -> str: ...

def event_payload(kind: object, fields: dict) -> bytes:
    """
    The JSON payload of an event of KIND ('settings', 'fault', ...) with the members FIELDS (bool, int or str), as bytes in the record-kind table's order. Raises ValueError naming the kind and the member: not in the table, wrong type, missing when required.
    """

class SessionReader:
    """
    Reads a .wtape file or a flexiport log (name.log) record by record, with memory independent of its size; a pipe or FIFO is read once, as a stream, waiting for its writer (Ctrl-C ends the wait). Iterating yields Record objects; at a damaged record iteration ends and .damage says where.
    """

    def __init__(self, path: object, channel: int | None = None) -> None:
        """
        CHANNEL: only that channel's records (its id); None: every channel's, in recorded order (Record.channel says which).
        """

    def __iter__(self) -> SessionReader: ...

    def __next__(self) -> Record: ...

    @property
    def header(self) -> SessionHeader:
        """the session's header (a SessionHeader)"""

    @property
    def damage(self, /) -> SessionError | None:
        """
        None, or a SessionError (not raised) with .offset and .message: where reading stopped and why
        """

    @property
    def unfinished(self, /) -> SessionError | None:
        """
        None, or (not damage: a warning) a SessionError with .offset and .message when reading stopped at the end of a file still being written: every record before it was read
        """

    def rewind(self) -> None:
        """back to the first record"""

    @property
    def path(self) -> str: ...

    def close(self) -> None: ...

    def __enter__(self) -> SessionReader: ...

    def __exit__(self, *args) -> None: ...

class SessionWriter:
    """
    Writes a new .wtape file (truncating PATH). Buffered; buffered records reach the OS at most flush_ms after they were written. A full disk or file-size limit raises PortError; what was written before stays readable.
    """

    def __init__(self, path: str | os.PathLike[str] | bytes, header: SessionHeader | None = None, *, flush_ms: int = 100, fsync: bool = False, header_room: int = 0, compress: str = 'none', **members: object) -> None:
        """
        HEADER (default: SessionHeader.starting_now()) with MEMBERS (keyword arguments named as SessionHeader's members) set on it is what the file's header says. header_room: spare header bytes (spaces) kept so that add_channel() can rewrite the header in place; 0 writes it exactly as long as its JSON.
        """

    @property
    def header(self) -> SessionHeader:
        """the header as written (this library's format version, metadata_json)"""

    def write(self, kind: object, t_ns: int, data: bytes = ..., channel: int = 0) -> None:
        """
        Appends a record: kind is a name ('rx', 'tx', 'open', ...) or a code. channel is reserved for sessions of several ports: 0, the session's port.
        """

    def add_channel(self, channel: Channel) -> int:
        """
        Adds CHANNEL (its id is ignored) to the header's channels, rewriting the header in place within the header_room reserved; returns its id. Raises OptionError naming 'name' (a bad or taken name), SessionError when the header has no room left.
        """

    def flush(self) -> None: ...

    def close(self) -> None: ...

    @property
    def path(self) -> str: ...

    def __enter__(self) -> SessionWriter: ...

    def __exit__(self, *args) -> None: ...

class Recorder:
    """
    Records several ports into one session file, one channel each, on one clock (time 0: the first channel's open). Its ports keep the file open; it is closed at close() (or leaving a with block), or when the recorder and its ports are gone.
    """

    def __init__(self, path: str | os.PathLike[str] | bytes, header: SessionHeader | None = None, *, flush_ms: int = 100, fsync: bool = False, header_room: int = 32768, compress: str = 'none', **members: object) -> None:
        """
        Creates the session file. HEADER (default: SessionHeader.starting_now()) with MEMBERS set on it is its header; each port adds its channel to it. header_room: the bytes kept for the channels' entries.
        """

    def open_port(self, options: str) -> Port:
        """
        Opens the port OPTIONS describe (as open_port() does) recording into a new channel named by its name=NAME: 'name=gps,type=serial,device=/dev/ttyUSB0'. Raises OptionError naming the key (a missing, bad or taken name; log=).
        """

    def close(self) -> None:
        """Flushes and closes the file; its ports go on, unrecorded."""

    def now_ns(self) -> int:
        """The recorder's clock: ns since its first channel's open (0 before)."""

    @property
    def path(self) -> str: ...

    @property
    def header(self) -> SessionHeader:
        """the header as written so far"""

    def __enter__(self) -> Recorder: ...

    def __exit__(self, *args) -> None: ...

def export_flexiport(source: object, prefix: object, format: str = 'new') -> int:
    """
    Writes a session (.wtape or flexiport) as flexiport's logs PREFIX + 'r' (reads) and PREFIX + 'w' (writes), in its new format (from 2008-07) or the old one; events are dropped. A FIFO or a device there (through a symbolic link too) is written through. Returns the number of records written.
    """

MAX_CASSETTE_NAME_LENGTH: int = 100

def safe_file_name(name: str) -> str:
    """
    NAME as a cassette's file name: runs of characters but ASCII letters, digits and ._-=+ become one _, _ and . are trimmed; a name that changed or is longer than MAX_CASSETTE_NAME_LENGTH is cut to fit and ends with - and 12 hex digits of its SHA-1, so that distinct tests never share a cassette.
    """

def cassette_file_name(test_name_parts: Sequence[str]) -> str:
    """
    A test's cassette file name from its name's parts, outermost first (suite or class, then the test with its parameters): joined by '.', made safe, + '.wtape'.
    """

def cassette_directory(source_file: object, directory: str = '') -> str:
    """
    The folder of SOURCE_FILE's cassettes: <its dir>/recordings/<its stem>, or <DIRECTORY>/<its stem> when a directory is given.
    """

def recorded_device(port_options: str) -> str:
    """
    The device setting a cassette was recorded from, for the command that records it again: PORT_OPTIONS as its header keeps them without log=, name= and the test helpers' meta_gtest= and meta_pytest_node=; '' when none are kept.
    """

def publish_recording(recording: object, cassette: object) -> None:
    """
    Moves a finished recording to CASSETTE, its header naming the cassette (log=<its file name>) instead of the temporary file RECORDING; a damaged recording, or one naming no such file, is moved as it is.
    """

def crc32c(data: bytes, crc: int = 0) -> int:
    """The CRC32C (Castagnoli) of data, continuing from crc."""

class BridgeStats:
    """A bridge's counters so far (read-only)."""

    @property
    def bytes_to_device(self) -> int: ...

    @property
    def bytes_from_device(self) -> int: ...

    @property
    def bytes_dropped(self) -> int: ...

    @property
    def clients_accepted(self) -> int: ...

    @property
    def clients_refused(self) -> int: ...

    @property
    def settings_changes(self) -> int: ...

    @property
    def device_losses(self) -> int: ...

    @property
    def device_reopens(self) -> int: ...

    @property
    def records_written(self) -> int: ...

    @property
    def datagrams_dropped(self) -> int: ...

    @property
    def datagrams_from_others(self) -> int: ...

    @property
    def datagrams_refused(self) -> int: ...

    def items(self) -> list[tuple[str, int]]:
        """(name, count) pairs, in declaration order."""

    def __repr__(self) -> str: ...

class BridgeResult:
    """How a bridge ended (or that it is running), read-only."""

    @property
    def outcome(self) -> str:
        """running, stopped, finished, device_closed, mismatch or failed."""

    @property
    def ok(self) -> bool:
        """False for a mismatch or a failure."""

    @property
    def message(self) -> str:
        """The mismatch report, the error, or why the device closed."""

    @property
    def stats(self) -> BridgeStats: ...

    @property
    def nothing_served(self) -> str:
        """
        Why a replay with rx served none of it to any client (no client connected, nothing matched, the greeting was lost); '' otherwise.
        """

    @property
    def ended_by_fault(self) -> bool:
        """
        True when an injected fault (disconnect) lost the replay's device and that ended the bridge.
        """

    def __repr__(self) -> str: ...

class Bridge:
    """
    Forwards bytes between a device port and a pty, TCP clients or UDP clients, optionally recording them (see wiretape.bridge).
    """

    def __init__(self, device: str, *, client_side: str = 'pty', pty_link: str = '', pty_mode: int = 432, pty_group: str = '', listen_host: str = '127.0.0.1', listen_port: int = 0, listen_backlog: int = 4096, udp_peer_host: str = '', udp_peer_port: int = 0, protocol: str = 'raw', shared: bool = False, max_monitors: int = 16, output: str = '', metadata: Mapping[str, str] = {}, flush_ms: int = 100, mirror_settings: bool = True, reopen: bool = False, restart: bool = False, duration: object | None = None, buffer_limit: int = 1048576, quiet: bool = False, line_channel: str = '', recorder: Recorder | None = None, channel: str = '', compress: str = 'none') -> None:
        """
        compress: 'zstd' writes `output` in compressed chunks (format 2.0). recorder: a Recorder whose channel named `channel` the bridge records into (capture=wire) instead of opening `output`.
        """

    def start(self) -> None:
        """
        Opens the device, the client side and the session file and starts forwarding.
        """

    def stop(self) -> None:
        """Ends forwarding (thread-safe); the session file is closed complete."""

    def wait(self, timeout: object | None = None) -> bool:
        """
        True once the bridge has ended; False if `timeout` (seconds) expired first.
        """

    @property
    def running(self) -> bool: ...

    def result(self) -> BridgeResult:
        """
        A BridgeResult: outcome (running, stopped, finished, device_closed, mismatch or failed), ok, message and stats.
        """

    def stats(self) -> BridgeStats:
        """A BridgeStats: the counters so far."""

    @property
    def pty_path(self) -> str: ...

    @property
    def listen_address(self) -> str: ...

    @property
    def device_description(self) -> str: ...

    def messages(self) -> list[str]: ...

class AttachSummary:
    """How an attached recording ended (read-only)."""

    @property
    def ended_by(self) -> str:
        """
        stopped (stop(), Ctrl-C, a duration), exited (the program ended) or execed (it executed another program, which is not followed)
        """

    @property
    def exit_status(self) -> int | None:
        """the program's exit status as waitpid reports it, when it exited"""

    @property
    def rx_bytes(self) -> int:
        """bytes the program read from the device"""

    @property
    def tx_bytes(self) -> int:
        """bytes the program wrote to the device"""

    @property
    def records(self) -> int:
        """records written"""

    @property
    def warnings(self) -> list[str]:
        """what the recording cannot hold (splice, sendfile, io_uring...)"""

class Attachment:
    """
    Records a running program's session with its device through ptrace into an ordinary session file, and lets it go as it was (docs/recording.md, "Attaching to a running program"). A refusal raises OptionError naming why; nothing is written.
    """

    def __init__(self, pid: int, output: str, path: str = '', fd: int | None = None, meta: Mapping[str, str] = {}, flush_ms: int = 100) -> None:
        """
        Attaches to process PID and records the device (PATH, matched by stat; descriptor FD; or its only tty or socket) into OUTPUT.
        """

    def stop(self) -> None:
        """Ends the recording: every thread is detached (returns once done)."""

    def wait(self, timeout: object | None = None) -> bool:
        """
        True once the recording ended (stop(), the program's exit or exec); False if `timeout` (seconds) expired first.
        """

    @property
    def finished(self) -> bool: ...

    def summary(self) -> AttachSummary:
        """
        An AttachSummary; raises the write failure that ended the recording early.
        """

    @property
    def header(self) -> SessionHeader:
        """The session header as written."""

    @property
    def path(self) -> str:
        """The session file."""

def attach(pid: int, output: str, path: str = '', fd: int | None = None, meta: Mapping[str, str] = {}, flush_ms: int = 100) -> Attachment:
    """
    Attaches to running process PID and records its session with the device (PATH, matched by stat; descriptor FD; or its only tty or socket) into OUTPUT, an ordinary session file; returns the Attachment (stop() it, or wait() for the program's end). A refusal raises OptionError saying why (no such process, permission, kernel.yama.ptrace_scope, already traced, a descriptor or path it does not hold); nothing is written then.
    """

class Profile:
    """
    What wiretape knows of a protocol: how each direction is cut into frames, the bytes of a request compared when matching, and frame names. Get one with profile_from_spec(text).
    """

    @property
    def name(self) -> str: ...

    @property
    def options(self) -> str:
        """
        the replay keys that give this profile: 'profile=NAME', or a declared profile's 'framing=...[,echo=...]' (for a replay's option string and session_exchanges(options=))
        """

    @property
    def summary(self) -> str: ...

    def frames(self, direction: str, data: bytes) -> list:
        """
        The frames of one direction's whole byte stream ('tx' or 'rx'); an incomplete tail is the last frame.
        """

    def framer(self, direction: str) -> Framer:
        """
        A new framer for one direction's stream ('tx' or 'rx'), fed piece by piece.
        """

    def recompute_checksums(self, direction: str, frame: bytes) -> bytes:
        """
        The whole frame with every checksum it carries recomputed over its bytes as they are now (same size); unchanged for a protocol without checksums or a frame that is not this protocol's.
        """

    def match_key(self, request: bytes) -> bytes:
        """The bytes of a request frame that are compared when matching."""

    def frame_name(self, direction: str, frame: bytes) -> str:
        """The frame's short name (for SCIP, the command code)."""

    def describe(self, direction: str, frame: bytes) -> str:
        """The frame's one-line description, as show prints it."""

    def decode_session(self, source: object) -> DecodedSession:
        """
        Decodes a session for show: `source` is a session file's path or an iterable of records. Yields (t_ns, kind, data, description): frames of 'tx' and 'rx' (re-assembled however the recording split them; t_ns is that of the frame's first byte) with their description, once complete; events as they come, with their payload and None. Frames incomplete at the end come last, rx before tx.
        """

    def __repr__(self) -> str: ...

class Framer:
    """
    Cuts one direction's byte stream into frames, however it is split into feed() calls. Get one with Profile.framer(direction).
    """

    def feed(self, data: bytes, t_ns: int = 0) -> list[tuple[bytes, str]]:
        """
        The next bytes of the stream, which arrived at t_ns (for framers that cut by silence): the frames they complete, as (bytes, end) with end one of 'delimited', 'size_limit', 'stream_end', 'broken'.
        """

    def finish(self) -> tuple[bytes, str] | None:
        """The stream has ended: the kept tail as a last (bytes, end), or None."""

    @property
    def pending(self) -> int:
        """How many bytes are kept for the next frame."""

class DecodedSession:
    """The items of a session decoded with a profile (an iterator)."""

    def __iter__(self) -> object: ...

    def __next__(self) -> object: ...

    @property
    def damage(self) -> object:
        """
        None, or a SessionError (not raised) saying where reading a session file stopped
        """

def profile_names() -> list[str]:
    """
    The built-in protocol profiles' names, `scip` first, then registered ones.
    """

def register_callable_profile(name: str, base: str, match_key: object | None = None, fix_response: object | None = None) -> None:
    """
    Registers `name` for profile=: the framing and names of the profile `base`, the match key match_key(request: bytes) -> bytes and the response fix fix_response(recorded_request, actual_request, response) -> bytes, where given (None: the base profile's). The callables are called with the GIL from the thread that serves the client.
    """

def declared_profile(options: str) -> Profile:
    """
    The profile declared by 'framing=...[,ignore=...][,echo=...][,checksum=...]' (docs/replay.md); OptionError naming the key for a bad spec or another key.
    """

def find_profile(name: str) -> Profile:
    """The built-in profile called `name`; OptionError for an unknown name."""

def profile_from_spec(text: str) -> Profile:
    """
    The profile a --profile value stands for, by the replay's rule: text with no '=' is a name ('scip', as profile=scip), else the replay keys profile=, framing=, ignore=, echo=, checksum= ('framing=fixed:10,echo=0:2'). OptionError naming the key for an empty spec, another key, a bad spec or an unknown name.
    """

def hex_ascii(data: bytes) -> str:
    """
    The bytes as hex, then as ASCII with '.' for what is not printable: '56 56 0a  |VV.|'; '(none)' for no bytes.
    """

def escape_bytes(data: bytes, limit: int = 64) -> str:
    """
    The bytes as one line of terminal-safe text: printable ASCII kept, a backslash doubled, \\n \\r \\t and \\xNN for every other byte (ESC included); beyond `limit` bytes, '... (+N bytes)'.
    """

def set_parent_death_signal(signum: int) -> int:
    """
    prctl(PR_SET_PDEATHSIG, signum): this process gets `signum` when the thread that forked it ends (Linux). 0, or the errno of the failure (ENOSYS elsewhere).
    """

class Exchange:
    """
    One exchange of a session: a request of the client's (a run of tx records; with a profile one request frame; in a udp session one datagram) and what the device sent until the next request. Numbered from 0 per file, as replay numbers them in mismatch reports and faults=exchange:N.
    """

    @property
    def index(self) -> int: ...

    @property
    def client_session(self) -> int | None:
        """the client session (0-based) it began in, or None outside any"""

    @property
    def first_record(self) -> int:
        """the index of its first record in the file (every kind counted)"""

    @property
    def end_record(self) -> int:
        """one past the index of its last record"""

    @property
    def request_first_t_ns(self) -> int | None: ...

    @property
    def request_last_t_ns(self) -> int | None: ...

    @property
    def response_first_t_ns(self) -> int | None: ...

    @property
    def response_last_t_ns(self) -> int | None: ...

    @property
    def request_end_t_ns(self) -> int | None:
        """
        when its request was complete: the time of the record holding its last byte (with a profile, the one completing its request frame); None: no request
        """

    @property
    def response_start_t_ns(self) -> int | None:
        """
        the time of its first rx record after request_end_t_ns; None: unanswered
        """

    @property
    def channel_id(self) -> int:
        """the id of the channel it was said on"""

    @property
    def channel_name(self) -> str:
        """the name of that channel ("" in a session without named channels)"""

    @property
    def request_bytes(self) -> int: ...

    @property
    def response_bytes(self) -> int: ...

    @property
    def response_records(self) -> int: ...

    @property
    def request_frames(self) -> list:
        """with a profile: its request frame (a list of one); else empty"""

    @property
    def response_frames(self) -> list:
        """with a profile: the response frames that began in it"""

    def __repr__(self) -> str: ...

class ClientSession:
    """
    A controlling client's connection to a virtual device or proxy: from its client_connect to its client_disconnect (a read-only monitor's connect is none).
    """

    @property
    def index(self) -> int: ...

    @property
    def first_record(self) -> int:
        """the index of its client_connect"""

    @property
    def end_record(self) -> int:
        """
        one past its client_disconnect (or the last record before the next session)
        """

    @property
    def connect_t_ns(self) -> int: ...

    @property
    def disconnect_t_ns(self) -> int | None: ...

def session_exchanges(path: str, profile: str | None = None, match: str | None = None, options: str = '') -> list[Exchange]:
    """
    The exchanges of the session file at `path`, as a replay with profile= and match= (default sequence) numbers them (under match=request a greeting is exchange 0 of its own). `options`: the replay's keys, e.g. a declared profile's 'framing=...,echo=...' (profile and match, when given, override them). OptionError for a bad or non-replay key.
    """

class SessionShape:
    """
    Where faults can fire in what a replay serves (every client session of a proxy recording): its exchanges, rx bytes and the session time of its last rx.
    """

    @property
    def first_exchange(self) -> int:
        """the number of the first exchange served (numbered per file)"""

    @property
    def exchanges(self) -> int:
        """one past the last exchange with rx (0: none)"""

    @property
    def rx_bytes(self) -> int:
        """the rx bytes served"""

    @property
    def last_rx_t_ns(self) -> int:
        """the session time of the last rx record served (0: none)"""

    @property
    def seconds(self) -> float:
        """last_rx_t_ns in seconds: t:S past it never fires"""

    def __repr__(self) -> str: ...

def session_shape(path: str, profile: str | None = None, match: str | None = None, options: str = '', channel: str | None = None) -> SessionShape:
    """
    Where faults can fire in what a replay of the session file at `path` (with profile=, match=, further replay keys `options`, and channel= of a session of several ports) serves, as the replay counts places: every client session of a proxy recording.
    """

class RequestLatency:
    """A request answered, and how long the answer took."""

    @property
    def exchange(self) -> int: ...

    @property
    def request_name(self) -> str:
        """with a profile its request frame's name ('?': unnamed); else ''"""

    @property
    def wait_ns(self) -> int:
        """from the request's end to the first rx record after it"""

    def __repr__(self) -> str: ...

class LatencyMeter:
    """
    The latency pairing of `wiretape stats` over the one segmentation: fed one channel's records in order, it keeps each answered request, from the end of its request (Exchange.request_end_t_ns) to the first rx after it (response_start_t_ns), as the replay cuts exchanges.
    """

    def __init__(self, header: SessionHeader, channel: int = 0, profile: str | None = None) -> None:
        """
        For channel `channel` (its id) of the session whose header is `header`; request frames cut and named by the profile `profile` (a name or a declared profile, read as every --profile is: profile_from_spec).
        """

    def feed(self, kind: str, t_ns: int, payload: bytes) -> None:
        """One record of the channel, in recorded order."""

    @property
    def answered(self) -> list[RequestLatency]:
        """The answered requests so far (RequestLatency), in order."""

class ClientSessionTracker:
    """
    Follows client sessions through a session's records in order, by the bridge's rule: a controlling client's client_connect while none is open begins one (a read-only monitor's, or a second client's, does not); that client's client_disconnect ends it.
    """

    def __init__(self) -> None: ...

    def feed(self, kind: str, payload: bytes) -> str:
        """
        One record: 'began' if it begins a client session, 'ended' if it ends one, else ''.
        """

    @property
    def open(self) -> bool:
        """whether a client session is open"""

def session_client_sessions(path: str) -> list[ClientSession]:
    """The client sessions of the session file at `path`, in order."""

class FaultKind:
    """A kind of fault (docs/faults.md)."""

    @property
    def name(self) -> str:
        """Its name in KIND (drop, delay, ...)."""

    @property
    def amount(self) -> str:
        """Whether it takes ':N': 'none', 'optional' or 'required'."""

    @property
    def campaign(self) -> str:
        """The KIND a campaign injects (delay:500 for delay, drop for drop)."""

    def __repr__(self) -> str: ...

class FaultSpec:
    """One KIND@WHERE of a fault plan."""

    @property
    def kind(self) -> str:
        """The kind's name (drop, corrupt, ...)."""

    @property
    def amount(self) -> int | None:
        """The :N or :MS given, or None."""

    @property
    def where(self) -> str:
        """The place's name: exchange, rx, t, every or p."""

    @property
    def number(self) -> int | None:
        """N of exchange:N, rx:N and every:N; None for t: and p:."""

    @property
    def value(self) -> float | None:
        """The seconds of t: or the probability of p:; None for the others."""

    @property
    def kind_text(self) -> str:
        """KIND in its normal spelling (corrupt:4)."""

    @property
    def where_text(self) -> str:
        """WHERE in its normal spelling (exchange:3; exchange:3@channel:gps)."""

    @property
    def channel(self) -> str:
        """The channel of @channel:NAME; "" for a fault of every channel."""

    @property
    def text(self) -> str:
        """The item as written (without surrounding spaces)."""

    def __repr__(self) -> str: ...

class FaultPlan:
    """faults= parsed: its items in order, and the seed."""

    @property
    def faults(self) -> list[FaultSpec]:
        """The items (FaultSpec), in order."""

    @property
    def seed(self) -> int:
        """seed=, for the faults' random choices."""

    def check_against(self, path: str, profile: str | None = None, match: str | None = None, options: str = '') -> None:
        """
        Raises OptionError (key 'faults') for a fault naming a channel the session file at `path` lacks, or placed past the end of what its replay (with profile=, match= and further replay keys `options`) serves: exchange:N, rx:N, t:S (after the last rx recorded on the session's clock); a fault without @channel: past every channel's end.
        """

    def __len__(self) -> int: ...

    def __getitem__(self, arg: int, /) -> FaultSpec: ...

    def __repr__(self) -> str: ...

def fault_kinds() -> list[FaultKind]:
    """Every fault kind, in the order a campaign injects them."""

def parse_faults(text: str, seed: int = 0) -> FaultPlan:
    """
    Parses faults= (KIND@WHERE[;KIND@WHERE...]) as a replay does. Raises OptionError naming the key 'faults', the item and the grammar.
    """

def normal_fault_kind(kind: str) -> str:
    """
    One KIND (drop, corrupt:4, delay:500) in its normal spelling. Raises OptionError naming the kind and the grammar.
    """

class FuzzedReplay:
    """
    A recording read once, that fuzzing plans mutate (docs/fuzzing.md): open(plan) a replay Port of it, write(path, plan) a .wtape session.
    """

    def __init__(self, session: str, profile: str = '', options: str = '') -> None:
        """
        session: the recording; profile: a profile name whose frames plans mutate ('' : plans act on rx records); options: replay keys over the fuzzing defaults timing=none,at_end=closed,unused=ignore. OptionError for bad options or a profile that does not fit the recording; SessionError for a session with no device bytes.
        """

    def open(self, plan: bytes) -> Port:
        """A replay Port of the recording mutated by `plan` (any bytes)."""

    def edits(self, plan: bytes) -> list[str]:
        """
        What `plan` changes, one line a change; [] for a plan that changes nothing.
        """

    def write(self, path: str, plan: bytes) -> list[str]:
        """
        Writes the recording mutated by `plan` as a .wtape session at `path` (the edits appended to its header's edits); returns the edits.
        """

    def inert(self, plan: bytes) -> bool:
        """
        Whether `plan` only splits frames across reads or delays them within the replay's tolerance: a driver failing on it, even with a clean error, has a finding.
        """

    @property
    def units(self) -> int:
        """
        How many rx frames (with a profile) or rx records a plan's steps index.
        """

class RecordCheck:
    """
    What check_session_records() found: every record the reader reached, with those of channels the header does not list.
    """

    @property
    def header(self) -> SessionHeader: ...

    @property
    def records(self) -> int:
        """the good records of the channels the header lists"""

    @property
    def channel_records(self) -> dict[int, int]:
        """records per channel id, those of unlisted channels included"""

    @property
    def unlisted_records(self) -> int:
        """
        records naming a channel the header does not list (the reader skips them)
        """

    @property
    def first_unlisted_offset(self) -> int | None:
        """where the first such record begins, or None"""

    @property
    def first_unlisted_channel(self) -> int | None:
        """the channel the first such record names, or None"""

    @property
    def index_state(self) -> str:
        """
        the per-channel index: 'not needed' (one channel), 'current', 'absent', 'stale' or 'unchecked' (a damaged file, a stream)
        """

    @property
    def index_detail(self) -> str:
        """why the index is absent, stale or unchecked; where it is when current"""

    @property
    def damage(self, /) -> SessionError | None:
        """
        None, or a SessionError (not raised) with .offset and .message: where reading stopped and why
        """

    @property
    def unfinished(self) -> str | None:
        """
        None, or why reading stopped at the end of a file still being written (not damage)
        """

    @property
    def unfinished_offset(self) -> int | None:
        """where the unfinished chunk or record begins, or None"""

def check_session_records(path: str) -> RecordCheck:
    """
    Reads every record of the session at PATH as SessionReader does (CRC, length, content), counting them per channel and noting the records of channels the header does not list, which a reader skips. Raises PortError when PATH cannot be opened, SessionError when it is not a session; damage later on is RecordCheck.damage.
    """

def repair_session_index(path: str) -> tuple[str, str]:
    """
    `wiretape verify --repair`: appends the per-channel index to the session at PATH, of several channels, when it has none or a stale one. Returns (state, detail): ('current', 'appended at byte N'), or the state found when nothing was to be done. Raises SessionError when the file is damaged, PortError when it cannot be written.
    """

def parse_start_utc(text: str) -> int | None:
    """
    A header's start_utc (2026-11-23T10:00:00.123456Z) as ns since the epoch; None for '' (not known). Raises OptionError naming start_utc and saying why for text the header does not allow.
    """

def format_start_utc(epoch_ns: int) -> str:
    """
    EPOCH_NS (ns since 1970, UTC) as a header's start_utc, with nine digits of fraction (2026-11-23T10:00:00.123456789Z). Raises ValueError when it is outside the years a header can hold.
    """
