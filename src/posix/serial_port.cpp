// type=serial: a serial device through termios.
#include <sys/file.h>
#include <sys/ioctl.h>

#include <cerrno>
#include <chrono>
#include <mutex>
#include <thread>

#include "posix/transports.hpp"
#include "posix/fd_port.hpp"
#include "posix/termios_settings.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

namespace {

std::string describe(const std::string& device, const SerialSettings& s) {
  return "serial " + device + " @ " + std::to_string(s.baud) + " " +
         frame_name(s);
}

class SerialPort final : public FdPort {
 public:
  SerialPort(sys::UniqueFd fd, std::string device, SerialSettings settings,
             bool exclusive = false)
      : FdPort(std::move(fd), describe(device, settings)),
        device_(std::move(device)),
        settings_(settings),
        exclusive_(exclusive) {
    configure(settings);
  }
  ~SerialPort() override { close(); }

  std::string type() const override { return "serial"; }
  PortCapabilities capabilities() const override { PortCapabilities c; c.serial_settings = c.modem_lines = c.send_break = c.output_pollable = true; return c; }

 protected:
  // A pseudo-terminal outlives its clients (its master keeps it), and so
  // would the exclusive lock: without this, the next client that is not
  // root gets EBUSY.
  void on_close() override {
    if (exclusive_) sys::ioctl(fd(), TIOCNXCL);
  }

 public:
  void configure(const SerialSettings& wanted) override {
    Call call(*this);
    std::lock_guard<std::mutex> lock(settings_mutex_);
    termios settings{};
    if (sys::tcgetattr(fd(), &settings) != 0) fail(errno, "tcgetattr");
    make_raw(settings);
    apply_line_settings(settings, wanted, description());
    program_terminal(fd(), settings, wanted.baud, description());
    settings_ = wanted;
    set_description(describe(device_, settings_));
  }

  void set_baud(unsigned baud) override {
    SerialSettings wanted = serial_settings();
    wanted.baud = baud;
    configure(wanted);
  }

  SerialSettings serial_settings() const override {
    std::lock_guard<std::mutex> lock(settings_mutex_);
    return settings_;
  }

  void set_dtr(bool level) override { set_line(TIOCM_DTR, level, "set_dtr"); }
  void set_rts(bool level) override { set_line(TIOCM_RTS, level, "set_rts"); }
  bool cts() override { return line(TIOCM_CTS, "cts"); }
  bool dsr() override { return line(TIOCM_DSR, "dsr"); }
  bool ri() override { return line(TIOCM_RI, "ri"); }
  bool cd() override { return line(TIOCM_CD, "cd"); }

  void send_break(std::chrono::milliseconds duration) override {
    Call call(*this);
    if (sys::ioctl(fd(), TIOCSBRK) == 0) {
      std::this_thread::sleep_for(duration);
      if (sys::ioctl(fd(), TIOCCBRK) != 0) fail(errno, "send_break (TIOCCBRK)");
      return;
    }
    // No break ioctl (e.g. a pty): the POSIX call sends a default-length one.
    if (sys::tcsendbreak(fd(), 0) != 0) fail(errno, "send_break");
  }

 private:
  int modem_bits(const char* operation) {
    int bits = 0;
    if (sys::ioctl(fd(), TIOCMGET, &bits) != 0) no_modem_lines(errno, operation);
    return bits;
  }

  bool line(int bit, const char* operation) {
    Call call(*this);
    return (modem_bits(operation) & bit) != 0;
  }

  void set_line(int bit, bool level, const char* operation) {
    Call call(*this);
    int bits = modem_bits(operation);
    bits = level ? (bits | bit) : (bits & ~bit);
    if (sys::ioctl(fd(), TIOCMSET, &bits) != 0) no_modem_lines(errno, operation);
  }

  [[noreturn]] void no_modem_lines(int err, const char* operation) {
    if (err == ENOTTY || err == EINVAL || err == ENOTSUP || err == ENOSYS) {
      throw PortError(err, description() + ": " + operation +
                               ": the device has no modem lines (a "
                               "pseudo-terminal or a port without them)");
    }
    fail(err, operation);
  }

  const std::string device_;
  mutable std::mutex settings_mutex_;
  SerialSettings settings_;
  const bool exclusive_;
};

}  // namespace

std::unique_ptr<Port> open_serial(Options& options) {
  const std::string device = options.take_required("device");
  SerialSettings settings;
  settings.baud = static_cast<unsigned>(options.take_int("baud"));
  settings.data_bits = static_cast<int>(options.take_int("databits"));
  settings.stop_bits = static_cast<int>(options.take_int("stopbits"));
  // take_choice checked the name against the table, whose choices are these.
  settings.parity = parse_parity(options.take_choice("parity")).value_or(Parity::none);
  // flexiport's spelling of RTS/CTS flow control.
  if (options.has("hwflowctrl")) {
    if (options.has("flow")) {
      throw OptionError("hwflowctrl", "options 'hwflowctrl' and 'flow' mean "
                                      "the same thing; give only one");
    }
    const bool hardware = options.take_bool("hwflowctrl");
    options.set("flow", to_string(hardware ? FlowControl::rtscts : FlowControl::none));
  }
  settings.flow = parse_flow_control(options.take_choice("flow")).value_or(FlowControl::none);
  const bool exclusive = options.take_bool("exclusive");
  options.finish("serial");  // reject bad keys before touching the device

  const std::string where = "serial " + device;
  sys::UniqueFd fd(
      sys::open(device.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC));
  if (!fd) {
    const int err = errno;
    std::string hint;
    if (err == EACCES) hint = " (is the user in the group that owns it, e.g. dialout?)";
    if (err == ENOENT) hint = " (no such device; is it plugged in?)";
    throw PortError(err, where + ": cannot open" + hint);
  }
  if (exclusive) {
    if (sys::flock(fd.get(), LOCK_EX | LOCK_NB) != 0) {
      const int err = errno;
      if (err == EWOULDBLOCK) {
        throw PortError(EBUSY, where + ": in use by another program "
                                       "(exclusive=true; give exclusive=false "
                                       "to share it)");
      }
      raise_os_error(err, where, "locking the device (flock)");
    }
    if (sys::ioctl(fd.get(), TIOCEXCL) != 0 && errno != ENOTTY) {
      raise_os_error(errno, where, "TIOCEXCL");
    }
  }
  termios probe{};
  if (sys::tcgetattr(fd.get(), &probe) != 0) {
    const int err = errno;
    if (err == ENOTTY) {
      throw PortError(err, where + ": not a terminal device");
    }
    raise_os_error(err, where, "tcgetattr");
  }
  return std::make_unique<SerialPort>(std::move(fd), device, settings, exclusive);
}

}  // namespace wiretape::detail
