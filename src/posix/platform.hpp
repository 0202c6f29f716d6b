// The few operating-system calls that are not plain POSIX live behind this
// header, in platform.cpp alone, so that other systems need only a new
// implementation of these functions.
#pragma once

#include <string>
#include <vector>

namespace wiretape::detail::platform {

// Programs `baud` as both input and output rate of terminal `fd`, for rates
// that have no standard Bxxx constant (Linux: termios2 with BOTHER). Returns
// 0, or an errno value (ENOTSUP where the system cannot do it).
int set_custom_baud(int fd, unsigned baud);

// The output rate terminal `fd` is programmed with, including custom rates.
// Returns 0 and sets `baud`, or an errno value (ENOTSUP: ask cfgetospeed).
int get_baud(int fd, unsigned& baud);

// The flags of terminal `fd` that say its line (c_cflag, c_iflag) and its
// output rate, custom rates included, in one call (Linux: TCGETS2, where
// tcgetattr() and get_baud() would make two). Returns 0, or an errno value
// (ENOTSUP: use tcgetattr()).
struct LineFlags {
  unsigned cflag = 0;
  unsigned iflag = 0;
  unsigned baud = 0;
};
int get_line_flags(int fd, LineFlags& out);

// The path of the terminal side of pseudo-terminal master `master_fd`, or ""
// with errno set.
std::string terminal_path(int master_fd);

// Flags for send()/sendto() so that writing to a dropped connection gives
// EPIPE instead of killing the process with SIGPIPE.
int no_sigpipe_send_flags();
// Per-socket equivalent where the system has no send flag for it.
void prevent_sigpipe(int socket_fd);

// Asks the system to wake the calling thread from timed sleeps as close to
// the requested time as it can (Linux: timer slack of 1 ns instead of the
// default 50 us, by which the kernel may otherwise defer a wake-up to batch
// timers). Applies to the calling thread only; a no-op where the system has
// no such setting.
void precise_timers_for_this_thread();

// Watches the file at `path` (a pseudo-terminal's terminal side) being opened,
// read, written and closed by any process, so that a pty's client can be seen
// to arrive, take data, send data and leave, in that order (Linux: inotify).
// An open is reported before the open returns and a write after it returned,
// so a reopen and the writes after it are never reported before the close
// that came first. Returns a descriptor that
// polls readable when something happened, or -1 with errno set where the
// system cannot do it.
int watch_opens_and_closes(const std::string& path);
// Whether the watch reports reads too: they cost a wake-up per read of the
// client, so a caller that has learnt what it needed from them stops them.
// Best effort: false where the system cannot change the watch.
bool watch_reads(int watch_fd, const std::string& path, bool reads);
enum class TerminalEvent { opened, read, wrote, closed };
// What happened since the last call, in order. Empty when nothing did.
std::vector<TerminalEvent> read_opens_and_closes(int watch_fd);

}  // namespace wiretape::detail::platform
