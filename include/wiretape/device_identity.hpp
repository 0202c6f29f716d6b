// A serial device's identity (DESIGN §20, "Identity"): read from sysfs by
// src/posix/device_identity.cpp, kept in a session's header
// (wiretape/session.hpp), presented again under replay. A header of its
// own so that the code that reads it (posix/) needs no session type.
#pragma once

#include <string>

namespace wiretape {

// A serial device's identity as its machine knew it when it was recorded
// (DESIGN §20, "Identity"; read from sysfs and the /dev/serial/by-id links):
// what a driver that looks for its device by USB ids finds. Empty: not known
// (a device that is not on USB has no ids, a device udev made no by-id link
// for has no by_id).
struct DeviceIdentity {
  std::string kernel_name;  // ttyUSB0, ttyACM0
  // The kernel's bus of the tty's device: "usb" (CDC ACM), "usb-serial"
  // (FTDI, CP210x, ...: a converter driver), "pnp", "platform", ...
  std::string subsystem;
  std::string vendor_id;   // USB idVendor as sysfs writes it: 4 hex digits, 2341
  std::string product_id;  // USB idProduct: 0043
  std::string serial_number;
  std::string manufacturer;
  std::string product;
  std::string interface;  // the USB interface's own name, when it has one
  std::string location;   // the USB interface's sysfs name: 1-1.2:1.0
  std::string by_id;      // /dev/serial/by-id/usb-..., when udev made one

  // Member by member (defined with the member table, src/session/header.cpp).
  bool operator==(const DeviceIdentity& other) const;
  bool operator!=(const DeviceIdentity& other) const { return !(*this == other); }
};

}  // namespace wiretape
