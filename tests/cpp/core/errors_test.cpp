// How an OS error becomes text (src/core/errors.cpp): the errno's message
// once, after the context, and what every port error says with it.
#include <gtest/gtest.h>

#include <cerrno>
#include <string>

#include "wiretape/errors.hpp"

namespace wiretape {
namespace {

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

// A resolver's reason is the whole explanation: the errno a program reads
// stays, its text (which would contradict the reason) is not appended.
TEST(SystemErrorMessage, AnErrorWithItsOwnExplanationIsTakenAsItIs) {
  const PortError error(EHOSTUNREACH, "tcp nosuch:1: cannot resolve host 'nosuch': Name or "
                                      "service not known", PortError::OwnExplanation{});
  EXPECT_STREQ(error.what(),
               "tcp nosuch:1: cannot resolve host 'nosuch': Name or service not known");
  EXPECT_EQ(error.code().value(), EHOSTUNREACH);
}

TEST(SystemErrorMessage, NoContextIsTheErrnosTextAlone) {
  EXPECT_EQ(system_error_message("", ENOENT), "No such file or directory");
  EXPECT_EQ(system_error_message("", 0), "");
}

}  // namespace
}  // namespace wiretape
