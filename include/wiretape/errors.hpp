// Exceptions thrown by wiretape. Timeouts are never exceptions: a read that
// times out returns what it has (possibly nothing).
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <system_error>

namespace wiretape {

// A bad option string: unknown key, bad value, key that does not apply to the
// port type. The message names the key and lists what is valid.
class OptionError : public std::invalid_argument {
 public:
  OptionError(std::string key, const std::string& message)
      : std::invalid_argument(message), key_(std::move(key)) {}
  // The offending key ("" when the problem is the syntax of the string).
  const std::string& key() const noexcept { return key_; }

 private:
  std::string key_;
};

// The one way an operating-system error becomes text: "<context>: <the
// errno's text>". errno 0 adds nothing (never ": Success"), and neither does
// an errno whose text `context` already holds (a message wrapped again), so
// the text never repeats. `context` names where and what failed
// ("/dev/ttyUSB0: read failed"), without the errno's text.
std::string system_error_message(const std::string& context, int errno_value);

// An operating-system error on a port; code() carries the errno (0 when the
// failure did not come from the OS). what() is
// system_error_message(context, errno): callers give the context only.
class PortError : public std::system_error {
 public:
  PortError(int errno_value, const std::string& context)
      : std::system_error(errno_value, std::generic_category()),
        message_(system_error_message(context, errno_value)) {}
  // A failure that comes with its own explanation (a resolver's "Name or
  // service not known"): `message` as it is. The errno stays for programs,
  // its text is left out, since it would contradict the explanation.
  struct OwnExplanation {};
  PortError(int errno_value, const std::string& message, OwnExplanation)
      : std::system_error(errno_value, std::generic_category()), message_(message) {}
  // std::system_error's own text would append the errno's text whatever the
  // message already says, ": Success" included.
  const char* what() const noexcept override { return message_.what(); }

 private:
  std::runtime_error message_;  // copies share the text and never throw
};

// The device went away (EOF, ENXIO, ECONNRESET, a recorded close on replay) or
// the port was closed, possibly from another thread while a call was blocked.
class PortClosed : public PortError {
 public:
  explicit PortClosed(const std::string& what, int errno_value = 0)
      : PortError(errno_value, what) {}
};

// What a replayed client wrote differs from the recording. The message is the
// full human-readable report (offset, session time, hex+ASCII context,
// exchange number); the fields are there for programs.
class ReplayMismatch : public std::runtime_error {
 public:
  ReplayMismatch(const std::string& report, std::uint64_t tx_offset,
                 std::uint64_t session_time_ns, std::int64_t exchange)
      : std::runtime_error(report),
        tx_offset_(tx_offset),
        session_time_ns_(session_time_ns),
        exchange_(exchange) {}
  std::uint64_t tx_offset() const noexcept { return tx_offset_; }
  std::uint64_t session_time_ns() const noexcept { return session_time_ns_; }
  // Exchange number (0-based): the matched exchange in request mode, the run
  // of recorded writes in sequence mode; -1 where there is none.
  std::int64_t exchange() const noexcept { return exchange_; }

 private:
  std::uint64_t tx_offset_;
  std::uint64_t session_time_ns_;
  std::int64_t exchange_;
};

// A session file that cannot be read: bad magic, newer major version, a
// truncated or corrupt record. offset() is the byte offset of the problem.
class SessionError : public std::runtime_error {
 public:
  SessionError(const std::string& what, std::uint64_t offset)
      : std::runtime_error(what), offset_(offset) {}
  std::uint64_t offset() const noexcept { return offset_; }

 private:
  std::uint64_t offset_;
};

}  // namespace wiretape
