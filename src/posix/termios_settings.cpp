#include "posix/termios_settings.hpp"

#include <cerrno>
#include <utility>

#include "posix/fd_port.hpp"
#include "posix/platform.hpp"
#include "posix/syscalls.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

namespace {

const std::pair<unsigned, speed_t> kSpeeds[] = {
    {50, B50},       {75, B75},         {110, B110},     {134, B134},
    {150, B150},     {200, B200},       {300, B300},     {600, B600},
    {1200, B1200},   {1800, B1800},     {2400, B2400},   {4800, B4800},
    {9600, B9600},   {19200, B19200},   {38400, B38400},
#ifdef B57600
    {57600, B57600},
#endif
#ifdef B115200
    {115200, B115200},
#endif
#ifdef B230400
    {230400, B230400},
#endif
#ifdef B460800
    {460800, B460800},
#endif
#ifdef B500000
    {500000, B500000},
#endif
#ifdef B576000
    {576000, B576000},
#endif
#ifdef B921600
    {921600, B921600},
#endif
#ifdef B1000000
    {1000000, B1000000},
#endif
#ifdef B1152000
    {1152000, B1152000},
#endif
#ifdef B1500000
    {1500000, B1500000},
#endif
#ifdef B2000000
    {2000000, B2000000},
#endif
#ifdef B2500000
    {2500000, B2500000},
#endif
#ifdef B3000000
    {3000000, B3000000},
#endif
#ifdef B3500000
    {3500000, B3500000},
#endif
#ifdef B4000000
    {4000000, B4000000},
#endif
};

}  // namespace

std::optional<speed_t> standard_speed(unsigned baud) {
  for (const auto& [rate, speed] : kSpeeds) {
    if (rate == baud) return speed;
  }
  return std::nullopt;
}

unsigned baud_of_speed(speed_t speed) {
  for (const auto& [rate, constant] : kSpeeds) {
    if (constant == speed) return rate;
  }
  return 0;
}

void make_raw(termios& settings) {
  settings.c_iflag &= ~static_cast<tcflag_t>(IGNBRK | BRKINT | PARMRK | ISTRIP |
                                            INLCR | IGNCR | ICRNL | IXON |
                                            IXOFF | IXANY | INPCK);
  settings.c_oflag &= ~static_cast<tcflag_t>(OPOST);
  settings.c_lflag &= ~static_cast<tcflag_t>(ECHO | ECHONL | ICANON | ISIG |
                                            IEXTEN);
  settings.c_cflag &= ~static_cast<tcflag_t>(CSIZE | PARENB);
  settings.c_cflag |= CS8 | CREAD | CLOCAL;
  settings.c_cc[VMIN] = 1;
  settings.c_cc[VTIME] = 0;
}

void apply_line_settings(termios& settings, const SerialSettings& wanted,
                         const std::string& where) {
  (void)where;  // used only where the system lacks a feature
  settings.c_cflag &= ~static_cast<tcflag_t>(CSIZE);
  switch (wanted.data_bits) {
    case 5: settings.c_cflag |= CS5; break;
    case 6: settings.c_cflag |= CS6; break;
    case 7: settings.c_cflag |= CS7; break;
    default: settings.c_cflag |= CS8; break;
  }
  if (wanted.stop_bits == 2) {
    settings.c_cflag |= CSTOPB;
  } else {
    settings.c_cflag &= ~static_cast<tcflag_t>(CSTOPB);
  }
  settings.c_cflag &= ~static_cast<tcflag_t>(PARENB | PARODD);
#ifdef CMSPAR
  settings.c_cflag &= ~static_cast<tcflag_t>(CMSPAR);
#endif
  switch (wanted.parity) {
    case Parity::none: break;
    case Parity::even: settings.c_cflag |= PARENB; break;
    case Parity::odd: settings.c_cflag |= PARENB | PARODD; break;
    case Parity::mark:
    case Parity::space:
#ifdef CMSPAR
      settings.c_cflag |= PARENB | CMSPAR;
      if (wanted.parity == Parity::mark) settings.c_cflag |= PARODD;
      break;
#else
      throw PortError(ENOTSUP, where + ": mark and space parity are not "
                                       "supported on this system");
#endif
  }
#ifdef CRTSCTS
  settings.c_cflag &= ~static_cast<tcflag_t>(CRTSCTS);
#endif
  settings.c_iflag &= ~static_cast<tcflag_t>(IXON | IXOFF | IXANY);
  switch (wanted.flow) {
    case FlowControl::none: break;
    case FlowControl::rtscts:
#ifdef CRTSCTS
      settings.c_cflag |= CRTSCTS;
      break;
#else
      throw PortError(ENOTSUP, where + ": RTS/CTS flow control is not "
                                       "supported on this system");
#endif
    case FlowControl::xonxoff: settings.c_iflag |= IXON | IXOFF; break;
  }
}

SerialSettings line_settings_of(const termios& settings, unsigned baud) {
  SerialSettings out;
  out.baud = baud;
  switch (settings.c_cflag & CSIZE) {
    case CS5: out.data_bits = 5; break;
    case CS6: out.data_bits = 6; break;
    case CS7: out.data_bits = 7; break;
    default: out.data_bits = 8; break;
  }
  out.stop_bits = (settings.c_cflag & CSTOPB) ? 2 : 1;
  out.parity = Parity::none;
  if (settings.c_cflag & PARENB) {
    const bool odd = (settings.c_cflag & PARODD) != 0;
#ifdef CMSPAR
    if (settings.c_cflag & CMSPAR) {
      out.parity = odd ? Parity::mark : Parity::space;
    } else
#endif
    {
      out.parity = odd ? Parity::odd : Parity::even;
    }
  }
  out.flow = FlowControl::none;
#ifdef CRTSCTS
  if (settings.c_cflag & CRTSCTS) out.flow = FlowControl::rtscts;
#endif
  if (out.flow == FlowControl::none && (settings.c_iflag & IXON)) {
    out.flow = FlowControl::xonxoff;
  }
  return out;
}

namespace {

// glibc reports EINVAL when the terminal silently changed the data bits or
// parity it was given, which a pseudo-terminal always does (Linux forces 8N
// on a pty). Everything else having been applied, that is not a failure:
// the device has no framing to program.
bool only_framing_was_forced(int fd, const termios& wanted) {
  if (errno != EINVAL) return false;
  const int saved = errno;
  termios applied{};
  if (sys::tcgetattr(fd, &applied) != 0) {
    errno = saved;
    return false;
  }
  tcflag_t framing = CSIZE | PARENB | PARODD;
#ifdef CMSPAR
  framing |= CMSPAR;
#endif
  const bool same = (applied.c_cflag & ~framing) == (wanted.c_cflag & ~framing) &&
                    applied.c_iflag == wanted.c_iflag &&
                    applied.c_lflag == wanted.c_lflag &&
                    cfgetospeed(&applied) == cfgetospeed(&wanted);
  errno = saved;
  return same;
}

}  // namespace

void program_terminal(int fd, termios settings, unsigned baud,
                      const std::string& where) {
  const auto speed = standard_speed(baud);
  if (speed) {
    if (cfsetispeed(&settings, *speed) != 0 ||
        cfsetospeed(&settings, *speed) != 0) {
      throw PortError(EINVAL, where + ": baud " + std::to_string(baud) +
                                  " is not accepted");
    }
  }
  if (sys::tcsetattr(fd, TCSANOW, &settings) != 0 &&
      !only_framing_was_forced(fd, settings)) {
    raise_os_error(errno, where, "programming the line settings (tcsetattr)");
  }
  if (!speed) {
    const int err = platform::set_custom_baud(fd, baud);
    if (err != 0) {
      throw PortError(err, where + ": baud " + std::to_string(baud) +
                               " is not accepted by the system");
    }
  }
}

unsigned current_baud(int fd, const termios& settings) {
  unsigned baud = 0;
  if (platform::get_baud(fd, baud) == 0 && baud != 0) return baud;
  return baud_of_speed(cfgetospeed(&settings));
}

std::string frame_name(const SerialSettings& settings) {
  static const char parity_letters[] = {'N', 'E', 'O', 'M', 'S'};
  std::string out = std::to_string(settings.data_bits);
  out += parity_letters[static_cast<int>(settings.parity)];
  out += std::to_string(settings.stop_bits);
  if (settings.flow == FlowControl::rtscts) out += " rtscts";
  if (settings.flow == FlowControl::xonxoff) out += " xonxoff";
  return out;
}

}  // namespace wiretape::detail
