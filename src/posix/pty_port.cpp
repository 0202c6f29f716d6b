// type=pty: a pseudo-terminal whose device side this port is. A program
// opens the terminal (the path in description(), or `link`) as if it were a
// serial device; what it writes is read here and vice versa.
#include <grp.h>
#include <sys/ioctl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <vector>

#include "posix/transports.hpp"
#include "posix/fd_port.hpp"
#include "posix/platform.hpp"
#include "posix/pty_terminal.hpp"
#include "posix/syscalls.hpp"
#include "posix/termios_settings.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

namespace {

class PtyPort final : public FdPort {
 public:
  PtyPort(sys::UniqueFd master, sys::UniqueFd terminal, std::string path)
      : FdPort(std::move(master), describe(path, "")),
        terminal_(std::move(terminal)),
        path_(std::move(path)) {}
  ~PtyPort() override { close(); }

  std::string type() const override { return "pty"; }
  PortCapabilities capabilities() const override { PortCapabilities c; c.terminal_settings = c.output_pollable = true; return c; }

  // What the client set on the terminal. Linux forces 8 data bits and no
  // parity on a pty, so only the rate and stop bits carry information there.
  // Read before every read of the client's bytes (PtyEndpoint): one system
  // call where the platform allows.
  SerialSettings serial_settings() const override {
    termios settings{};
    platform::LineFlags flags;
    if (platform::get_line_flags(terminal_.get(), flags) == 0) {
      settings.c_cflag = static_cast<tcflag_t>(flags.cflag);
      settings.c_iflag = static_cast<tcflag_t>(flags.iflag);
      return line_settings_of(settings, flags.baud != 0
                                            ? flags.baud
                                            : baud_of_speed(cfgetospeed(&settings)));
    }
    if (sys::tcgetattr(terminal_.get(), &settings) != 0) {
      raise_os_error(errno, description(), "reading the terminal settings");
    }
    return line_settings_of(settings, current_baud(terminal_.get(), settings));
  }

  const std::string& terminal_path() const { return path_; }

  void set_packet_mode() {
    int on = 1;
    if (sys::ioctl(native_handle(), TIOCPKT, &on) != 0) {
      raise_os_error(errno, description(), "putting the pty in packet mode");
    }
  }

  std::size_t terminal_unread() const {
    int unread = 0;
    if (sys::ioctl(terminal_.get(), FIONREAD, &unread) != 0 || unread < 0) return 0;
    return static_cast<std::size_t>(unread);
  }

  // Through the descriptor held open, not the path: the node cannot be
  // swapped in between.
  void set_access(mode_t mode, gid_t group) {
    if (sys::fchown(terminal_.get(), static_cast<uid_t>(-1), group) != 0) {
      raise_os_error(errno, description(),
                     "giving the terminal to group " + std::to_string(group));
    }
    if (sys::fchmod(terminal_.get(), mode & 0777) != 0) {
      raise_os_error(errno, description(), "setting the terminal's mode");
    }
  }

  // The link appears last: a client may open the terminal through it at
  // once. A stale link from an earlier run is replaced; anything else is
  // refused.
  void publish_link(const std::string& link) {
    if (!link_.empty()) throw std::logic_error(description() + ": the link is made once");
    struct stat existing {};
    if (sys::lstat(link.c_str(), &existing) == 0) {
      if (!S_ISLNK(existing.st_mode)) {
        throw PortError(EEXIST, "pty: link=" + link +
                                    " exists and is not a symbolic link; "
                                    "refusing to replace it");
      }
      sys::unlink(link.c_str());
    }
    if (sys::symlink(path_.c_str(), link.c_str()) != 0) {
      raise_os_error(errno, "pty: link=" + link, "creating the symbolic link");
    }
    link_ = link;
    set_description(describe(path_, link_));
  }

  void set_dtr(bool) override { no_modem_lines(); }
  void set_rts(bool) override { no_modem_lines(); }
  bool cts() override { no_modem_lines(); }
  bool dsr() override { no_modem_lines(); }
  bool ri() override { no_modem_lines(); }
  bool cd() override { no_modem_lines(); }

 protected:
  void on_close() override {
    if (!link_.empty()) {
      // Remove the link only if it is still ours.
      char target[4096];
      const ssize_t n = sys::readlink(link_.c_str(), target, sizeof target - 1);
      if (n > 0 && std::string(target, static_cast<std::size_t>(n)) == path_) {
        sys::unlink(link_.c_str());
      }
    }
    terminal_.reset();
  }

 private:
  static std::string describe(const std::string& path,
                              const std::string& link) {
    return "pty " + path + (link.empty() ? "" : " (link " + link + ")");
  }

  [[noreturn]] void no_modem_lines() const {
    throw PortError(ENOTTY, description() +
                                ": a pseudo-terminal has no modem lines "
                                "(DTR, RTS, CTS, DSR, RI, CD)");
  }

  // Held open so that a client closing and reopening the terminal does not
  // hang up the device side.
  sys::UniqueFd terminal_;
  std::string path_;
  std::string link_;
};

}  // namespace

std::string pty_terminal_path(const Port& port) {
  const auto* pty = dynamic_cast<const PtyPort*>(&port);
  return pty ? pty->terminal_path() : std::string();
}

std::optional<gid_t> find_group(const std::string& name_or_id) {
  if (name_or_id.empty()) return std::nullopt;
  if (name_or_id.find_first_not_of("0123456789") == std::string::npos) {
    errno = 0;
    char* end = nullptr;
    const unsigned long long id = std::strtoull(name_or_id.c_str(), &end, 10);
    // (gid_t)-1 means "leave the group" to chown: not a group.
    if (errno != 0 || id >= static_cast<unsigned long long>(static_cast<gid_t>(-1))) {
      return std::nullopt;
    }
    return static_cast<gid_t>(id);
  }
  std::vector<char> buffer(4096);
  for (;;) {
    group entry{};
    group* found = nullptr;
    const int error = ::getgrnam_r(name_or_id.c_str(), &entry, buffer.data(), buffer.size(), &found);
    if (error == ERANGE && buffer.size() < (1u << 20)) {
      buffer.resize(buffer.size() * 2);
      continue;
    }
    if (error != 0 || found == nullptr) return std::nullopt;
    return found->gr_gid;
  }
}

void set_terminal_access(Port& port, mode_t mode, gid_t group) {
  auto* pty = dynamic_cast<PtyPort*>(&port);
  if (pty == nullptr) {
    throw std::logic_error("set_terminal_access: " + port.description() + " is not a pty");
  }
  pty->set_access(mode, group);
}

void set_packet_mode(Port& port) {
  auto* pty = dynamic_cast<PtyPort*>(&port);
  if (pty == nullptr) {
    throw std::logic_error("set_packet_mode: " + port.description() + " is not a pty");
  }
  pty->set_packet_mode();
}

void publish_terminal_link(Port& port, const std::string& link) {
  auto* pty = dynamic_cast<PtyPort*>(&port);
  if (pty == nullptr) {
    throw std::logic_error("publish_terminal_link: " + port.description() + " is not a pty");
  }
  pty->publish_link(link);
}

std::size_t terminal_unread(const Port& port) {
  const auto* pty = dynamic_cast<const PtyPort*>(&port);
  return pty ? pty->terminal_unread() : 0;
}

std::unique_ptr<Port> open_pty(Options& options) {
  const std::string link = options.take_string("link");
  options.finish("pty");

  sys::UniqueFd master(sys::posix_openpt(O_RDWR | O_NOCTTY));
  if (!master) raise_os_error(errno, "pty", "creating a pseudo-terminal");
  if (::grantpt(master.get()) != 0 || ::unlockpt(master.get()) != 0) {
    raise_os_error(errno, "pty", "unlocking the pseudo-terminal");
  }
  const std::string path = platform::terminal_path(master.get());
  if (path.empty()) raise_os_error(errno, "pty", "naming the terminal");

  sys::UniqueFd terminal(
      sys::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC));
  if (!terminal) raise_os_error(errno, "pty " + path, "opening the terminal");
  termios settings{};
  if (sys::tcgetattr(terminal.get(), &settings) != 0) {
    raise_os_error(errno, "pty " + path, "reading the terminal settings");
  }
  make_raw(settings);
  if (sys::tcsetattr(terminal.get(), TCSANOW, &settings) != 0) {
    raise_os_error(errno, "pty " + path, "putting the terminal in raw mode");
  }

  auto port = std::make_unique<PtyPort>(std::move(master), std::move(terminal), path);
  if (!link.empty()) port->publish_link(link);
  return port;
}

}  // namespace wiretape::detail
