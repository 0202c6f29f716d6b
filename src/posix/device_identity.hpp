// Reading a serial device's identity from sysfs and the /dev/serial/by-id
// links (DESIGN §20, "Identity"), as pyserial's list_ports_linux and udev
// read it, so that replay can present the same identity.
#pragma once

#include <optional>
#include <string>

#include "wiretape/device_identity.hpp"

namespace wiretape::detail {

// The identity of the terminal device at `device_path` (a /dev name or a link
// to one, by-id links included), read under `sysfs_root` (/sys) and
// `dev_root` (/dev); tests pass a tree of their own. std::nullopt when the
// path is no terminal with a device behind it in sysfs: a pty, a virtual
// terminal, a path that does not exist. USB members are filled for the
// subsystems "usb" (CDC ACM) and "usb-serial" (converter drivers); the by-id
// name is given as on the machine (/dev/serial/by-id/NAME), whatever
// `dev_root` is. Values that are not UTF-8 are kept escaped (\xNN), as
// payload bytes are shown.
std::optional<DeviceIdentity> read_device_identity(const std::string& device_path,
                                                   const std::string& sysfs_root = "/sys",
                                                   const std::string& dev_root = "/dev");

// The kernel name a presented device has for a command that opens
// `device_path`: the path's own name when it is a terminal's name directly
// under /dev (/dev/ttyUSB3: ttyUSB3), else the recorded kernel name; empty
// when neither is a name the tree can hold.
std::string presented_tty_name(const DeviceIdentity& identity, const std::string& device_path);

// Writes under `root` the sysfs folders and attributes a reader of the tty
// `tty_name` looks at (pyserial's list_ports, read_device_identity), laid
// out as the kernel lays out `identity`'s subsystem, so that replay can
// present the recorded device (DESIGN §20): root/class/tty/TTY_NAME leads to
// the tty's folder, whose `device` link leads (by an absolute path) to the
// device's folder under root/devices. Returns the tty's folder, which stands
// for /sys/class/tty/TTY_NAME. Folder names taken from the identity that
// could leave the tree (a `/`, `..`) are replaced by the kernel's usual ones.
// Throws OptionError (key "tty") when `tty_name` is no file name, PortError
// when the tree cannot be written.
std::string write_device_tree(const DeviceIdentity& identity, const std::string& root,
                              const std::string& tty_name);

}  // namespace wiretape::detail
