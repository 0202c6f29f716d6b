// The terminal side of a type=pty port, for a bridge that watches the
// terminal being opened and closed by its clients and decides who may open
// it.
#pragma once

#include <sys/types.h>

#include <cstddef>
#include <optional>
#include <string>

namespace wiretape {
class Port;
}

namespace wiretape::detail {

// The path a program opens to reach `port` ("/dev/pts/7"), or "" if `port`
// is not a pseudo-terminal.
std::string pty_terminal_path(const Port& port);

// The group a real serial device belongs to on most systems; a virtual
// device joins it where it exists, so that the same clients may open it.
inline constexpr const char* kSerialDeviceGroup = "dialout";

// The group `name_or_id` names: a group name, or a number taken as a group
// id as it stands (chown accepts ids without a name too). Nothing when no
// group has that name.
std::optional<gid_t> find_group(const std::string& name_or_id);

// Makes the terminal of the pty `port` mode `mode` (permission bits only)
// and group `group`, as a real serial device's node is. PortError when the
// system refuses (not the owner, not a member of the group).
void set_terminal_access(Port& port, mode_t mode, gid_t group);

// Puts the master of the pty `port` in packet mode (TIOCPKT): each read of
// it then starts with a control byte, 0 before data, or TIOCPKT_FLUSHREAD /
// TIOCPKT_FLUSHWRITE alone when the client flushed its input or output.
// For the bridge's pty endpoint only (type=pty reads plain data).
// PortError when the system refuses.
void set_packet_mode(Port& port);

// Makes `link` a symbolic link to the terminal of the pty `port` (opened
// without one), removed when the port closes. A bridge publishes it once it
// is ready to serve: a client that opens the terminal the moment the link
// appears is seen arriving (DESIGN.md section 12). A stale link is
// replaced; a file that is not a link is refused (PortError).
void publish_terminal_link(Port& port, const std::string& link);

// Bytes written to the pty `port` that its client has not read yet (0 when
// that cannot be told).
std::size_t terminal_unread(const Port& port);

}  // namespace wiretape::detail
