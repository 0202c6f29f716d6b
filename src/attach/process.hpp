// What /proc says of a program to attach to: its threads, its name, its
// tracer, the descriptors it holds and which of them is the device
// (DESIGN §26), and why an attach is refused. Read through the system-call
// seam, so that tests can fake a kernel with Yama.
#pragma once

#include <sys/stat.h>
#include <sys/types.h>

#include <optional>
#include <string>
#include <vector>

#include "wiretape/errors.hpp"

namespace wiretape::detail {

// The thread ids of process `pid` (empty: no such process).
std::vector<pid_t> process_threads(pid_t pid);
// Its command name (/proc/PID/comm), "" when unknown.
std::string process_command(pid_t pid);
// The pid tracing it (TracerPid), 0 for none.
pid_t process_tracer(pid_t pid);
// kernel.yama.ptrace_scope when the kernel has Yama.
std::optional<int> yama_ptrace_scope();

// Why attaching to `pid` failed with `error` (errno of PTRACE_SEIZE), as
// an OptionError of key "attach" (exit 2): no such process, another user's
// without CAP_SYS_PTRACE, kernel.yama.ptrace_scope, already traced.
OptionError attach_refusal(pid_t pid, int error);

enum class DeviceKind { tty, tcp, udp, other_socket, other };
const char* device_kind_name(DeviceKind kind);

// A descriptor the program holds.
struct HeldDescriptor {
  int fd = -1;
  std::string target;  // what /proc/PID/fd/N links to: /dev/pts/3, socket:[1234]
  struct stat info {};
  DeviceKind kind = DeviceKind::other;
};
std::vector<HeldDescriptor> held_descriptors(pid_t pid);

// The device a recording follows: identified by stat, never by path.
struct DeviceMatch {
  DeviceKind kind = DeviceKind::other;
  std::string target;
  bool by_rdev = false;  // a device node: its device number
  dev_t rdev = 0;
  dev_t dev = 0;  // anything else: device and inode
  ino_t ino = 0;
  bool matches(const struct stat& info) const;
};

// The descriptors to record and what they are: those of `path` (matched by
// stat), descriptor `fd` (and its duplicates), or the program's only tty or
// socket. Throws OptionError ("path", "fd" or "attach") naming what the
// program holds when none or several fit.
struct AttachTarget {
  DeviceMatch device;
  std::vector<int> fds;
};
AttachTarget choose_descriptors(pid_t pid, const std::string& path, std::optional<int> fd);

// Whether descriptor `fd` of `pid` is now the device (an open of its path).
bool descriptor_is(pid_t pid, int fd, const DeviceMatch& device);

// Descriptors of io_uring instances the program set up (their traffic
// cannot be seen).
std::vector<int> io_uring_descriptors(pid_t pid);

}  // namespace wiretape::detail
