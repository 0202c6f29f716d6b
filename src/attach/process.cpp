#include "attach/process.hpp"

#include <fcntl.h>
#include <sys/sysmacros.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <sstream>

#include "posix/syscalls.hpp"

namespace wiretape::detail {

namespace {

namespace fs = std::filesystem;

std::string proc_path(pid_t pid, const std::string& tail) {
  return "/proc/" + std::to_string(pid) + "/" + tail;
}

// A small file of /proc or /sys, "" when it cannot be read.
std::optional<std::string> read_small_file(const std::string& path) {
  sys::UniqueFd fd(sys::open(path.c_str(), O_RDONLY | O_CLOEXEC));
  if (!fd) return std::nullopt;
  std::string text;
  char buffer[4096];
  for (;;) {
    const ssize_t got = sys::read(fd.get(), buffer, sizeof buffer);
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) break;
    text.append(buffer, static_cast<std::size_t>(got));
    if (text.size() > (16u << 20)) break;
  }
  return text;
}

std::string status_member(pid_t pid, const std::string& name) {
  const std::string status = read_small_file(proc_path(pid, "status")).value_or("");
  std::istringstream lines(status);
  std::string line;
  while (std::getline(lines, line)) {
    if (line.rfind(name + ":", 0) == 0) {
      const auto value = line.find_first_not_of(" \t", name.size() + 1);
      return value == std::string::npos ? "" : line.substr(value);
    }
  }
  return "";
}

std::string link_target(const std::string& path) {
  char buffer[4096];
  const ssize_t length = sys::readlink(path.c_str(), buffer, sizeof buffer);
  return length < 0 ? "" : std::string(buffer, static_cast<std::size_t>(length));
}

// The socket inode of a "socket:[1234]" target.
std::optional<std::string> socket_inode(const std::string& target) {
  if (target.rfind("socket:[", 0) != 0 || target.back() != ']') return std::nullopt;
  return target.substr(8, target.size() - 9);
}

// Whether `inode` is a socket of one of /proc/PID/net/<table> (tcp, udp...).
bool in_socket_table(pid_t pid, const char* table, const std::string& inode) {
  const std::string text = read_small_file(proc_path(pid, std::string("net/") + table)).value_or("");
  std::istringstream lines(text);
  std::string line;
  std::getline(lines, line);  // the column names
  while (std::getline(lines, line)) {
    std::istringstream fields(line);
    std::string field;
    for (int column = 0; column < 10 && fields >> field; ++column) {
    }
    if (field == inode) return true;
  }
  return false;
}

DeviceKind kind_of(pid_t pid, const HeldDescriptor& held) {
  if (S_ISCHR(held.info.st_mode)) {
    const std::string& t = held.target;
    const bool terminal = t.rfind("/dev/pts/", 0) == 0 || t.rfind("/dev/tty", 0) == 0 ||
                          t.rfind("/dev/serial", 0) == 0 || t == "/dev/ptmx";
    return terminal ? DeviceKind::tty : DeviceKind::other;
  }
  if (S_ISSOCK(held.info.st_mode)) {
    const auto inode = socket_inode(held.target);
    if (!inode) return DeviceKind::other_socket;
    if (in_socket_table(pid, "tcp", *inode) || in_socket_table(pid, "tcp6", *inode)) {
      return DeviceKind::tcp;
    }
    if (in_socket_table(pid, "udp", *inode) || in_socket_table(pid, "udp6", *inode)) {
      return DeviceKind::udp;
    }
    return DeviceKind::other_socket;
  }
  return DeviceKind::other;
}

DeviceMatch match_of(const HeldDescriptor& held) {
  DeviceMatch device;
  device.kind = held.kind;
  device.target = held.target;
  device.by_rdev = S_ISCHR(held.info.st_mode) || S_ISBLK(held.info.st_mode);
  device.rdev = held.info.st_rdev;
  device.dev = held.info.st_dev;
  device.ino = held.info.st_ino;
  return device;
}

std::string listing(const std::vector<HeldDescriptor>& held) {
  std::string out;
  for (const HeldDescriptor& d : held) {
    out += (out.empty() ? "" : ", ") + std::to_string(d.fd) + " (" + d.target + ")";
  }
  return out.empty() ? "none" : out;
}

std::vector<HeldDescriptor> ttys_and_sockets(const std::vector<HeldDescriptor>& held) {
  std::vector<HeldDescriptor> out;
  for (const HeldDescriptor& d : held) {
    if (d.kind == DeviceKind::tty || d.kind == DeviceKind::tcp || d.kind == DeviceKind::udp) {
      out.push_back(d);
    }
  }
  return out;
}

}  // namespace

std::vector<pid_t> process_threads(pid_t pid) {
  std::vector<pid_t> tids;
  std::error_code error;
  for (fs::directory_iterator it(proc_path(pid, "task"), error), end; !error && it != end;
       it.increment(error)) {
    tids.push_back(static_cast<pid_t>(std::atoi(it->path().filename().c_str())));
  }
  std::sort(tids.begin(), tids.end());
  return tids;
}

std::string process_command(pid_t pid) {
  std::string comm = read_small_file(proc_path(pid, "comm")).value_or("");
  while (!comm.empty() && comm.back() == '\n') comm.pop_back();
  return comm;
}

pid_t process_tracer(pid_t pid) {
  return static_cast<pid_t>(std::atoi(status_member(pid, "TracerPid").c_str()));
}

std::optional<int> yama_ptrace_scope() {
  const auto text = read_small_file("/proc/sys/kernel/yama/ptrace_scope");
  if (!text || text->empty()) return std::nullopt;
  return std::atoi(text->c_str());
}

OptionError attach_refusal(pid_t pid, int error) {
  const std::string who = "process " + std::to_string(pid);
  const std::string command = process_command(pid);
  const std::string named = command.empty() ? who : who + " (" + command + ")";
  if (error == ESRCH && process_threads(pid).empty()) {
    return OptionError("attach", "cannot attach: there is no " + who);
  }
  if (const pid_t tracer = process_tracer(pid); tracer != 0) {
    return OptionError("attach", "cannot attach to " + named + ": it is already traced by "
                                 "process " + std::to_string(tracer) + " (" +
                                 process_command(tracer) +
                                 "; a debugger or strace?): a process has one tracer");
  }
  if (error == EPERM) {
    if (const auto scope = yama_ptrace_scope(); scope && *scope > 0) {
      return OptionError(
          "attach", "cannot attach to " + named + ": kernel.yama.ptrace_scope is " +
                        std::to_string(*scope) +
                        (*scope >= 3 ? " (no process may be traced: only a reboot lowers it)"
                                     : " (only a parent or CAP_SYS_PTRACE may trace): run "
                                       "wiretape as root, or lower it with `sysctl "
                                       "kernel.yama.ptrace_scope=0`"));
    }
    return OptionError("attach", "cannot attach to " + named +
                                     ": permission denied (another user's process needs "
                                     "CAP_SYS_PTRACE: run wiretape as that user or as root)");
  }
  return OptionError("attach", system_error_message("cannot attach to " + named, error));
}

const char* device_kind_name(DeviceKind kind) {
  switch (kind) {
    case DeviceKind::tty: return "tty";
    case DeviceKind::tcp: return "tcp";
    case DeviceKind::udp: return "udp";
    case DeviceKind::other_socket: return "socket";
    case DeviceKind::other: break;
  }
  return "file";
}

std::vector<HeldDescriptor> held_descriptors(pid_t pid) {
  std::vector<HeldDescriptor> held;
  std::error_code error;
  fs::directory_iterator it(proc_path(pid, "fd"), error);
  if (error) {
    // Another user's process: its descriptors are as closed to us as ptrace.
    const int code = error.value();
    throw attach_refusal(pid, code == EACCES ? EPERM : code == ENOENT ? ESRCH : code);
  }
  for (fs::directory_iterator end; !error && it != end; it.increment(error)) {
    HeldDescriptor d;
    d.fd = std::atoi(it->path().filename().c_str());
    const std::string link = it->path().string();
    d.target = link_target(link);
    if (sys::stat(link.c_str(), &d.info) != 0) continue;  // closed meanwhile
    d.kind = kind_of(pid, d);
    held.push_back(std::move(d));
  }
  std::sort(held.begin(), held.end(),
            [](const HeldDescriptor& a, const HeldDescriptor& b) { return a.fd < b.fd; });
  return held;
}

bool DeviceMatch::matches(const struct stat& info) const {
  if (by_rdev) return (S_ISCHR(info.st_mode) || S_ISBLK(info.st_mode)) && info.st_rdev == rdev;
  return info.st_dev == dev && info.st_ino == ino;
}

AttachTarget choose_descriptors(pid_t pid, const std::string& path, std::optional<int> fd) {
  const std::vector<HeldDescriptor> held = held_descriptors(pid);
  if (held.empty() && process_threads(pid).empty()) throw attach_refusal(pid, ESRCH);
  const std::string who = "process " + std::to_string(pid);
  AttachTarget target;
  if (fd) {
    const auto it = std::find_if(held.begin(), held.end(),
                                 [&](const HeldDescriptor& d) { return d.fd == *fd; });
    if (it == held.end()) {
      throw OptionError("fd", "option --fd: " + who + " holds no descriptor " +
                                  std::to_string(*fd) + "; it holds " + listing(held));
    }
    target.device = match_of(*it);
  } else if (!path.empty()) {
    struct stat info {};
    if (sys::stat(path.c_str(), &info) != 0) {
      throw OptionError("path", system_error_message("option --path: " + path, errno));
    }
    HeldDescriptor wanted;
    wanted.target = path;
    wanted.info = info;
    target.device = match_of(wanted);
    const auto it = std::find_if(held.begin(), held.end(), [&](const HeldDescriptor& d) {
      return target.device.matches(d.info);
    });
    if (it == held.end()) {
      throw OptionError("path", "option --path: " + who + " does not hold " + path +
                                    " open; its ttys and sockets: " +
                                    listing(ttys_and_sockets(held)));
    }
    target.device = match_of(*it);
  } else {
    const std::vector<HeldDescriptor> candidates = ttys_and_sockets(held);
    std::vector<HeldDescriptor> distinct;
    for (const HeldDescriptor& d : candidates) {
      const DeviceMatch m = match_of(d);
      if (std::none_of(distinct.begin(), distinct.end(),
                       [&](const HeldDescriptor& o) { return m.matches(o.info); })) {
        distinct.push_back(d);
      }
    }
    if (distinct.size() != 1) {
      throw OptionError("attach", who + " holds " +
                                      (distinct.empty() ? std::string("no tty or socket")
                                                        : "several ttys and sockets: " +
                                                              listing(candidates)) +
                                      "; say which with --path DEV or --fd N");
    }
    target.device = match_of(distinct.front());
  }
  for (const HeldDescriptor& d : held) {
    if (target.device.matches(d.info)) target.fds.push_back(d.fd);
  }
  return target;
}

bool descriptor_is(pid_t pid, int fd, const DeviceMatch& device) {
  struct stat info {};
  const std::string link = proc_path(pid, "fd/" + std::to_string(fd));
  return sys::stat(link.c_str(), &info) == 0 && device.matches(info);
}

std::vector<int> io_uring_descriptors(pid_t pid) {
  std::vector<int> found;
  std::error_code error;
  for (fs::directory_iterator it(proc_path(pid, "fd"), error), end; !error && it != end;
       it.increment(error)) {
    if (link_target(it->path().string()) == "anon_inode:[io_uring]") {
      found.push_back(std::atoi(it->path().filename().c_str()));
    }
  }
  std::sort(found.begin(), found.end());
  return found;
}

}  // namespace wiretape::detail
