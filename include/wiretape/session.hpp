// Session files (.wtape): one file per session with both directions and
// events in the order they happened. The byte layout is specified in
// docs/session-format.md. Readers also accept flexiport's two-file logs
// (`name.log` meaning `name.logr` + `name.logw`), detected automatically.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "wiretape/device_identity.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/version.hpp"

namespace wiretape {

// What a record is. Payloads: the bytes for rx/tx; a JSON object for events
// (may be empty). Unknown kinds read from a newer file are skipped.
enum class RecordKind : std::uint8_t {
  rx = 0x01,  // device -> host
  tx = 0x02,  // host -> device
  open = 0x10,
  close = 0x11,
  flush_input = 0x12,
  flush_output = 0x13,
  drain = 0x14,
  settings = 0x15,     // {"baud":115200,"databits":8,"parity":"none",...}
  modem_lines = 0x16,  // {"dtr":true} / {"rts":false}
  line_break = 0x17,   // {"duration_ms":250}
  client_connect = 0x18,
  client_disconnect = 0x19,
  device_lost = 0x1a,  // the device went away (EOF, ENXIO, ECONNRESET)
  fault = 0x1b,        // replay injected a fault here: {"kind":"corrupt","where":"exchange:3"}
  redaction = 0x1c,    // the next direction record's bytes at offset, length were scrubbed
  capture_gap = 0x1d,  // an imported capture lost `length` bytes of a direction at `offset`
};

// "rx", "tx", "open", ... "line_break" is spelled "break".
std::string_view to_string(RecordKind kind);
std::optional<RecordKind> record_kind_from_string(std::string_view name);

struct Record {
  std::uint64_t t_ns = 0;  // since the device was opened, monotonic
  RecordKind kind = RecordKind::rx;
  std::string data;
  // Which port of the session the record belongs to (format 1.2: its id in
  // SessionHeader::channels); 0 in a session of one port.
  std::uint16_t channel = 0;
};

enum class Capture {
  client,  // library recording: rx stamped when the client's read returned
  wire,    // proxy: every byte, stamped on arrival
};

// One port of a session of several ports (format 1.2, DESIGN §19): what a
// session header says of a single port, said of each of its channels.
struct Channel {
  std::uint16_t id = 0;  // what its records carry in Record::channel
  // "" only for the one channel of a session without named channels; else
  // unique in the session and a good name (channel_name_problem).
  std::string name;
  std::string port_options;
  std::string port_type;
  Capture capture = Capture::client;
  std::string device_address;
  std::optional<DeviceIdentity> device_identity;

  bool operator==(const Channel& other) const;
  bool operator!=(const Channel& other) const { return !(*this == other); }
};

// Why `name` cannot name a channel (not an identifier of at most 64
// characters: letters, digits, '_' and '-', not starting with a digit or
// '-'; or an option key, which would make `--device NAME=...` ambiguous),
// or std::nullopt when it can.
std::optional<std::string> channel_name_problem(std::string_view name);

// A recording made by attaching to a running program (`record --attach`,
// DESIGN §26): which program, when, and what of it was followed.
struct AttachedProgram {
  std::int64_t pid = 0;
  std::string command;  // its command name (/proc/PID/comm)
  std::string utc;      // when the attach began, ISO 8601 UTC like start_utc
  std::vector<int> descriptors;  // the device's descriptors at the attach
  std::string device;            // what they are: /dev/pts/3, socket:[1234]
  // What the recording cannot hold (bytes moved by splice, sendfile,
  // io_uring...), said rather than left a silent gap.
  std::vector<std::string> warnings;

  bool operator==(const AttachedProgram& other) const;
  bool operator!=(const AttachedProgram& other) const { return !(*this == other); }
};

// A session's header: what was recorded, where, when and how. The one type
// for reading (SessionReader::header) and writing (SessionWriter): what a
// writer is given is what the file says, nothing is filled in behind it.
struct SessionHeader {
  // The file's format version, as read: 0.0 for a flexiport log. A writer
  // writes its own format version and ignores these.
  std::uint16_t version_major = 1;
  std::uint16_t version_minor = 0;
  // The header's JSON object as stored (read), or as written (the writer's
  // header()); a writer makes it from the fields below (to_json) and ignores
  // what is here.
  std::string metadata_json;
  std::string port_options;  // the option string the port was opened with
  std::string port_type;
  std::string start_utc;  // ISO 8601, e.g. 2026-11-23T10:00:00.123456Z; empty: not known
  std::string wiretape_version = version;  // of the wiretape that wrote the file
  std::string host;  // the recording machine's name; empty: not known
  Capture capture = Capture::client;
  // Where the session came from: "wiretape" (recorded by wiretape), or the
  // format it was imported from ("flexiport", "pcap", "reserial", ...),
  // with the imported files' names and what else the import noted.
  std::string source_format = "wiretape";
  std::vector<std::string> source_files;
  std::map<std::string, std::string> source_details;
  std::string device_address;  // host:port of a network device, when known
  std::vector<std::string> edits;  // what `wiretape edit` changed, in order
  // Format 1.2: the serial device's identity, when `record` opened one that
  // has it (none for a pty, a network device, an import).
  std::optional<DeviceIdentity> device_identity;
  std::map<std::string, std::string> user_metadata;  // free user metadata (--meta)
  // Format 1.2: the session's ports, ids 0..n-1 in order. Empty: one
  // unnamed channel, 0, which the port members above describe. With
  // channels, the port members above are channel 0's: to_json writes them
  // from channels[0], so that a reader of format 1.1 (which skips records of
  // other channels) reads the session as its channel 0.
  std::vector<Channel> channels;
  // Set when the session was recorded by attaching to a running program.
  std::optional<AttachedProgram> attached;

  // Every channel of the session: `channels`, or the one unnamed channel 0
  // that the port members describe. Never empty.
  std::vector<Channel> channel_list() const;
  // The channel named `name`, if the session has one.
  std::optional<Channel> find_channel(std::string_view name) const;

  // A header for a session that starts now on this machine: start_utc is
  // now and host this machine's name (what recorders write).
  static SessionHeader starting_now();
  // The header's JSON object, as a writer writes it (docs/session-format.md,
  // "Metadata"). Throws OptionError naming the member when the reader would
  // refuse it: a string that is not valid UTF-8, a start_utc that is not an
  // ISO 8601 UTC time in range, a source detail named format or files, a
  // channel list with a bad or repeated name or ids out of order.
  std::string to_json() const;
};

// Streams records with memory independent of the file's size.
class SessionReader {
 public:
  // Throws PortError when the file cannot be opened (missing, permission
  // denied) or is not a regular file (a FIFO or a device is refused at once,
  // never waited on); SessionError (with the byte offset) when it is not a
  // usable session: empty, wrong magic, newer major version, bad header.
  // `channel`: read only that channel's records; std::nullopt: every
  // channel's, in the order they were recorded (Record::channel says which).
  explicit SessionReader(const std::string& path,
                         std::optional<std::uint16_t> channel = std::nullopt);
  ~SessionReader();
  SessionReader(SessionReader&&) noexcept;
  SessionReader& operator=(SessionReader&&) noexcept;

  const SessionHeader& header() const;
  // The next record; false at the end of the file, or at the first damaged
  // or truncated record (then damage() says where and why).
  bool next(Record& record);
  // Set once reading stopped at a damaged record: everything before it was
  // returned.
  const std::optional<SessionError>& damage() const;
  // Set instead of damage() when reading stopped at the end of a file that
  // is still being written (its writer, a SessionWriter of this or another
  // process, holds it open): it ends in a chunk or record not written
  // whole yet. Every record before it was returned; reading it again later
  // returns more.
  const std::optional<SessionError>& unfinished() const;
  // Back to the first record.
  void rewind();
  const std::string& path() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// How a SessionWriter hands its records to the OS (not part of the file).
// How records are stored: as they are, or in zstd chunks (format 2.0,
// DESIGN §29; `compress=zstd`).
enum class Compression { none, zstd };

// How records reach the file.
struct FlushPolicy {
  // Bound on what a crash may lose: buffered records reach the OS at most
  // this long after they were written, even when the recorder goes idle.
  std::chrono::milliseconds interval{100};
  bool fsync = false;  // fsync after each flush
  // zstd: records are grouped into chunks of about 1 MiB, each flush of
  // the file flushing the compressor too, so that what reached the file
  // decodes up to it; the file is format 2.0, which 1.x readers refuse.
  Compression compression = Compression::none;
};

// Appends records to a new session file. Thread-safe: a reader thread and a
// writer thread of a port may record at once.
class SessionWriter {
 public:
  // Truncates/creates `path`; throws PortError (errno) if it cannot. Only a
  // regular file is written: a symbolic link, a FIFO or a device at `path`
  // is refused untouched, and so is a file this process is reading as a
  // session (same device and inode: links to it included).
  // Throws OptionError naming the member when `header` cannot be written
  // (SessionHeader::to_json), before the file is created.
  // `header_room`: spare bytes reserved after the header JSON (written as
  // spaces, which JSON ignores), so that add_channel() can rewrite the header
  // in place; 0 writes the header exactly as long as its JSON.
  SessionWriter(const std::string& path, const SessionHeader& header,
                FlushPolicy flush = FlushPolicy{}, std::size_t header_room = 0);
  ~SessionWriter();  // closes; never throws
  SessionWriter(const SessionWriter&) = delete;
  SessionWriter& operator=(const SessionWriter&) = delete;

  // Throws PortError when the file cannot be written (full disk, file-size
  // limit); what was written before stays readable. `channel`: the id of
  // the record's channel (SessionHeader::channels; 0 in a session of one
  // port).
  void write(RecordKind kind, std::uint64_t t_ns, std::string_view data,
             std::uint16_t channel = 0);
  void write(const Record& record) {
    write(record.kind, record.t_ns, record.data, record.channel);
  }
  // A record read straight into the writer's buffer, without a copy (the
  // bridge's reads of its device): `fill` is called with the writer locked
  // and room for `max_size` bytes, and returns how many it put there and
  // their time; they become a record of `kind` (nothing for 0 bytes). An
  // exception of `fill` leaves nothing recorded. `*bytes` is set to the
  // record's bytes in the buffer before a flush this write makes, so that
  // when the flush fails (thrown as by write()) the caller still has them.
  // They stay valid and unchanged until the next write to this writer from
  // any thread: only a writer of one writing thread may use them after
  // this returns, and only before it writes again.
  struct Filled {
    std::size_t size = 0;
    std::uint64_t t_ns = 0;
  };
  using Fill = Filled (*)(void* context, char* room, std::size_t max_size);
  void write_filled(RecordKind kind, std::size_t max_size, Fill fill, void* context,
                    std::string_view* bytes, std::uint16_t channel = 0);
  // Appends `channel` to the header's channels with the next id (returned;
  // the given id is ignored) and rewrites the header in place, padded to the
  // length reserved at construction (header_room). Thread-safe with write().
  // Throws OptionError naming `name` for a bad or duplicate channel name,
  // SessionError when the header would no longer fit its reserved room (the
  // message says how many channels fit), PortError when the file cannot be
  // written. A channel named "" is refused: the unnamed channel is the one
  // of a file without `channels`.
  std::uint16_t add_channel(Channel channel);
  // Rewrites the header in place with `updated`'s members (its channels
  // stay the ones added), as add_channel() does: an attached recording's
  // warnings are added so. Throws as add_channel().
  void rewrite_header(SessionHeader updated);
  // Hands everything buffered to the OS now (and fsyncs if asked).
  void flush();
  // Flushes and closes; throws PortError if the last data could not be
  // written. Further writes throw.
  void close();
  const std::string& path() const;
  // The header as written: this library's format version and metadata_json
  // (its JSON without the padding). Not to be read while another thread
  // calls add_channel().
  const SessionHeader& header() const;
  // The first write failure (full disk, file-size limit), if any. After a
  // failure the file holds every whole record written before it and nothing
  // after it, and write() throws.
  std::optional<PortError> failure() const;
  // Bytes in the file so far, flushed or buffered.
  std::uint64_t size() const;
  // Records handed whole to the OS so far: not those still buffered, nor
  // those a failed write lost. After close(), what a reader of the file finds.
  std::uint64_t records_written() const;

 private:
  std::string rewrite_in_place(const SessionHeader& updated, const std::string& what,
                               const std::string& fit, const std::string& why);
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// flexiport's two chunk layouts: `modern` (flexiport from 2008-07, "new":
// u32 BE seconds, microseconds, length) and `legacy` (before, "old": i64 LE
// seconds, microseconds, u64 LE length).
enum class FlexiportFormat { modern, legacy };

// flexiport's two-file logs. `prefix` is "name.log" for name.logr/name.logw.
// Import (reading) is done by SessionReader; this writes `format` (the new
// one unless asked).
// Events are not representable there and are dropped; times are truncated to
// microseconds. Throws SessionError if the source is not a session (or is
// damaged: what was written up to the damage stays), PortError when a file
// cannot be opened or written. The source may be a pipe or FIFO (read once,
// as SessionReader reads it); an output that is a FIFO or a device is written
// through (a symbolic link is followed), a directory is refused. Returns the
// number of records written (rx and tx).
std::uint64_t export_flexiport(const std::string& session_path, const std::string& prefix,
                               FlexiportFormat format = FlexiportFormat::modern);

// The CRC32C (Castagnoli) of `data`, continuing from `crc` (0 to start): the
// checksum of every header and record of a .wtape file.
std::uint32_t crc32c(const void* data, std::size_t size, std::uint32_t crc = 0);

}  // namespace wiretape
