// The Port: one API for serial lines, TCP, UDP, pseudo-terminals, in-memory
// loopback, recordings and replays. Ports are made by open_port() from an
// option string (see options.hpp and docs/options.md).
//
// Timeout contract (every blocking call):
//   - the port's timeout() applies unless a call is given its own;
//   - wiretape::forever (std::nullopt) blocks, zero polls, a duration waits at
//     most that long;
//   - read() returns at least one byte, or 0 when the timeout expires; it
//     never throws on a timeout;
//   - compound reads (read_exactly, read_until, read_line, skip, skip_until)
//     that time out return the partial data and never throw; each is one read
//     (one rx record in a log= recording) however many system calls it took;
//   - a device that goes away raises PortClosed; other OS errors PortError;
//     EINTR never reaches the caller.
// Threads: one reader and one writer may run at once; close() from any thread
// wakes a blocked read or write, which then raises PortClosed. Two concurrent
// readers are not supported.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "wiretape/timeout.hpp"

namespace wiretape {

enum class Access { read_write, read_only, write_only };
enum class Parity { none, even, odd, mark, space };
enum class FlowControl { none, rtscts, xonxoff };

// Names as in option strings: "none", "even", ... / "none", "rtscts", ...
const char* to_string(Parity parity) noexcept;
const char* to_string(FlowControl flow) noexcept;

// Line settings of a serial port (or of the terminal a pty emulates).
struct SerialSettings {
  unsigned baud = 9600;
  int data_bits = 8;
  int stop_bits = 1;
  Parity parity = Parity::none;
  FlowControl flow = FlowControl::none;
  bool operator==(const SerialSettings& other) const {
    return baud == other.baud && data_bits == other.data_bits &&
           stop_bits == other.stop_bits && parity == other.parity &&
           flow == other.flow;
  }
  bool operator!=(const SerialSettings& other) const {
    return !(*this == other);
  }
};

// What a port can do, asked of the port (Port::capabilities()) instead of
// guessed from its type() or description(). Every field is false unless the
// port type says otherwise, so a new port type starts out conservative.
//   serial_settings   configure()/set_baud()/serial_settings() act on a line
//                     (serial; replay emulates one)
//   terminal_settings serial_settings() reports what a client programmed on
//                     its terminal (pty), to be mirrored onto a device
//   modem_lines       set_dtr/set_rts and cts/dsr/ri/cd work (serial; replay)
//   send_break        send_break() works (serial; replay)
//   datagrams         reads and writes keep message boundaries (udp)
//   output_pollable   native_handle() polls writable exactly when a write
//                     would not block (descriptor-backed ports); otherwise a
//                     write that took nothing is retried on a timer
//   played_recording  the device is a recording played back (replay): a
//                     virtual device, whose output waits for its client
struct PortCapabilities {
  bool serial_settings = false;
  bool terminal_settings = false;
  bool modem_lines = false;
  bool send_break = false;
  bool datagrams = false;
  bool output_pollable = false;
  bool played_recording = false;
};

class Port {
 public:
  virtual ~Port();
  Port(const Port&) = delete;
  Port& operator=(const Port&) = delete;

  // --- reading -----------------------------------------------------------
  // Whatever is there, at least one byte, up to `size`; 0 on timeout.
  std::size_t read(void* buffer, std::size_t size);
  std::size_t read(void* buffer, std::size_t size, Timeout timeout);
  // Exactly `count` bytes, or fewer if the timeout expires first.
  std::string read_exactly(std::size_t count);
  std::string read_exactly(std::size_t count, Timeout timeout);
  // Up to and including `delimiter`, or `max_bytes`, or what came before the
  // timeout.
  std::string read_until(std::string_view delimiter,
                         std::size_t max_bytes = unlimited);
  std::string read_until(std::string_view delimiter, std::size_t max_bytes,
                         Timeout timeout);
  std::string read_line(std::size_t max_bytes = unlimited);
  // Discards up to `count` bytes; returns how many were discarded.
  std::size_t skip(std::size_t count);
  std::string read_line(std::size_t max_bytes, Timeout timeout);
  std::size_t skip(std::size_t count, Timeout timeout);
  // Discards through `delimiter`; false if the timeout expired first.
  bool skip_until(std::string_view delimiter);
  bool skip_until(std::string_view delimiter, Timeout timeout);
  // Bytes that a read would return at once.
  virtual std::size_t available() = 0;
  // True once a read would not block (data, or the device is gone).
  bool wait_readable(Timeout timeout);

  // --- writing -----------------------------------------------------------
  // Writes what the device accepts, at least one byte, or 0 on timeout.
  std::size_t write(const void* data, std::size_t size);
  std::size_t write(const void* data, std::size_t size, Timeout timeout);
  std::size_t write(std::string_view data) { return write(data.data(), data.size()); }
  // Writes everything; returns less than `size` only on timeout.
  std::size_t write_all(const void* data, std::size_t size);
  std::size_t write_all(const void* data, std::size_t size, Timeout timeout);
  std::size_t write_all(std::string_view data) {
    return write_all(data.data(), data.size());
  }

  // --- buffers -----------------------------------------------------------
  virtual void flush_input() = 0;   // drop what was received, unread
  virtual void flush_output() = 0;  // drop what was written, unsent
  virtual void drain() = 0;         // wait until written data has left

  // --- state -------------------------------------------------------------
  void set_timeout(Timeout timeout) { timeout_ = timeout; }
  Timeout timeout() const noexcept { return timeout_; }
  Access access() const noexcept { return access_; }
  void set_access(Access access) noexcept { access_ = access; }
  virtual void close() = 0;
  virtual bool is_open() const = 0;
  // Human-readable, e.g. "serial /dev/ttyUSB0 @ 115200 8N1".
  virtual std::string description() const = 0;
  // The port's type as in the option string ("serial", "tcp", "replay"…).
  virtual std::string type() const = 0;
  // A file descriptor that polls readable exactly when available() > 0 (or
  // the device is gone); -1 only after close().
  virtual int native_handle() const = 0;
  // What this port can do (see PortCapabilities); none of it by default.
  virtual PortCapabilities capabilities() const { return {}; }
  // A played recording (replay), once closed: what its client left of the
  // recording unread or unasked, as unused= words it ("" when it used it
  // all), whatever unused= says to do about it; "" before close() and for
  // every other port.
  virtual std::string left_unused() const { return {}; }

  // --- serial line control (PortError ENOTSUP where the port has none) ----
  virtual void set_baud(unsigned baud);
  virtual void configure(const SerialSettings& settings);
  virtual SerialSettings serial_settings() const;
  virtual void set_dtr(bool level);
  virtual void set_rts(bool level);
  virtual bool cts();
  virtual bool dsr();
  virtual bool ri();
  virtual bool cd();
  virtual void send_break(std::chrono::milliseconds duration);

  static constexpr std::size_t unlimited =
      std::numeric_limits<std::size_t>::max();

 protected:
  Port() = default;
  // The transport's primitives. read_some returns >= 1 byte, or 0 once
  // `deadline` passed; write_some likewise. Both raise PortClosed when the
  // device is gone or the port closed.
  virtual std::size_t read_some(void* buffer, std::size_t size,
                                Deadline deadline) = 0;
  virtual std::size_t write_some(const void* data, std::size_t size,
                                 Deadline deadline) = 0;
  virtual bool wait_readable_until(Deadline deadline) = 0;
  // For the serial-control defaults: throws PortError(ENOTSUP) naming `what`.
  [[noreturn]] void unsupported(const char* what) const;

  // Decorators (recording port) call another port's primitives.
  static std::size_t read_some_of(Port& port, void* buffer, std::size_t size,
                                  Deadline deadline) {
    return port.read_some(buffer, size, deadline);
  }
  static std::size_t write_some_of(Port& port, const void* data,
                                   std::size_t size, Deadline deadline) {
    return port.write_some(data, size, deadline);
  }
  static bool wait_readable_until_of(Port& port, Deadline deadline) {
    return port.wait_readable_until(deadline);
  }
  static std::optional<std::size_t> peek_some_of(Port& port, void* buffer,
                                                 std::size_t size,
                                                 Deadline deadline) {
    return port.peek_some(buffer, size, deadline);
  }

  // Copies up to `size` bytes that the next read_some would return, without
  // consuming them: at least one byte, or 0 once `deadline` passed; raises
  // PortClosed as read_some does. std::nullopt, at once, when the transport
  // cannot look ahead (a tty): compound reads then read one byte at a time,
  // so that they never consume past what they need (ports keep no read-ahead
  // buffer, which keeps native_handle() truthful).
  virtual std::optional<std::size_t> peek_some(void* buffer, std::size_t size,
                                               Deadline deadline);
  // Called once when a compound read hands its bytes to the caller, or ends
  // by an exception, after all the read_some calls it made: the recording
  // port records them there as one rx.
  virtual void read_returned() {}
  // True while a CompoundRead is reading: its read_some calls are parts of
  // one read. A simple read() is one read_some call.
  bool in_compound_read() const noexcept { return compound_read_; }

 private:
  friend class CompoundRead;
  Timeout timeout_ = forever;
  bool compound_read_ = false;  // owned by the reading thread
  Access access_ = Access::read_write;
};

// One compound read (read_exactly, read_until/read_line, skip, skip_until)
// that its caller advances in steps, each bounded by a deadline of its own:
// for callers that must regain control while the read waits (the Python
// binding checks for Ctrl-C between steps). Port's compound reads are this
// object advanced once to the call's deadline. However many steps and system
// calls it takes, it is one read: its bytes are handed over, and recorded by
// a log= port as one rx, once, by finish() (or by the destructor, when the
// caller gave up, e.g. on Ctrl-C, after bytes were consumed).
//
// Where the port can look ahead (sockets, loopback), read_until takes one
// system call per chunk the device sent; where it cannot (a tty), one byte
// per call, so that nothing past the delimiter is consumed.
class CompoundRead {
 public:
  // read_exactly: `count` bytes.
  static CompoundRead exactly(Port& port, std::size_t count);
  // read_until: through `delimiter` (none when empty), at most `max_bytes`.
  static CompoundRead until(Port& port, std::string_view delimiter,
                            std::size_t max_bytes = Port::unlimited);
  // skip: discards `count` bytes.
  static CompoundRead discard(Port& port, std::size_t count);
  // skip_until: discards through `delimiter` (which must not be empty).
  static CompoundRead discard_until(Port& port, std::string_view delimiter);

  CompoundRead(CompoundRead&& other) noexcept;
  CompoundRead& operator=(CompoundRead&&) = delete;
  CompoundRead(const CompoundRead&) = delete;
  CompoundRead& operator=(const CompoundRead&) = delete;
  ~CompoundRead();

  // Reads until the read is complete or `deadline` passed; true once it is
  // complete (count reached, delimiter found, or max_bytes read). Raises what
  // the port raises (PortClosed...); the bytes consumed before stay recorded.
  bool advance(Deadline deadline);
  bool complete() const noexcept { return complete_; }
  // Bytes consumed so far (kept or discarded).
  std::size_t consumed() const noexcept { return consumed_; }
  // Whether the read ended with its delimiter.
  bool found_delimiter() const noexcept { return found_delimiter_; }
  // Ends the read and returns its bytes (empty for discards).
  std::string finish();

 private:
  enum class Goal { count, delimiter };
  CompoundRead(Port& port, Goal goal, std::string delimiter, std::size_t limit,
               bool keep);
  // How many bytes to take from the `size` peeked at `chunk`: through the
  // delimiter if it ends there, else all of them.
  std::size_t take_from(const char* chunk, std::size_t size) const;
  void append(const char* bytes, std::size_t size);
  void end_read() noexcept;

  Port* port_;  // null once the read ended (or moved from)
  Goal goal_;
  std::string delimiter_;
  std::size_t limit_;
  bool keep_;
  std::string data_;  // the bytes, when kept
  std::string tail_;  // the last delimiter-size bytes, to find the delimiter
  std::size_t consumed_ = 0;
  bool complete_ = false;
  bool found_delimiter_ = false;
  bool read_started_ = false;
};

// Opens the port described by `options` (see docs/options.md). Throws
// OptionError for a bad option string, PortError when the device cannot be
// opened.
std::unique_ptr<Port> open_port(std::string_view options);
class Options;
std::unique_ptr<Port> open_port(Options options);

}  // namespace wiretape
