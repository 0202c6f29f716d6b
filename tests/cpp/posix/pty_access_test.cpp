// Who may open the pty a bridge creates: mode 0660 and group dialout by
// default (the process's group where there is no dialout, or where the
// system refuses it), pty_mode and pty_group otherwise; set through the
// system-call seam on the terminal's node, checked with stat.
#include <sys/stat.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <optional>
#include <string>
#include <vector>

#include "posix/pty_terminal.hpp"
#include "posix/syscalls.hpp"
#include "wiretape/bridge.hpp"
#include "wiretape/errors.hpp"

namespace {

using wiretape::Bridge;
using wiretape::BridgeClientSide;
using wiretape::BridgeOptions;
using wiretape::OptionError;
using wiretape::PortError;
namespace sys = wiretape::detail::sys;

BridgeOptions pty_bridge() {
  BridgeOptions options;
  options.device = "type=loopback";
  options.client_side = BridgeClientSide::pty;
  options.quiet = true;
  return options;
}

struct Node {
  mode_t mode;
  gid_t group;
};

Node node_of(const std::string& path) {
  struct stat info {};
  EXPECT_EQ(::stat(path.c_str(), &info), 0) << path;
  EXPECT_TRUE(S_ISCHR(info.st_mode)) << path;
  return {static_cast<mode_t>(info.st_mode & 07777), info.st_gid};
}

gid_t default_group() {
  const std::optional<gid_t> serial = wiretape::detail::find_group("dialout");
  return serial ? *serial : ::getegid();
}

bool said(const Bridge& bridge, const std::string& words) {
  const std::vector<std::string> messages = bridge.messages();
  return std::any_of(messages.begin(), messages.end(),
                     [&](const std::string& m) { return m.find(words) != std::string::npos; });
}

TEST(PtyAccess, DefaultIsMode0660InTheSerialDeviceGroup) {
  Bridge bridge(pty_bridge());
  bridge.start();
  const Node node = node_of(bridge.pty_path());
  EXPECT_EQ(node.mode, 0660u);
  EXPECT_EQ(node.group, default_group());
}

TEST(PtyAccess, ModeAndGroupAreSetThroughTheSeamOnTheTerminal) {
  sys::ScopedOverride seam;
  std::vector<mode_t> modes;
  std::vector<gid_t> groups;
  seam->fchmod = [&](int fd, mode_t mode) {
    modes.push_back(mode);
    return sys::real().fchmod(fd, mode);
  };
  seam->fchown = [&](int fd, uid_t owner, gid_t group) {
    groups.push_back(group);
    return sys::real().fchown(fd, owner, group);
  };
  BridgeOptions options = pty_bridge();
  options.pty_mode = 0604;
  options.pty_group = std::to_string(::getegid());
  Bridge bridge(options);
  bridge.start();
  EXPECT_EQ(modes, std::vector<mode_t>{0604});
  EXPECT_EQ(groups, std::vector<gid_t>{::getegid()});
  const Node node = node_of(bridge.pty_path());
  EXPECT_EQ(node.mode, 0604u);
  EXPECT_EQ(node.group, ::getegid());
}

TEST(PtyAccess, ARefusedSerialDeviceGroupFallsBackToTheProcessGroupAndSaysSo) {
  const std::optional<gid_t> serial = wiretape::detail::find_group("dialout");
  if (!serial || *serial == ::getegid()) {
    GTEST_SKIP() << "no dialout group distinct from this process's group here";
  }
  sys::ScopedOverride seam;
  seam->fchown = [&](int fd, uid_t owner, gid_t group) {
    if (group == *serial) {
      errno = EPERM;  // as for a user outside that group
      return -1;
    }
    return sys::real().fchown(fd, owner, group);
  };
  Bridge bridge(pty_bridge());
  bridge.start();
  const Node node = node_of(bridge.pty_path());
  EXPECT_EQ(node.mode, 0660u);
  EXPECT_EQ(node.group, ::getegid());
  EXPECT_TRUE(said(bridge, "keeps this process's group"));
}

TEST(PtyAccess, ARefusedChosenGroupFailsTheStart) {
  sys::ScopedOverride seam;
  seam->fchown = [](int, uid_t, gid_t) {
    errno = EPERM;
    return -1;
  };
  BridgeOptions options = pty_bridge();
  options.pty_group = "0";
  Bridge bridge(options);
  EXPECT_THROW(bridge.start(), PortError);
  EXPECT_FALSE(bridge.running());
}

TEST(PtyAccess, BadModeOrUnknownGroupIsAnOptionErrorNamingTheKey) {
  BridgeOptions options = pty_bridge();
  options.pty_mode = 01777;
  try {
    Bridge bridge(options);
    FAIL() << "a mode beyond 0777 was taken";
  } catch (const OptionError& error) {
    EXPECT_EQ(error.key(), "pty_mode");
  }
  options = pty_bridge();
  options.pty_group = "no-such-group-wiretape";
  try {
    Bridge bridge(options);
    FAIL() << "an unknown group was taken";
  } catch (const OptionError& error) {
    EXPECT_EQ(error.key(), "pty_group");
  }
}

TEST(PtyAccess, FindGroupTakesNamesAndNumbers) {
  EXPECT_EQ(wiretape::detail::find_group("0"), std::optional<gid_t>(0));
  EXPECT_EQ(wiretape::detail::find_group("root"), std::optional<gid_t>(0));
  EXPECT_EQ(wiretape::detail::find_group("no-such-group-wiretape"), std::nullopt);
  EXPECT_EQ(wiretape::detail::find_group(""), std::nullopt);
  EXPECT_EQ(wiretape::detail::find_group("4294967295"), std::nullopt);
}

}  // namespace
