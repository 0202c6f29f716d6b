#include "posix/device_identity.hpp"

#include <algorithm>
#include <cerrno>
#include <filesystem>
#include <fstream>
#include <system_error>
#include <vector>

#include "util/hex.hpp"
#include "wiretape/errors.hpp"
#include "util/json.hpp"

namespace wiretape::detail {

namespace {

namespace fs = std::filesystem;

// sysfs attributes are one short line; more than this is not an attribute.
constexpr std::size_t max_attribute_size = 4096;

// Where `path` leads, links followed; empty when it leads nowhere.
fs::path resolved(const fs::path& path) {
  std::error_code error;
  fs::path target = fs::canonical(path, error);
  return error ? fs::path() : target;
}

// A header string made from what the machine wrote: UTF-8 as it is, other
// bytes escaped.
std::string as_header_text(const std::string& bytes) {
  if (!json::invalid_utf8_offset(bytes)) return bytes;
  return escape_bytes(bytes, bytes.size());
}

// The first line of a sysfs attribute with the white space around it
// removed, as pyserial's read_line gives it; empty when it cannot be read.
std::string attribute(const fs::path& folder, const char* name) {
  std::ifstream file(folder / name, std::ios::binary);
  if (!file) return "";
  std::string line;
  std::getline(file, line);
  if (line.size() > max_attribute_size) line.resize(max_attribute_size);
  const auto is_space = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; };
  const auto first = std::find_if_not(line.begin(), line.end(), is_space);
  const auto last = std::find_if_not(line.rbegin(), line.rend(), is_space).base();
  return first < last ? as_header_text(std::string(first, last)) : "";
}

// The /dev/serial/by-id link that leads to `device` (the first by name when
// there are several), as /dev/serial/by-id/NAME; empty when none does.
std::string by_id_name(const fs::path& dev_root, const fs::path& device) {
  std::error_code error;
  std::vector<std::string> names;
  for (fs::directory_iterator entry(dev_root / "serial" / "by-id", error), end;
       !error && entry != end; entry.increment(error)) {
    if (resolved(entry->path()) == device) names.push_back(entry->path().filename().string());
  }
  if (names.empty()) return "";
  return "/dev/serial/by-id/" + as_header_text(*std::min_element(names.begin(), names.end()));
}

}  // namespace

std::optional<DeviceIdentity> read_device_identity(const std::string& device_path,
                                                   const std::string& sysfs_root,
                                                   const std::string& dev_root) {
  const fs::path device = resolved(device_path);
  if (device.empty()) return std::nullopt;
  DeviceIdentity identity;
  identity.kernel_name = device.filename().string();
  // A pty or a virtual console has a class/tty entry but no device link.
  const fs::path device_folder =
      resolved(fs::path(sysfs_root) / "class" / "tty" / identity.kernel_name / "device");
  if (device_folder.empty()) return std::nullopt;
  identity.kernel_name = as_header_text(identity.kernel_name);
  identity.subsystem = as_header_text(resolved(device_folder / "subsystem").filename().string());
  // pyserial's layout: a converter's tty device sits in its USB interface's
  // folder, a CDC ACM tty's device is the interface; the USB device holds both.
  fs::path interface_folder;
  if (identity.subsystem == "usb-serial") {
    interface_folder = device_folder.parent_path();
  } else if (identity.subsystem == "usb") {
    interface_folder = device_folder;
  }
  if (!interface_folder.empty()) {
    const fs::path usb_device = interface_folder.parent_path();
    identity.vendor_id = attribute(usb_device, "idVendor");
    identity.product_id = attribute(usb_device, "idProduct");
    identity.serial_number = attribute(usb_device, "serial");
    identity.manufacturer = attribute(usb_device, "manufacturer");
    identity.product = attribute(usb_device, "product");
    identity.interface = attribute(interface_folder, "interface");
    identity.location = as_header_text(interface_folder.filename().string());
  }
  identity.by_id = by_id_name(dev_root, device);
  return identity;
}

namespace {

// A folder name taken from a recording that stays a name in the tree: the
// characters sysfs names are made of, not "." or "..".
bool safe_folder_name(std::string_view name) {
  if (name.empty() || name == "." || name == ".." || name.size() > 64) return false;
  for (const char c : name) {
    const bool allowed = (c >= '0' && c <= '9') || (c >= 'a' && c <= 'z') ||
                         (c >= 'A' && c <= 'Z') || c == '-' || c == '_' || c == '.' || c == ':';
    if (!allowed) return false;
  }
  return true;
}

void create_folders(const fs::path& folder) {
  std::error_code error;
  fs::create_directories(folder, error);
  if (error) {
    throw PortError(error.value(), "cannot make the device tree folder " + folder.string());
  }
}

void create_link(const fs::path& target, const fs::path& link) {
  std::error_code error;
  fs::create_symlink(target, link, error);
  if (error) throw PortError(error.value(), "cannot make the device tree link " + link.string());
}

void write_attribute(const fs::path& folder, const char* name, const std::string& value) {
  std::ofstream file(folder / name, std::ios::binary | std::ios::trunc);
  file << value << '\n';
  if (!file.flush()) {
    throw PortError(errno, "cannot write the device tree attribute " + (folder / name).string());
  }
}

}  // namespace

std::string presented_tty_name(const DeviceIdentity& identity,
                               const std::string& device_path) {
  const fs::path path(device_path);
  if (path.parent_path() == "/dev" && safe_folder_name(path.filename().string())) {
    return path.filename().string();
  }
  return safe_folder_name(identity.kernel_name) ? identity.kernel_name : std::string();
}

std::string write_device_tree(const DeviceIdentity& identity, const std::string& root,
                              const std::string& tty_name) {
  if (!safe_folder_name(tty_name)) {
    throw OptionError("tty", "the presented device's name \"" + escape_bytes(tty_name) +
                                 "\" is not a terminal's name under /dev (as ttyACM0)");
  }
  const fs::path sysfs = root;
  const std::string subsystem =
      safe_folder_name(identity.subsystem) ? identity.subsystem : std::string("usb");
  const bool usb = subsystem == "usb" || subsystem == "usb-serial";
  // The USB interface's name is BUS-PORTS:CONFIG.INTERFACE, inside the USB
  // device's folder BUS-PORTS.
  std::string location =
      safe_folder_name(identity.location) && identity.location.find(':') != std::string::npos
          ? identity.location
          : std::string("1-1:1.0");
  const fs::path usb_device = sysfs / "devices" / "wiretape" / "usb1" /
                              location.substr(0, location.find(':'));
  const fs::path interface_folder = usb_device / location;
  fs::path device_folder;
  if (subsystem == "usb") {
    device_folder = interface_folder;
  } else if (subsystem == "usb-serial") {
    device_folder = interface_folder / tty_name;
  } else {
    device_folder = sysfs / "devices" / "wiretape" / subsystem / tty_name;
  }
  const fs::path tty_folder = device_folder / "tty" / tty_name;
  create_folders(tty_folder);
  create_folders(sysfs / "bus" / subsystem);
  create_folders(sysfs / "class" / "tty");
  create_link(sysfs / "bus" / subsystem, device_folder / "subsystem");
  create_link(device_folder, tty_folder / "device");
  create_link(tty_folder, sysfs / "class" / "tty" / tty_name);
  if (usb) {
    // pyserial reads the ids as numbers: an id not recorded reads as 0.
    write_attribute(usb_device, "idVendor", identity.vendor_id.empty() ? "0000" : identity.vendor_id);
    write_attribute(usb_device, "idProduct",
                    identity.product_id.empty() ? "0000" : identity.product_id);
    // As the kernel writes it; pyserial needs a number here.
    write_attribute(usb_device, "bNumInterfaces", " 1");
    // Absent attributes stay absent: pyserial then reports None, as on the
    // recording machine.
    if (!identity.serial_number.empty()) {
      write_attribute(usb_device, "serial", identity.serial_number);
    }
    if (!identity.manufacturer.empty()) {
      write_attribute(usb_device, "manufacturer", identity.manufacturer);
    }
    if (!identity.product.empty()) write_attribute(usb_device, "product", identity.product);
    if (!identity.interface.empty()) {
      write_attribute(interface_folder, "interface", identity.interface);
    }
  }
  return tty_folder.string();
}

}  // namespace wiretape::detail
