#include "posix/fd_port.hpp"

#include <sys/ioctl.h>

#include <cerrno>
#include <chrono>
#include <climits>

#include "wiretape/errors.hpp"

namespace wiretape::detail {

bool is_disconnect(int errno_value) {
  switch (errno_value) {
    case ENXIO:
    case ENODEV:
    case EIO:
    case EPIPE:
    case ECONNRESET:
    case ECONNABORTED:
    case ENOTCONN:
    case ESHUTDOWN:
      return true;
    default:
      return false;
  }
}

void raise_os_error(int errno_value, const std::string& where,
                    const std::string& operation) {
  const std::string message = where + ": " + operation + " failed";
  if (is_disconnect(errno_value)) {
    throw PortClosed(message + ", the device went away", errno_value);
  }
  throw PortError(errno_value, message);
}

int poll_timeout_ms(Deadline deadline) {
  if (!deadline) return -1;
  const auto left = *remaining(deadline);
  const auto ms = std::chrono::ceil<std::chrono::milliseconds>(left).count();
  return ms > INT_MAX ? INT_MAX : static_cast<int>(ms);
}

void make_nonblocking(int fd, const std::string& where) {
  const int flags = sys::fcntl(fd, F_GETFL);
  if (flags < 0 || sys::fcntl(fd, F_SETFL, flags | O_NONBLOCK) < 0) {
    raise_os_error(errno, where, "making the descriptor non-blocking");
  }
  const int fd_flags = sys::fcntl(fd, F_GETFD);
  if (fd_flags >= 0) sys::fcntl(fd, F_SETFD, fd_flags | FD_CLOEXEC);
}

FdPort::FdPort(sys::UniqueFd fd, std::string description)
    : fd_(std::move(fd)), description_(std::move(description)) {
  make_nonblocking(fd_.get(), description_);
  int fds[2];
  if (sys::pipe(fds) != 0) {
    raise_os_error(errno, description_, "creating the wake-up pipe");
  }
  wake_read_.reset(fds[0]);
  wake_write_.reset(fds[1]);
  make_nonblocking(fds[0], description_);
  make_nonblocking(fds[1], description_);
}

FdPort::~FdPort() {
  // Concrete ports with an on_close() close in their own destructor; this
  // one closes what is left.
  fd_.reset();
  wake_read_.reset();
  wake_write_.reset();
}

void FdPort::set_description(std::string description) {
  std::lock_guard<std::mutex> lock(description_mutex_);
  description_ = std::move(description);
}

std::string FdPort::description() const {
  std::lock_guard<std::mutex> lock(description_mutex_);
  return description_;
}

int FdPort::native_handle() const { return closed_ ? -1 : fd_.get(); }

// Every read and write passes through here, so it takes no lock (two
// lock/unlock pairs and a notify a call were a tenth of record --pty's
// instructions a MB, docs/benchmarks.md): the call is counted first and closed_
// read after, close() sets closed_ first and reads the count after (both
// sequentially consistent), so either the call sees closed_ or close()
// sees the call and waits for it. Only a call that leaves after close()
// began takes the mutex, to wake it.
FdPort::Call::Call(FdPort& port) : port_(port) {
  port_.calls_in_flight_.fetch_add(1);
  if (port_.closed_.load()) {
    leave();
    port_.raise_closed();
  }
}

FdPort::Call::~Call() { leave(); }

void FdPort::Call::leave() {
  if (port_.calls_in_flight_.fetch_sub(1) == 1 && port_.closed_.load()) {
    std::lock_guard<std::mutex> lock(port_.mutex_);
    port_.idle_.notify_all();
  }
}

void FdPort::raise_closed() const {
  throw PortClosed(description() + ": the port is closed");
}

void FdPort::fail(int errno_value, const std::string& operation) {
  if (is_disconnect(errno_value)) gone_ = true;
  raise_os_error(errno_value, description(), operation);
}

void FdPort::close() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (closed_) return;
    closed_ = true;
  }
  const char token = 'x';
  while (sys::write(wake_write_.get(), &token, 1) < 0 && errno == EINTR) {
  }
  {
    std::unique_lock<std::mutex> lock(mutex_);
    idle_.wait(lock, [this] { return calls_in_flight_.load() == 0; });
  }
  on_close();
  fd_.reset();
  wake_read_.reset();
  wake_write_.reset();
}

ssize_t FdPort::transfer_in(void* buffer, std::size_t size) {
  return sys::read(fd_.get(), buffer, size);
}

ssize_t FdPort::transfer_out(const void* data, std::size_t size) {
  return sys::write(fd_.get(), data, size);
}

bool FdPort::wait_for(short events, Deadline deadline) {
  for (;;) {
    pollfd fds[2] = {{fd_.get(), events, 0}, {wake_read_.get(), POLLIN, 0}};
    const int ready = sys::poll(fds, 2, poll_timeout_ms(deadline));
    if (closed_) raise_closed();
    if (ready < 0) {
      if (errno == EINTR) continue;
      fail(errno, "poll");
    }
    if (ready == 0) {
      if (deadline && std::chrono::steady_clock::now() >= *deadline) {
        return false;
      }
      continue;
    }
    if (fds[0].revents & POLLNVAL) fail(EBADF, "poll");
    if (fds[0].revents & (events | POLLHUP | POLLERR)) return true;
  }
}

ssize_t FdPort::transfer_peek(void*, std::size_t) {
  errno = ENOTSUP;
  return -1;
}

std::size_t FdPort::read_some(void* buffer, std::size_t size,
                              Deadline deadline) {
  return *receive(buffer, size, deadline, Receive::consume);
}

std::optional<std::size_t> FdPort::peek_some(void* buffer, std::size_t size,
                                             Deadline deadline) {
  return receive(buffer, size, deadline, Receive::peek);
}

std::optional<std::size_t> FdPort::receive(void* buffer, std::size_t size,
                                           Deadline deadline, Receive how) {
  Call call(*this);
  for (;;) {
    if (gone_) {
      throw PortClosed(description() + ": the device went away");
    }
    const ssize_t n = how == Receive::peek ? transfer_peek(buffer, size)
                                           : transfer_in(buffer, size);
    if (n > 0) return static_cast<std::size_t>(n);
    if (n == 0) {
      if (size == 0) return 0;
      if (zero_read_is_end_of_file()) {
        gone_ = true;
        throw PortClosed(description() +
                         ": the device closed the connection (end of file)");
      }
      // An empty datagram: nothing to return; a peek drops it, or it would
      // see it again forever.
      if (how == Receive::peek) transfer_in(buffer, 0);
      continue;
    }
    const int err = errno;
    if (err == EINTR) continue;
    if (how == Receive::peek && err == ENOTSUP) return std::nullopt;
    if (err == EAGAIN || err == EWOULDBLOCK) {
      // A deadline already past (a read with timeout 0) was answered by the
      // read just tried: a poll would only add a system call to every read
      // that finds nothing, which the bridge makes to empty a terminal.
      if (deadline && std::chrono::steady_clock::now() >= *deadline) return 0;
      if (!wait_for(POLLIN, deadline)) return 0;
      continue;
    }
    fail(err, how == Receive::peek ? "peek" : "read");
  }
}

std::size_t FdPort::write_some(const void* data, std::size_t size,
                               Deadline deadline) {
  Call call(*this);
  for (;;) {
    if (gone_) {
      throw PortClosed(description() + ": the device went away");
    }
    const ssize_t n = transfer_out(data, size);
    if (n > 0 || (n == 0 && size == 0)) return static_cast<std::size_t>(n);
    const int err = n == 0 ? EAGAIN : errno;
    if (err == EINTR) continue;
    if (err == EAGAIN || err == EWOULDBLOCK || err == ENOBUFS) {
      // As for a read: a deadline already past (a write with timeout 0, the
      // bridge's to a full terminal) was answered by the write just tried.
      if (deadline && std::chrono::steady_clock::now() >= *deadline) return 0;
      if (!wait_for(POLLOUT, deadline)) return 0;
      continue;
    }
    fail(err, "write");
  }
}

bool FdPort::wait_readable_until(Deadline deadline) {
  Call call(*this);
  if (gone_) return true;
  return wait_for(POLLIN, deadline);
}

std::size_t FdPort::available() {
  Call call(*this);
  int count = 0;
  if (sys::ioctl(fd_.get(), FIONREAD, &count) != 0) fail(errno, "FIONREAD");
  return count > 0 ? static_cast<std::size_t>(count) : 0;
}

void FdPort::flush_input() {
  Call call(*this);
  if (sys::tcflush(fd_.get(), TCIFLUSH) != 0) fail(errno, "flush_input");
}

void FdPort::flush_output() {
  Call call(*this);
  if (sys::tcflush(fd_.get(), TCOFLUSH) != 0) fail(errno, "flush_output");
}

void FdPort::drain() {
  Call call(*this);
  while (sys::tcdrain(fd_.get()) != 0) {
    if (errno != EINTR) fail(errno, "drain");
  }
}

}  // namespace wiretape::detail
