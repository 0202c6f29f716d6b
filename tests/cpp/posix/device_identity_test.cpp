// Reading a serial device's identity from sysfs and the by-id links (issue
// 24, DESIGN §20 "Identity"), on fake trees laid out as the kernel and udev
// lay them out for a CDC ACM board (an Arduino Uno), an FTDI converter and a
// built-in port, and for a pty.
#include <unistd.h>

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "posix/device_identity.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/session.hpp"

namespace wiretape {
namespace {

namespace fs = std::filesystem;
using detail::read_device_identity;
using test::TempDir;
using test::write_file;

// A machine's /sys and /dev under a temporary folder.
struct FakeMachine {
  TempDir dir;
  std::string sys = dir.file("sys");
  std::string dev = dir.file("dev");

  FakeMachine() {
    fs::create_directories(sys + "/class/tty");
    fs::create_directories(sys + "/bus/usb");
    fs::create_directories(sys + "/bus/usb-serial");
    fs::create_directories(sys + "/bus/pnp");
    fs::create_directories(dev + "/serial/by-id");
  }

  // A tty whose device folder is `device_folder` (under sys/devices) on
  // `subsystem`, with its /dev node.
  void add_tty(const std::string& name, const std::string& device_folder,
               const std::string& subsystem) {
    const std::string folder = sys + "/devices/" + device_folder;
    fs::create_directories(folder);
    fs::create_symlink(sys + "/bus/" + subsystem, folder + "/subsystem");
    // As in sysfs: class/tty/NAME is a link into the device's tty folder,
    // whose `device` link leads back up to the device.
    const std::string tty_folder = folder + "/tty/" + name;
    fs::create_directories(tty_folder);
    fs::create_symlink("../..", tty_folder + "/device");
    fs::create_symlink(tty_folder, sys + "/class/tty/" + name);
    write_file(dev + "/" + name, "");
  }

  void add_usb_device(const std::string& usb_folder, const std::string& vendor,
                      const std::string& product_id, const std::string& serial,
                      const std::string& manufacturer, const std::string& product) {
    const std::string folder = sys + "/devices/" + usb_folder;
    fs::create_directories(folder);
    write_file(folder + "/idVendor", vendor + "\n");
    write_file(folder + "/idProduct", product_id + "\n");
    if (!serial.empty()) write_file(folder + "/serial", serial + "\n");
    write_file(folder + "/manufacturer", manufacturer + "\n");
    write_file(folder + "/product", product + "\n");
  }

  void add_by_id(const std::string& name, const std::string& target) {
    fs::create_symlink("../../" + target, dev + "/serial/by-id/" + name);
  }
};

constexpr char arduino_usb[] = "pci0000:00/0000:00:14.0/usb1/1-2";
constexpr char arduino_interface[] = "pci0000:00/0000:00:14.0/usb1/1-2/1-2:1.0";
constexpr char arduino_by_id[] = "usb-Arduino__www.arduino.cc__0043_85736323838351F0B1C1-if00";

TEST(DeviceIdentity, ReadsACdcAcmBoardAsPyserialDoes) {
  FakeMachine machine;
  machine.add_usb_device(arduino_usb, "2341", "0043", "85736323838351F0B1C1",
                         "Arduino (www.arduino.cc)", "Arduino Uno");
  machine.add_tty("ttyACM0", arduino_interface, "usb");
  write_file(machine.sys + "/devices/" + arduino_interface + "/interface", "  CDC ACM  \n");
  machine.add_by_id(arduino_by_id, "ttyACM0");

  const auto identity = read_device_identity(machine.dev + "/ttyACM0", machine.sys, machine.dev);
  ASSERT_TRUE(identity.has_value());
  EXPECT_EQ(identity->kernel_name, "ttyACM0");
  EXPECT_EQ(identity->subsystem, "usb");
  EXPECT_EQ(identity->vendor_id, "2341");
  EXPECT_EQ(identity->product_id, "0043");
  EXPECT_EQ(identity->serial_number, "85736323838351F0B1C1");
  EXPECT_EQ(identity->manufacturer, "Arduino (www.arduino.cc)");
  EXPECT_EQ(identity->product, "Arduino Uno");
  EXPECT_EQ(identity->interface, "CDC ACM");  // stripped, as pyserial reads it
  EXPECT_EQ(identity->location, "1-2:1.0");
  // As on the machine, not under the tree it was read from.
  EXPECT_EQ(identity->by_id, std::string("/dev/serial/by-id/") + arduino_by_id);
}

TEST(DeviceIdentity, OpenedByItsByIdLinkIsTheSameDevice) {
  FakeMachine machine;
  machine.add_usb_device(arduino_usb, "2341", "0043", "85736323838351F0B1C1",
                         "Arduino (www.arduino.cc)", "Arduino Uno");
  machine.add_tty("ttyACM0", arduino_interface, "usb");
  machine.add_by_id(arduino_by_id, "ttyACM0");

  const auto identity = read_device_identity(
      machine.dev + "/serial/by-id/" + arduino_by_id, machine.sys, machine.dev);
  ASSERT_TRUE(identity.has_value());
  EXPECT_EQ(identity->kernel_name, "ttyACM0");
  EXPECT_EQ(identity->vendor_id, "2341");
  EXPECT_EQ(identity->by_id, std::string("/dev/serial/by-id/") + arduino_by_id);
}

TEST(DeviceIdentity, AConverterTtyLivesInItsUsbInterfaceFolder) {
  FakeMachine machine;
  const std::string usb = "pci0000:00/0000:00:14.0/usb1/1-1/1-1.4";
  machine.add_usb_device(usb, "0403", "6001", "A50285BI", "FTDI", "FT232R USB UART");
  machine.add_tty("ttyUSB0", usb + "/1-1.4:1.0/ttyUSB0", "usb-serial");

  const auto identity = read_device_identity(machine.dev + "/ttyUSB0", machine.sys, machine.dev);
  ASSERT_TRUE(identity.has_value());
  EXPECT_EQ(identity->subsystem, "usb-serial");
  EXPECT_EQ(identity->vendor_id, "0403");
  EXPECT_EQ(identity->product_id, "6001");
  EXPECT_EQ(identity->serial_number, "A50285BI");
  EXPECT_EQ(identity->product, "FT232R USB UART");
  EXPECT_EQ(identity->interface, "");  // this interface has no name
  EXPECT_EQ(identity->location, "1-1.4:1.0");
  EXPECT_EQ(identity->by_id, "");  // udev made no link
}

TEST(DeviceIdentity, ABuiltInPortHasNoUsbIds) {
  FakeMachine machine;
  machine.add_tty("ttyS0", "pnp0/00:05", "pnp");
  const auto identity = read_device_identity(machine.dev + "/ttyS0", machine.sys, machine.dev);
  ASSERT_TRUE(identity.has_value());
  EXPECT_EQ(identity->kernel_name, "ttyS0");
  EXPECT_EQ(identity->subsystem, "pnp");
  EXPECT_EQ(identity->vendor_id, "");
  EXPECT_EQ(identity->serial_number, "");
}

TEST(DeviceIdentity, APtyOrAMissingPathHasNone) {
  FakeMachine machine;
  // A pty's class/tty entry has no device link.
  fs::create_directories(machine.sys + "/class/tty/ptmx");
  fs::create_directories(machine.dev + "/pts");
  write_file(machine.dev + "/pts/3", "");
  EXPECT_FALSE(read_device_identity(machine.dev + "/pts/3", machine.sys, machine.dev));
  write_file(machine.dev + "/ptmx", "");
  EXPECT_FALSE(read_device_identity(machine.dev + "/ptmx", machine.sys, machine.dev));
  EXPECT_FALSE(read_device_identity(machine.dev + "/ttyUSB9", machine.sys, machine.dev));
}

TEST(DeviceIdentity, BytesThatAreNotUtf8AreKeptEscaped) {
  FakeMachine machine;
  machine.add_usb_device(arduino_usb, "2341", "0043", std::string("AB\xff", 3), "Maker",
                         "Board");
  machine.add_tty("ttyACM0", arduino_interface, "usb");
  const auto identity = read_device_identity(machine.dev + "/ttyACM0", machine.sys, machine.dev);
  ASSERT_TRUE(identity.has_value());
  EXPECT_EQ(identity->serial_number, "AB\\xff");
  // And such a header can be written.
  SessionHeader header;
  header.device_identity = identity;
  EXPECT_NE(header.to_json().find("\"serial_number\":\"AB\\\\xff\""), std::string::npos);
}

// The tree replay presents reads back as the identity that was recorded.
TEST(DeviceTree, ReadsBackAsTheRecordedIdentity) {
  for (const char* subsystem : {"usb", "usb-serial"}) {
    SCOPED_TRACE(subsystem);
    TempDir dir;
    DeviceIdentity recorded;
    recorded.kernel_name = "ttyACM0";
    recorded.subsystem = subsystem;
    recorded.vendor_id = "2341";
    recorded.product_id = "0043";
    recorded.serial_number = "85736323838351F0B1C1";
    recorded.manufacturer = "Arduino (www.arduino.cc)";
    recorded.product = "Arduino Uno";
    recorded.interface = "CDC ACM";
    recorded.location = "3-1.2:1.0";
    const std::string tty =
        detail::write_device_tree(recorded, dir.file("sys"), recorded.kernel_name);
    EXPECT_EQ(fs::canonical(dir.file("sys/class/tty/ttyACM0")).string(), tty);
    fs::create_directories(dir.file("dev"));
    write_file(dir.file("dev/ttyACM0"), "");
    const auto read =
        read_device_identity(dir.file("dev/ttyACM0"), dir.file("sys"), dir.file("dev"));
    ASSERT_TRUE(read.has_value());
    EXPECT_EQ(*read, recorded);
  }
}

TEST(DeviceTree, NamesFromTheRecordingStayInsideTheTree) {
  TempDir dir;
  DeviceIdentity hostile;
  hostile.subsystem = "../../../etc";
  hostile.location = "../../x:1.0";
  hostile.vendor_id = "2341";
  const std::string tty = detail::write_device_tree(hostile, dir.file("sys"), "ttyUSB0");
  EXPECT_EQ(tty.rfind(dir.path, 0), 0u) << tty;
  // The kernel's usual names instead: bus usb, interface 1-1:1.0.
  EXPECT_TRUE(fs::exists(dir.file("sys/devices/wiretape/usb1/1-1/idVendor")));
  EXPECT_TRUE(fs::exists(dir.file("sys/bus/usb")));
  EXPECT_THROW(detail::write_device_tree(hostile, dir.file("sys2"), "../ttyUSB0"), OptionError);
  EXPECT_THROW(detail::write_device_tree(hostile, dir.file("sys2"), ""), OptionError);
}

}  // namespace
}  // namespace wiretape
