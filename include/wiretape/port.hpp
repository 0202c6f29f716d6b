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
//   - compound reads (read_exactly, read_until, read_line, skip_until) that
//     time out return the partial data and never throw;
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
struct PortCapabilities {
  bool serial_settings = false;
  bool terminal_settings = false;
  bool modem_lines = false;
  bool send_break = false;
  bool datagrams = false;
  bool output_pollable = false;
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
  // Discards through `delimiter`; false if the timeout expired first.
  bool skip_until(std::string_view delimiter);
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

 private:
  Timeout timeout_ = forever;
  Access access_ = Access::read_write;
};

// Opens the port described by `options` (see docs/options.md). Throws
// OptionError for a bad option string, PortError when the device cannot be
// opened.
std::unique_ptr<Port> open_port(std::string_view options);
class Options;
std::unique_ptr<Port> open_port(Options options);

}  // namespace wiretape
