// The common part of every port built on a file descriptor (serial, pty,
// tcp, udp): a non-blocking descriptor waited on with poll() until the
// call's deadline, EINTR retried, disconnects raised as PortClosed, and a
// wake pipe so that close() from another thread ends a blocked call.
#pragma once

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <string>

#include "posix/syscalls.hpp"
#include "wiretape/port.hpp"

namespace wiretape::detail {

// True for the errno values that mean the device or peer went away.
bool is_disconnect(int errno_value);
// Raises PortClosed for a disconnect, PortError otherwise, as
// "<where>: <operation> failed: <the errno's text>" (system_error_message).
[[noreturn]] void raise_os_error(int errno_value, const std::string& where,
                                 const std::string& operation);
// poll()'s timeout argument for `deadline`: -1 forever, else milliseconds
// rounded up.
int poll_timeout_ms(Deadline deadline);
// Makes `fd` non-blocking and close-on-exec.
void make_nonblocking(int fd, const std::string& where);

class FdPort : public Port {
 public:
  ~FdPort() override;

  std::size_t available() override;
  void flush_input() override;
  void flush_output() override;
  void drain() override;
  void close() override;
  bool is_open() const override { return !closed_.load(); }
  std::string description() const override;
  int native_handle() const override;

 protected:
  // Takes ownership of `fd` (which it makes non-blocking).
  FdPort(sys::UniqueFd fd, std::string description);

  int fd() const noexcept { return fd_.get(); }
  void set_description(std::string description);

  // One transfer attempt, errno convention. Sockets use recv/send.
  virtual ssize_t transfer_in(void* buffer, std::size_t size);
  virtual ssize_t transfer_out(const void* data, std::size_t size);
  // What transfer_in() would return, left in place; -1 with errno ENOTSUP
  // where the descriptor cannot look ahead (a tty). Sockets use MSG_PEEK.
  virtual ssize_t transfer_peek(void* buffer, std::size_t size);
  // Whether a transfer_in() of 0 bytes means end of file (streams) or an
  // empty datagram (udp).
  virtual bool zero_read_is_end_of_file() const { return true; }
  // Called by close() once no call is in flight, before the descriptor is
  // closed. Concrete ports that override it call close() in their own
  // destructor.
  virtual void on_close() {}

  std::size_t read_some(void* buffer, std::size_t size,
                        Deadline deadline) override;
  std::optional<std::size_t> peek_some(void* buffer, std::size_t size,
                                       Deadline deadline) override;
  std::size_t write_some(const void* data, std::size_t size,
                         Deadline deadline) override;
  bool wait_readable_until(Deadline deadline) override;

  // Marks a call in flight: close() waits for it to leave before the
  // descriptor is closed, so a blocked call never polls a reused number.
  class Call {
   public:
    explicit Call(FdPort& port);
    ~Call();
    Call(const Call&) = delete;
    Call& operator=(const Call&) = delete;

   private:
    void leave();
    FdPort& port_;
  };

  // Waits until `events` are ready on the descriptor (true) or the deadline
  // passes (false); raises PortClosed once close() was called.
  bool wait_for(short events, Deadline deadline);
  [[noreturn]] void raise_closed() const;
  [[noreturn]] void fail(int errno_value, const std::string& operation);

 private:
  enum class Receive { consume, peek };
  // read_some and peek_some: waits for data, handles end of file and empty
  // datagrams; std::nullopt when a peek is not supported.
  std::optional<std::size_t> receive(void* buffer, std::size_t size,
                                     Deadline deadline, Receive how);

  sys::UniqueFd fd_;
  sys::UniqueFd wake_read_;
  sys::UniqueFd wake_write_;
  mutable std::mutex description_mutex_;
  std::string description_;
  // close()'s wait for the calls in flight to leave (see Call).
  mutable std::mutex mutex_;
  std::condition_variable idle_;
  std::atomic<int> calls_in_flight_{0};
  std::atomic<bool> closed_{false};
  // The device went away (end of file, hang-up): every later call raises.
  std::atomic<bool> gone_{false};
};

}  // namespace wiretape::detail
