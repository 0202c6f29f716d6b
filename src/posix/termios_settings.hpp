// Translation between SerialSettings and termios, shared by the serial port
// (which programs a device) and the pty port (which reports what its client
// programmed on the terminal).
#pragma once

#include <termios.h>

#include <optional>
#include <string>

#include "wiretape/port.hpp"

namespace wiretape::detail {

// The Bxxx constant for `baud`, if the system has one.
std::optional<speed_t> standard_speed(unsigned baud);
// The rate a Bxxx constant stands for (0 if unknown).
unsigned baud_of_speed(speed_t speed);

// Raw mode: no echo, no line editing, no signals, no translation, 8 bits.
void make_raw(termios& settings);

// Writes data bits, stop bits, parity and flow control into `settings`
// (the rate is programmed separately). Throws PortError(ENOTSUP) for what
// the system cannot express (mark/space parity without CMSPAR).
void apply_line_settings(termios& settings, const SerialSettings& wanted,
                         const std::string& where);

// The line settings in `settings`, with `baud` as the rate.
SerialSettings line_settings_of(const termios& settings, unsigned baud);

// Programs `settings` with rate `baud` on terminal `fd` (standard rates with
// cfsetispeed/cfsetospeed, others through the platform layer). Throws
// PortError naming `where` and the rate when the system refuses.
void program_terminal(int fd, termios settings, unsigned baud,
                      const std::string& where);

// The output rate terminal `fd` runs at, custom rates included.
unsigned current_baud(int fd, const termios& settings);

// "8N1", "7E2" ... with the flow control appended when not none.
std::string frame_name(const SerialSettings& settings);

}  // namespace wiretape::detail
