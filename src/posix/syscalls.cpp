#include "posix/syscalls.hpp"

#include <sys/file.h>
#include <sys/ioctl.h>
#include <sys/ptrace.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>

namespace wiretape::detail::sys {

namespace {

Table make_real() {
  Table t;
  t.open = [](const char* path, int flags, mode_t mode) {
    return ::open(path, flags, mode);
  };
  t.close = [](int fd) { return ::close(fd); };
  t.read = [](int fd, void* buffer, size_t size) {
    return ::read(fd, buffer, size);
  };
  t.write = [](int fd, const void* data, size_t size) {
    return ::write(fd, data, size);
  };
  t.poll = [](pollfd* fds, nfds_t count, int timeout_ms) {
    return ::poll(fds, count, timeout_ms);
  };
  t.ioctl = [](int fd, unsigned long request, void* argument) {
    return ::ioctl(fd, request, argument);
  };
  t.fcntl = [](int fd, int command, int argument) {
    return ::fcntl(fd, command, argument);
  };
  t.flock = [](int fd, int operation) { return ::flock(fd, operation); };
  t.pipe = [](int fds[2]) { return ::pipe(fds); };
  t.tcgetattr = [](int fd, termios* settings) {
    return ::tcgetattr(fd, settings);
  };
  t.tcsetattr = [](int fd, int when, const termios* settings) {
    return ::tcsetattr(fd, when, settings);
  };
  t.tcflush = [](int fd, int queue) { return ::tcflush(fd, queue); };
  t.tcdrain = [](int fd) { return ::tcdrain(fd); };
  t.tcsendbreak = [](int fd, int duration) {
    return ::tcsendbreak(fd, duration);
  };
  t.posix_openpt = [](int flags) { return ::posix_openpt(flags); };
  t.socket = [](int domain, int type, int protocol) {
    return ::socket(domain, type, protocol);
  };
  t.connect = [](int fd, const sockaddr* address, socklen_t length) {
    return ::connect(fd, address, length);
  };
  t.bind = [](int fd, const sockaddr* address, socklen_t length) {
    return ::bind(fd, address, length);
  };
  t.listen = [](int fd, int backlog) { return ::listen(fd, backlog); };
  t.accept = [](int fd, sockaddr* address, socklen_t* length) {
    return ::accept(fd, address, length);
  };
  t.send = [](int fd, const void* data, size_t size, int flags) {
    return ::send(fd, data, size, flags);
  };
  t.recv = [](int fd, void* buffer, size_t size, int flags) {
    return ::recv(fd, buffer, size, flags);
  };
  t.sendto = [](int fd, const void* data, size_t size, int flags,
                const sockaddr* to, socklen_t length) {
    return ::sendto(fd, data, size, flags, to, length);
  };
  t.recvfrom = [](int fd, void* buffer, size_t size, int flags,
                  sockaddr* from, socklen_t* length) {
    return ::recvfrom(fd, buffer, size, flags, from, length);
  };
  t.recvmsg = [](int fd, msghdr* message, int flags) { return ::recvmsg(fd, message, flags); };
  t.setsockopt = [](int fd, int level, int name, const void* value,
                    socklen_t length) {
    return ::setsockopt(fd, level, name, value, length);
  };
  t.getsockopt = [](int fd, int level, int name, void* value,
                    socklen_t* length) {
    return ::getsockopt(fd, level, name, value, length);
  };
  t.getsockname = [](int fd, sockaddr* address, socklen_t* length) {
    return ::getsockname(fd, address, length);
  };
  t.shutdown = [](int fd, int how) { return ::shutdown(fd, how); };
  t.accept4 = [](int fd, sockaddr* address, socklen_t* length, int flags) {
    return ::accept4(fd, address, length, flags);
  };
  t.pipe2 = [](int fds[2], int flags) { return ::pipe2(fds, flags); };
  t.fstat = [](int fd, struct stat* info) { return ::fstat(fd, info); };
  t.stat = [](const char* path, struct stat* info) { return ::stat(path, info); };
  t.lstat = [](const char* path, struct stat* info) { return ::lstat(path, info); };
  t.lseek = [](int fd, off_t offset, int whence) { return ::lseek(fd, offset, whence); };
  t.pwrite = [](int fd, const void* data, size_t size, off_t offset) {
    return ::pwrite(fd, data, size, offset);
  };
  t.pread = [](int fd, void* buffer, size_t size, off_t offset) {
    return ::pread(fd, buffer, size, offset);
  };
  t.fallocate = [](int fd, int mode, off_t offset, off_t length) {
#ifdef FALLOC_FL_KEEP_SIZE
    return ::fallocate(fd, mode, offset, length);
#else
    (void)fd, (void)mode, (void)offset, (void)length;
    errno = ENOSYS;
    return -1;
#endif
  };
  t.fsync = [](int fd) { return ::fsync(fd); };
  t.ftruncate = [](int fd, off_t length) { return ::ftruncate(fd, length); };
  t.fchmod = [](int fd, mode_t mode) { return ::fchmod(fd, mode); };
  t.fchown = [](int fd, uid_t owner, gid_t group) { return ::fchown(fd, owner, group); };
  t.getegid = [] { return ::getegid(); };
  t.unlink = [](const char* path) { return ::unlink(path); };
  t.symlink = [](const char* target, const char* link) { return ::symlink(target, link); };
  t.readlink = [](const char* path, char* buffer, size_t size) {
    return ::readlink(path, buffer, size);
  };
  t.ptrace = [](int request, pid_t tid, void* address, void* data) {
    return ::ptrace(static_cast<__ptrace_request>(request), tid, address, data);
  };
  t.waitpid = [](pid_t tid, int* status, int options) { return ::waitpid(tid, status, options); };
  t.process_vm_readv = [](pid_t pid, const iovec* local, unsigned long local_count,
                          const iovec* remote, unsigned long remote_count) {
    return ::process_vm_readv(pid, local, local_count, remote, remote_count, 0);
  };
  t.process_vm_writev = [](pid_t pid, const iovec* local, unsigned long local_count,
                           const iovec* remote, unsigned long remote_count) {
    return ::process_vm_writev(pid, local, local_count, remote, remote_count, 0);
  };
  return t;
}

}  // namespace

const Table& real() {
  static const Table table = make_real();
  return table;
}

Table& current() {
  static Table table = real();
  return table;
}

ScopedOverride::ScopedOverride() : saved_(current()) {}
ScopedOverride::~ScopedOverride() { current() = saved_; }

// For platform.cpp, which cannot include <termios.h> next to Linux's
// <asm/termbits.h>.
int ioctl_through_seam(int fd, unsigned long request, void* argument) {
  return current().ioctl(fd, request, argument);
}

ssize_t read_through_seam(int fd, void* out, size_t size) { return current().read(fd, out, size); }

void close_quietly(int fd) {
  const int saved = errno;
  close(fd);
  errno = saved;
}

}  // namespace wiretape::detail::sys
