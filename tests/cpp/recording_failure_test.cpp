// Recording that fails part-way (issue 16): how an OS error becomes text.
#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <filesystem>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include "core/open_port.hpp"
#include "posix/fd_port.hpp"
#include "posix/syscalls.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/bridge.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/session.hpp"
#include "wiretape/wiretape.hpp"

namespace wiretape {
namespace {

namespace sys = detail::sys;
using namespace std::chrono_literals;
using test::TempDir;

constexpr auto kDeadline = 10s;

std::size_t count_of(const std::string& text, const std::string& part) {
  std::size_t count = 0;
  for (auto at = text.find(part); at != std::string::npos; at = text.find(part, at + 1)) ++count;
  return count;
}

// --- messages ---------------------------------------------------------------------

TEST(SystemErrorMessage, NamesTheErrnoOnceAndNothingForErrnoZero) {
  EXPECT_EQ(system_error_message("dev: read failed", EIO), "dev: read failed: Input/output error");
  EXPECT_EQ(system_error_message("dev: the device went away", 0), "dev: the device went away");
  // A message wrapped again keeps one copy of the errno's text.
  const std::string once = system_error_message("dev: read failed", EIO);
  EXPECT_EQ(system_error_message(once, EIO), once);
}

TEST(SystemErrorMessage, IsWhatEveryPortErrorSays) {
  EXPECT_STREQ(PortClosed("loopback: the port is closed").what(), "loopback: the port is closed");
  EXPECT_STREQ(PortError(0, "no errno").what(), "no errno");
  EXPECT_STREQ(PortError(ENOENT, "x.wtape: cannot open").what(),
               "x.wtape: cannot open: No such file or directory");
  EXPECT_EQ(PortError(ENOENT, "x").code().value(), ENOENT);
  // Copies (std::optional<PortError>, rethrow) keep the message.
  const PortError original(EIO, "copied");
  const PortError copy = original;
  EXPECT_STREQ(copy.what(), "copied: Input/output error");
}

TEST(SystemErrorMessage, ADeviceThatWentAwayIsNamedOnce) {
  for (const int error : {EIO, ECONNRESET, ENXIO, EACCES}) {
    try {
      detail::raise_os_error(error, "serial /dev/ttyX", "read");
      FAIL() << "no error";
    } catch (const PortError& e) {
      const std::string text = e.what();
      EXPECT_EQ(count_of(text, std::generic_category().message(error)), 1u) << text;
      EXPECT_EQ(text.find("Success"), std::string::npos) << text;
      EXPECT_EQ(text.rfind("serial /dev/ttyX: read failed", 0), 0u) << text;
    }
  }
}

}  // namespace
}  // namespace wiretape
