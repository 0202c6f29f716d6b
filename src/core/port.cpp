#include "wiretape/port.hpp"

#include <algorithm>
#include <cerrno>
#include <stdexcept>
#include <string>
#include <utility>

#include "wiretape/errors.hpp"

namespace wiretape {

Port::~Port() = default;

const char* to_string(Parity parity) noexcept {
  switch (parity) {
    case Parity::even: return "even";
    case Parity::odd: return "odd";
    case Parity::mark: return "mark";
    case Parity::space: return "space";
    case Parity::none: break;
  }
  return "none";
}

const char* to_string(FlowControl flow) noexcept {
  switch (flow) {
    case FlowControl::rtscts: return "rtscts";
    case FlowControl::xonxoff: return "xonxoff";
    case FlowControl::none: break;
  }
  return "none";
}

namespace {

void require(bool allowed, const char* operation, const Port& port) {
  if (!allowed) {
    throw PortError(EBADF, std::string("cannot ") + operation + " on " +
                               port.description() + ": the port is opened " +
                               (port.access() == Access::read_only
                                    ? "read-only"
                                    : "write-only"));
  }
}

// Bytes a compound read asks the port for at once: a peek's window, and
// what read_exactly reads into its result per call.
constexpr std::size_t chunk_size = 4096;
constexpr std::size_t bulk_size = 1 << 16;

}  // namespace

std::size_t Port::read(void* buffer, std::size_t size) {
  return read(buffer, size, timeout_);
}

std::size_t Port::read(void* buffer, std::size_t size, Timeout timeout) {
  require(access_ != Access::write_only, "read", *this);
  if (size == 0) return 0;
  return read_some(buffer, size, deadline_after(timeout));
}

std::string Port::read_exactly(std::size_t count) {
  return read_exactly(count, timeout_);
}

std::string Port::read_exactly(std::size_t count, Timeout timeout) {
  CompoundRead read = CompoundRead::exactly(*this, count);
  read.advance(deadline_after(timeout));
  return read.finish();
}

std::string Port::read_until(std::string_view delimiter, std::size_t max_bytes) {
  return read_until(delimiter, max_bytes, timeout_);
}

std::string Port::read_until(std::string_view delimiter, std::size_t max_bytes,
                             Timeout timeout) {
  CompoundRead read = CompoundRead::until(*this, delimiter, max_bytes);
  read.advance(deadline_after(timeout));
  return read.finish();
}

std::string Port::read_line(std::size_t max_bytes) {
  return read_line(max_bytes, timeout_);
}

std::string Port::read_line(std::size_t max_bytes, Timeout timeout) {
  return read_until("\n", max_bytes, timeout);
}

std::size_t Port::skip(std::size_t count) { return skip(count, timeout_); }

std::size_t Port::skip(std::size_t count, Timeout timeout) {
  CompoundRead read = CompoundRead::discard(*this, count);
  read.advance(deadline_after(timeout));
  read.finish();
  return read.consumed();
}

bool Port::skip_until(std::string_view delimiter) {
  return skip_until(delimiter, timeout_);
}

bool Port::skip_until(std::string_view delimiter, Timeout timeout) {
  CompoundRead read = CompoundRead::discard_until(*this, delimiter);
  read.advance(deadline_after(timeout));
  read.finish();
  return read.found_delimiter();
}

std::optional<std::size_t> Port::peek_some(void*, std::size_t, Deadline) {
  return std::nullopt;
}

bool Port::wait_readable(Timeout timeout) {
  return wait_readable_until(deadline_after(timeout));
}

std::size_t Port::write(const void* data, std::size_t size) {
  return write(data, size, timeout_);
}

std::size_t Port::write(const void* data, std::size_t size, Timeout timeout) {
  require(access_ != Access::read_only, "write", *this);
  if (size == 0) return 0;
  return write_some(data, size, deadline_after(timeout));
}

std::size_t Port::write_all(const void* data, std::size_t size) {
  return write_all(data, size, timeout_);
}

std::size_t Port::write_all(const void* data, std::size_t size, Timeout timeout) {
  require(access_ != Access::read_only, "write", *this);
  const Deadline deadline = deadline_after(timeout);
  const auto* bytes = static_cast<const char*>(data);
  std::size_t sent = 0;
  while (sent < size) {
    const std::size_t n = write_some(bytes + sent, size - sent, deadline);
    if (n == 0) break;
    sent += n;
  }
  return sent;
}

// --- CompoundRead --------------------------------------------------------

CompoundRead::CompoundRead(Port& port, Goal goal, std::string delimiter,
                           std::size_t limit, bool keep)
    : port_(&port),
      goal_(goal),
      delimiter_(std::move(delimiter)),
      limit_(limit),
      keep_(keep) {
  require(port.access() != Access::write_only, "read", port);
  complete_ = limit_ == 0;
}

CompoundRead CompoundRead::exactly(Port& port, std::size_t count) {
  return CompoundRead(port, Goal::count, {}, count, true);
}

CompoundRead CompoundRead::until(Port& port, std::string_view delimiter,
                                 std::size_t max_bytes) {
  return CompoundRead(port, Goal::delimiter, std::string(delimiter), max_bytes,
                      true);
}

CompoundRead CompoundRead::discard(Port& port, std::size_t count) {
  return CompoundRead(port, Goal::count, {}, count, false);
}

CompoundRead CompoundRead::discard_until(Port& port,
                                         std::string_view delimiter) {
  if (delimiter.empty()) {
    throw std::invalid_argument("skip_until: the delimiter must not be empty");
  }
  return CompoundRead(port, Goal::delimiter, std::string(delimiter),
                      Port::unlimited, false);
}

CompoundRead::CompoundRead(CompoundRead&& other) noexcept
    : port_(std::exchange(other.port_, nullptr)),
      goal_(other.goal_),
      delimiter_(std::move(other.delimiter_)),
      limit_(other.limit_),
      keep_(other.keep_),
      data_(std::move(other.data_)),
      tail_(std::move(other.tail_)),
      consumed_(other.consumed_),
      complete_(other.complete_),
      found_delimiter_(other.found_delimiter_),
      read_started_(other.read_started_) {}

CompoundRead::~CompoundRead() { end_read(); }

void CompoundRead::end_read() noexcept {
  Port* port = std::exchange(port_, nullptr);
  if (port == nullptr || !read_started_) return;
  port->compound_read_ = false;
  try {
    port->read_returned();
  } catch (...) {
    // A destructor never throws; the recorder reports its own failures on
    // the next port call.
  }
}

std::string CompoundRead::finish() {
  Port* port = std::exchange(port_, nullptr);
  if (port != nullptr && read_started_) {
    port->compound_read_ = false;
    port->read_returned();
  }
  return std::move(data_);
}

void CompoundRead::append(const char* bytes, std::size_t size) {
  consumed_ += size;
  if (keep_) data_.append(bytes, size);
  if (goal_ == Goal::delimiter && !delimiter_.empty()) {
    tail_.append(bytes, size);
    if (tail_.size() > delimiter_.size()) {
      tail_.erase(0, tail_.size() - delimiter_.size());
    }
    found_delimiter_ = tail_ == delimiter_;
  }
  complete_ = found_delimiter_ || consumed_ == limit_;
}

std::size_t CompoundRead::take_from(const char* chunk, std::size_t size) const {
  if (delimiter_.empty()) return size;
  // The delimiter may start in the bytes already read: a delimiter that
  // does is found in them and the chunk's first bytes, a short window (no
  // copy of the chunk, which is searched in place).
  const std::size_t reach = delimiter_.size() - 1;
  std::string window = tail_.size() > reach ? tail_.substr(tail_.size() - reach) : tail_;
  const std::size_t carried = window.size();
  window.append(chunk, std::min(size, reach));
  const std::size_t across = window.find(delimiter_);
  if (across != std::string::npos) return across + delimiter_.size() - carried;
  const std::size_t at = std::string_view(chunk, size).find(delimiter_);
  if (at == std::string_view::npos) return size;
  return at + delimiter_.size();
}

bool CompoundRead::advance(Deadline deadline) {
  if (port_ == nullptr) {
    throw std::logic_error("CompoundRead::advance after finish()");
  }
  Port& port = *port_;
  char chunk[chunk_size];
  while (!complete_) {
    read_started_ = true;
    port.compound_read_ = true;
    if (goal_ == Goal::count && keep_) {
      // Nothing to look for: read straight into the result, in large pieces.
      const std::size_t want = std::min(bulk_size, limit_ - consumed_);
      data_.resize(consumed_ + want);
      const std::size_t n = port.read_some(&data_[consumed_], want, deadline);
      data_.resize(consumed_ + n);
      if (n == 0) return false;
      consumed_ += n;
      complete_ = consumed_ == limit_;
      continue;
    }
    const std::size_t want = std::min(chunk_size, limit_ - consumed_);
    std::size_t take = want;
    if (goal_ == Goal::delimiter && !delimiter_.empty()) {
      const std::optional<std::size_t> peeked =
          port.peek_some(chunk, want, deadline);
      if (!peeked) {
        take = 1;
      } else if (*peeked == 0) {
        return false;
      } else {
        take = take_from(chunk, *peeked);
      }
    }
    const std::size_t n = port.read_some(chunk, take, deadline);
    if (n == 0) return false;
    append(chunk, n);
  }
  return true;
}

void Port::unsupported(const char* what) const {
  throw PortError(ENOTSUP, std::string(what) + " is not supported by " +
                               description());
}

void Port::set_baud(unsigned) { unsupported("set_baud"); }
void Port::configure(const SerialSettings&) { unsupported("configure"); }
SerialSettings Port::serial_settings() const {
  unsupported("serial_settings");
}
void Port::set_dtr(bool) { unsupported("set_dtr"); }
void Port::set_rts(bool) { unsupported("set_rts"); }
bool Port::cts() { unsupported("cts"); }
bool Port::dsr() { unsupported("dsr"); }
bool Port::ri() { unsupported("ri"); }
bool Port::cd() { unsupported("cd"); }
void Port::send_break(std::chrono::milliseconds) { unsupported("send_break"); }

}  // namespace wiretape
