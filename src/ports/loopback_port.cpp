// type=loopback: what is written is read back. Used by tests and examples;
// behaves as a device would (timeouts, close from another thread, a pollable
// handle) without touching the operating system beyond one pipe.
#include <algorithm>
#include <cerrno>
#include <condition_variable>
#include <deque>
#include <mutex>

#include "ports/ports.hpp"
#include "posix/fd_port.hpp"
#include "posix/syscalls.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

namespace {

class LoopbackPort final : public Port {
 public:
  LoopbackPort() {
    int fds[2];
    if (sys::pipe(fds) != 0) {
      raise_os_error(errno, "loopback", "creating the readiness pipe");
    }
    signal_read_.reset(fds[0]);
    signal_write_.reset(fds[1]);
    make_nonblocking(fds[0], "loopback");
    make_nonblocking(fds[1], "loopback");
  }
  ~LoopbackPort() override { close(); }

  std::size_t available() override {
    std::lock_guard<std::mutex> lock(mutex_);
    check_open();
    return buffer_.size();
  }

  void flush_input() override {
    std::lock_guard<std::mutex> lock(mutex_);
    check_open();
    buffer_.clear();
    update_signal();
  }
  void flush_output() override {
    std::lock_guard<std::mutex> lock(mutex_);
    check_open();
  }
  void drain() override {
    std::lock_guard<std::mutex> lock(mutex_);
    check_open();
  }

  void close() override {
    std::lock_guard<std::mutex> lock(mutex_);
    if (closed_) return;
    closed_ = true;
    buffer_.clear();
    signal_read_.reset();
    signal_write_.reset();
    changed_.notify_all();
  }
  bool is_open() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return !closed_;
  }
  std::string description() const override { return "loopback"; }
  std::string type() const override { return "loopback"; }
  PortCapabilities capabilities() const override { return {}; }
  int native_handle() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return signal_read_.get();
  }

 protected:
  std::size_t read_some(void* buffer, std::size_t size,
                        Deadline deadline) override {
    std::unique_lock<std::mutex> lock(mutex_);
    if (!wait_for_data(lock, deadline)) return 0;
    const std::size_t n = std::min(size, buffer_.size());
    std::copy_n(buffer_.begin(), n, static_cast<char*>(buffer));
    buffer_.erase(buffer_.begin(), buffer_.begin() + static_cast<long>(n));
    update_signal();
    return n;
  }

  std::optional<std::size_t> peek_some(void* buffer, std::size_t size,
                                       Deadline deadline) override {
    std::unique_lock<std::mutex> lock(mutex_);
    if (!wait_for_data(lock, deadline)) return 0;
    const std::size_t n = std::min(size, buffer_.size());
    std::copy_n(buffer_.begin(), n, static_cast<char*>(buffer));
    return n;
  }

  std::size_t write_some(const void* data, std::size_t size,
                         Deadline) override {
    std::lock_guard<std::mutex> lock(mutex_);
    check_open();
    const auto* bytes = static_cast<const char*>(data);
    buffer_.insert(buffer_.end(), bytes, bytes + size);
    update_signal();
    changed_.notify_all();
    return size;
  }

  bool wait_readable_until(Deadline deadline) override {
    std::unique_lock<std::mutex> lock(mutex_);
    return wait_for_data(lock, deadline);
  }

 private:
  void check_open() const {
    if (closed_) throw PortClosed("loopback: the port is closed");
  }

  bool wait_for_data(std::unique_lock<std::mutex>& lock, Deadline deadline) {
    const auto ready = [this] { return closed_ || !buffer_.empty(); };
    if (deadline) {
      changed_.wait_until(lock, *deadline, ready);
    } else {
      changed_.wait(lock, ready);
    }
    check_open();
    return !buffer_.empty();
  }

  // Keeps exactly one byte in the pipe while data is buffered, so that the
  // pipe polls readable exactly when available() > 0.
  void update_signal() {
    const bool want = !buffer_.empty();
    if (want == signalled_) return;
    char token = 'x';
    if (want) {
      while (sys::write(signal_write_.get(), &token, 1) < 0 && errno == EINTR) {
      }
    } else {
      while (sys::read(signal_read_.get(), &token, 1) < 0 && errno == EINTR) {
      }
    }
    signalled_ = want;
  }

  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<char> buffer_;
  bool closed_ = false;
  bool signalled_ = false;
  sys::UniqueFd signal_read_;
  sys::UniqueFd signal_write_;
};

}  // namespace

std::unique_ptr<Port> open_loopback(Options& options) {
  options.finish("loopback");
  return std::make_unique<LoopbackPort>();
}

}  // namespace wiretape::detail
