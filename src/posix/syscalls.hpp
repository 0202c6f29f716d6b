// The operating-system seam. Every transport reaches the OS through these
// functions instead of calling libc directly, so tests can replace any of
// them (inject EINTR, EAGAIN, short writes, disconnects, or watch the termios
// a serial port programs) without a device.
//
// The calls keep the libc signatures and errno convention. The table they
// dispatch to is process-wide; tests swap it with a ScopedOverride before
// starting any threads that use ports, and restore it on scope exit.
#pragma once

#include <fcntl.h>
#include <netdb.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/uio.h>
#include <termios.h>

#include <functional>

namespace wiretape::detail::sys {

struct Table {
  std::function<int(const char* path, int flags, mode_t mode)> open;
  std::function<int(int fd)> close;
  std::function<ssize_t(int fd, void* buffer, size_t size)> read;
  std::function<ssize_t(int fd, const void* data, size_t size)> write;
  std::function<int(pollfd* fds, nfds_t count, int timeout_ms)> poll;
  // ioctl's third argument is always a pointer here (or nullptr).
  std::function<int(int fd, unsigned long request, void* argument)> ioctl;
  std::function<int(int fd, int command, int argument)> fcntl;
  std::function<int(int fd, int operation)> flock;
  std::function<int(int fds[2])> pipe;
  std::function<int(int fd, termios* settings)> tcgetattr;
  std::function<int(int fd, int when, const termios* settings)> tcsetattr;
  std::function<int(int fd, int queue)> tcflush;
  std::function<int(int fd)> tcdrain;
  std::function<int(int fd, int duration)> tcsendbreak;
  std::function<int(int flags)> posix_openpt;
  std::function<int(int domain, int type, int protocol)> socket;
  std::function<int(int fd, const sockaddr* address, socklen_t length)> connect;
  std::function<int(int fd, const sockaddr* address, socklen_t length)> bind;
  std::function<int(int fd, int backlog)> listen;
  std::function<int(int fd, sockaddr* address, socklen_t* length)> accept;
  std::function<ssize_t(int fd, const void* data, size_t size, int flags)> send;
  std::function<ssize_t(int fd, void* buffer, size_t size, int flags)> recv;
  std::function<ssize_t(int fd, const void* data, size_t size, int flags,
                        const sockaddr* to, socklen_t length)>
      sendto;
  std::function<ssize_t(int fd, void* buffer, size_t size, int flags,
                        sockaddr* from, socklen_t* length)>
      recvfrom;
  std::function<ssize_t(int fd, msghdr* message, int flags)> recvmsg;
  std::function<int(int fd, int level, int name, const void* value,
                    socklen_t length)>
      setsockopt;
  std::function<int(int fd, int level, int name, void* value,
                    socklen_t* length)>
      getsockopt;
  std::function<int(int fd, sockaddr* address, socklen_t* length)> getsockname;
  std::function<int(int fd, int how)> shutdown;
  // With the flags the bridge needs set atomically (non-blocking,
  // close-on-exec).
  std::function<int(int fd, sockaddr* address, socklen_t* length, int flags)>
      accept4;
  std::function<int(int fds[2], int flags)> pipe2;
  // Session files.
  std::function<int(int fd, struct stat* info)> fstat;
  std::function<int(const char* path, struct stat* info)> stat;
  // What a path names without following a final symbolic link.
  std::function<int(const char* path, struct stat* info)> lstat;
  std::function<off_t(int fd, off_t offset, int whence)> lseek;
  std::function<ssize_t(int fd, const void* data, size_t size, off_t offset)> pwrite;
  // A session file read at its offsets: one call where lseek and read are two.
  std::function<ssize_t(int fd, void* buffer, size_t size, off_t offset)> pread;
  // Room reserved ahead of a growing file (ENOSYS where there is no fallocate).
  std::function<int(int fd, int mode, off_t offset, off_t length)> fallocate;
  std::function<int(int fd)> fsync;
  std::function<int(int fd, off_t length)> ftruncate;
  // Who may open a pseudo-terminal wiretape creates.
  std::function<int(int fd, mode_t mode)> fchmod;
  std::function<int(int fd, uid_t owner, gid_t group)> fchown;
  std::function<gid_t()> getegid;
  // A unix socket's name, removed.
  std::function<int(const char* path)> unlink;
  // A pty's link (type=pty's link=, the bridge's --pty LINK): the moment it
  // appears is when a client may open the terminal.
  std::function<int(const char* target, const char* link)> symlink;
  std::function<ssize_t(const char* path, char* buffer, size_t size)> readlink;
  // Attaching to a running program (src/attach, DESIGN §26). ptrace's
  // arguments as the raw system call takes them; the result and errno as
  // libc gives them (PTRACE_PEEK* are not used).
  std::function<long(int request, pid_t tid, void* address, void* data)> ptrace;
  std::function<pid_t(pid_t tid, int* status, int options)> waitpid;
  std::function<ssize_t(pid_t pid, const iovec* local, unsigned long local_count,
                        const iovec* remote, unsigned long remote_count)>
      process_vm_readv;
  std::function<ssize_t(pid_t pid, const iovec* local, unsigned long local_count,
                        const iovec* remote, unsigned long remote_count)>
      process_vm_writev;
};

// The real libc calls.
const Table& real();
// The table in force now.
Table& current();

// Replaces the table for its lifetime: copy of the table in force, edit the
// members to fake, restore on destruction.
class ScopedOverride {
 public:
  ScopedOverride();
  ~ScopedOverride();
  ScopedOverride(const ScopedOverride&) = delete;
  ScopedOverride& operator=(const ScopedOverride&) = delete;
  Table* operator->() { return &current(); }
  Table& table() { return current(); }

 private:
  Table saved_;
};

inline int open(const char* path, int flags, mode_t mode = 0) {
  return current().open(path, flags, mode);
}
inline int close(int fd) { return current().close(fd); }
inline ssize_t read(int fd, void* buffer, size_t size) {
  return current().read(fd, buffer, size);
}
inline ssize_t write(int fd, const void* data, size_t size) {
  return current().write(fd, data, size);
}
inline int poll(pollfd* fds, nfds_t count, int timeout_ms) {
  return current().poll(fds, count, timeout_ms);
}
inline int ioctl(int fd, unsigned long request, void* argument = nullptr) {
  return current().ioctl(fd, request, argument);
}
inline int fcntl(int fd, int command, int argument = 0) {
  return current().fcntl(fd, command, argument);
}
inline int flock(int fd, int operation) {
  return current().flock(fd, operation);
}
inline int pipe(int fds[2]) { return current().pipe(fds); }
inline int tcgetattr(int fd, termios* settings) {
  return current().tcgetattr(fd, settings);
}
inline int tcsetattr(int fd, int when, const termios* settings) {
  return current().tcsetattr(fd, when, settings);
}
inline int tcflush(int fd, int queue) { return current().tcflush(fd, queue); }
inline int tcdrain(int fd) { return current().tcdrain(fd); }
inline int tcsendbreak(int fd, int duration) {
  return current().tcsendbreak(fd, duration);
}
inline int posix_openpt(int flags) { return current().posix_openpt(flags); }
inline int socket(int domain, int type, int protocol) {
  return current().socket(domain, type, protocol);
}
inline int connect(int fd, const sockaddr* address, socklen_t length) {
  return current().connect(fd, address, length);
}
inline int bind(int fd, const sockaddr* address, socklen_t length) {
  return current().bind(fd, address, length);
}
inline int listen(int fd, int backlog) { return current().listen(fd, backlog); }
inline int accept(int fd, sockaddr* address, socklen_t* length) {
  return current().accept(fd, address, length);
}
inline ssize_t send(int fd, const void* data, size_t size, int flags) {
  return current().send(fd, data, size, flags);
}
inline ssize_t recv(int fd, void* buffer, size_t size, int flags) {
  return current().recv(fd, buffer, size, flags);
}
inline ssize_t sendto(int fd, const void* data, size_t size, int flags,
                      const sockaddr* to, socklen_t length) {
  return current().sendto(fd, data, size, flags, to, length);
}
inline ssize_t recvfrom(int fd, void* buffer, size_t size, int flags,
                        sockaddr* from, socklen_t* length) {
  return current().recvfrom(fd, buffer, size, flags, from, length);
}
inline ssize_t recvmsg(int fd, msghdr* message, int flags) {
  return current().recvmsg(fd, message, flags);
}
inline int setsockopt(int fd, int level, int name, const void* value,
                      socklen_t length) {
  return current().setsockopt(fd, level, name, value, length);
}
inline int getsockopt(int fd, int level, int name, void* value,
                      socklen_t* length) {
  return current().getsockopt(fd, level, name, value, length);
}
inline int getsockname(int fd, sockaddr* address, socklen_t* length) {
  return current().getsockname(fd, address, length);
}
inline int shutdown(int fd, int how) { return current().shutdown(fd, how); }
inline int accept4(int fd, sockaddr* address, socklen_t* length, int flags) {
  return current().accept4(fd, address, length, flags);
}
inline int pipe2(int fds[2], int flags) { return current().pipe2(fds, flags); }
inline int fstat(int fd, struct stat* info) { return current().fstat(fd, info); }
inline int stat(const char* path, struct stat* info) { return current().stat(path, info); }
inline int lstat(const char* path, struct stat* info) { return current().lstat(path, info); }
inline off_t lseek(int fd, off_t offset, int whence) {
  return current().lseek(fd, offset, whence);
}
inline ssize_t pwrite(int fd, const void* data, size_t size, off_t offset) {
  return current().pwrite(fd, data, size, offset);
}
inline ssize_t pread(int fd, void* buffer, size_t size, off_t offset) {
  return current().pread(fd, buffer, size, offset);
}
inline int fallocate(int fd, int mode, off_t offset, off_t length) {
  return current().fallocate(fd, mode, offset, length);
}
inline int fsync(int fd) { return current().fsync(fd); }
inline int ftruncate(int fd, off_t length) { return current().ftruncate(fd, length); }
inline int fchmod(int fd, mode_t mode) { return current().fchmod(fd, mode); }
inline int fchown(int fd, uid_t owner, gid_t group) {
  return current().fchown(fd, owner, group);
}
inline gid_t getegid() { return current().getegid(); }
inline int unlink(const char* path) { return current().unlink(path); }
inline int symlink(const char* target, const char* link) {
  return current().symlink(target, link);
}
inline ssize_t readlink(const char* path, char* buffer, size_t size) {
  return current().readlink(path, buffer, size);
}

inline long ptrace(int request, pid_t tid, void* address = nullptr, void* data = nullptr) {
  return current().ptrace(request, tid, address, data);
}
inline pid_t waitpid(pid_t tid, int* status, int options) {
  return current().waitpid(tid, status, options);
}
inline ssize_t process_vm_readv(pid_t pid, const iovec* local, unsigned long local_count,
                                const iovec* remote, unsigned long remote_count) {
  return current().process_vm_readv(pid, local, local_count, remote, remote_count);
}
inline ssize_t process_vm_writev(pid_t pid, const iovec* local, unsigned long local_count,
                                 const iovec* remote, unsigned long remote_count) {
  return current().process_vm_writev(pid, local, local_count, remote, remote_count);
}

// Closes a descriptor once, keeping errno (for clean-up paths).
void close_quietly(int fd);

// An owned file descriptor, closed through the seam.
class UniqueFd {
 public:
  UniqueFd() = default;
  explicit UniqueFd(int fd) : fd_(fd) {}
  ~UniqueFd() { reset(); }
  UniqueFd(UniqueFd&& other) noexcept : fd_(other.release()) {}
  UniqueFd& operator=(UniqueFd&& other) noexcept {
    if (this != &other) reset(other.release());
    return *this;
  }
  UniqueFd(const UniqueFd&) = delete;
  UniqueFd& operator=(const UniqueFd&) = delete;
  int get() const noexcept { return fd_; }
  explicit operator bool() const noexcept { return fd_ >= 0; }
  int release() noexcept {
    const int fd = fd_;
    fd_ = -1;
    return fd;
  }
  void reset(int fd = -1) {
    if (fd_ >= 0) close_quietly(fd_);
    fd_ = fd;
  }

 private:
  int fd_ = -1;
};

}  // namespace wiretape::detail::sys
