// The terminal path of a type=pty port, for a bridge that watches the
// terminal being opened and closed by its clients.
#pragma once

#include <string>

namespace wiretape {
class Port;
}

namespace wiretape::detail {

// The path a program opens to reach `port` ("/dev/pts/7"), or "" if `port`
// is not a pseudo-terminal.
std::string pty_terminal_path(const Port& port);

}  // namespace wiretape::detail
