#include "wiretape/port.hpp"

#include <cerrno>
#include <string>

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

bool ends_with(const std::string& text, std::string_view suffix) {
  return text.size() >= suffix.size() &&
         std::string_view(text).substr(text.size() - suffix.size()) == suffix;
}

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
  require(access_ != Access::write_only, "read", *this);
  const Deadline deadline = deadline_after(timeout);
  std::string data(count, '\0');
  std::size_t got = 0;
  while (got < count) {
    const std::size_t n = read_some(&data[got], count - got, deadline);
    if (n == 0) break;
    got += n;
  }
  data.resize(got);
  return data;
}

std::string Port::read_until(std::string_view delimiter, std::size_t max_bytes) {
  return read_until(delimiter, max_bytes, timeout_);
}

// Reads one byte at a time so that nothing past the delimiter is consumed:
// the port keeps no read-ahead buffer, which keeps available() and the
// pollable native_handle() truthful.
std::string Port::read_until(std::string_view delimiter, std::size_t max_bytes,
                             Timeout timeout) {
  require(access_ != Access::write_only, "read", *this);
  const Deadline deadline = deadline_after(timeout);
  std::string data;
  while (data.size() < max_bytes) {
    char byte;
    if (read_some(&byte, 1, deadline) == 0) break;
    data.push_back(byte);
    if (!delimiter.empty() && ends_with(data, delimiter)) break;
  }
  return data;
}

std::string Port::read_line(std::size_t max_bytes) {
  return read_until("\n", max_bytes);
}

std::size_t Port::skip(std::size_t count) {
  require(access_ != Access::write_only, "read", *this);
  const Deadline deadline = deadline_after(timeout_);
  char scratch[4096];
  std::size_t skipped = 0;
  while (skipped < count) {
    const std::size_t want = std::min(sizeof scratch, count - skipped);
    const std::size_t n = read_some(scratch, want, deadline);
    if (n == 0) break;
    skipped += n;
  }
  return skipped;
}

bool Port::skip_until(std::string_view delimiter) {
  const std::string data = read_until(delimiter, unlimited);
  return ends_with(data, delimiter);
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
