// Refusals of an attach (DESIGN §26): each is an OptionError naming the
// problem (exit 2 at the command line), and nothing is written.
#include "attach/process.hpp"

#include <sys/ptrace.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <string>

#include "attach/traced_program.hpp"
#include "posix/syscalls.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/attach.hpp"

namespace wiretape {
namespace {

namespace sys = detail::sys;
using test::Program;

// The OptionError an attach with `options` throws ("" and key "" if none).
std::pair<std::string, std::string> refusal(const AttachOptions& options,
                                            const std::string& output) {
  try {
    Attachment attachment(options, output);
  } catch (const OptionError& error) {
    return {error.key(), error.what()};
  }
  return {"", ""};
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

struct Served {
  test::TempDir dir;
  test::PtyPair pty;
  Program program{{"tty", pty.path}};
  std::string output = dir.file("refused.wtape");
  AttachOptions options;
  Served() {
    EXPECT_EQ(program.line(), "ready");
    options.pid = program.pid;
  }
  bool written() const { return std::filesystem::exists(output); }
};

TEST(AttachRefusal, AProcessThatDoesNotExist) {
  test::TempDir dir;
  const pid_t gone = ::fork();
  if (gone == 0) ::_exit(0);
  ::waitpid(gone, nullptr, 0);
  AttachOptions options;
  options.pid = gone;
  const auto [key, message] = refusal(options, dir.file("x.wtape"));
  EXPECT_EQ(key, "attach");
  EXPECT_TRUE(contains(message, "there is no process " + std::to_string(gone))) << message;
  EXPECT_FALSE(std::filesystem::exists(dir.file("x.wtape")));
}

TEST(AttachRefusal, ADescriptorOrAPathTheProgramDoesNotHold) {
  Served served;
  served.options.fd = 99;
  auto [key, message] = refusal(served.options, served.output);
  EXPECT_EQ(key, "fd");
  EXPECT_TRUE(contains(message, "holds no descriptor 99")) << message;
  EXPECT_TRUE(contains(message, served.pty.path)) << message;  // what it does hold
  served.options.fd.reset();
  test::PtyPair other;
  served.options.path = other.path;
  std::tie(key, message) = refusal(served.options, served.output);
  EXPECT_EQ(key, "path");
  EXPECT_TRUE(contains(message, "does not hold " + other.path)) << message;
  EXPECT_FALSE(served.written());
}

TEST(AttachRefusal, AProcessAlreadyTraced) {
  Served served;
  Attachment first(served.options, served.dir.file("first.wtape"));
  const auto [key, message] = refusal(served.options, served.output);
  EXPECT_EQ(key, "attach");
  EXPECT_TRUE(contains(message, "already traced by process ") && contains(message, "(process_test"))
      << message;
  EXPECT_FALSE(served.written());
}

TEST(AttachRefusal, AnotherUsersProcessWithoutCapSysPtrace) {
  if (::geteuid() != 0) GTEST_SKIP() << "needs root to become another user";
  Served served;
  std::filesystem::permissions(served.dir.path, std::filesystem::perms::all);
  int result[2];
  ASSERT_EQ(::pipe(result), 0);
  const pid_t child = ::fork();
  if (child == 0) {
    // nobody, without capabilities: the program is root's.
    if (::setresgid(65534, 65534, 65534) != 0 || ::setresuid(65534, 65534, 65534) != 0) {
      ::_exit(100);
    }
    const auto [key, message] = refusal(served.options, served.output);
    const std::string said = key + "|" + message;
    (void)!::write(result[1], said.data(), said.size());
    ::_exit(0);
  }
  ::close(result[1]);
  int status = 0;
  ::waitpid(child, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  ASSERT_EQ(WEXITSTATUS(status), 0);
  const std::string said = test::read_count(result[0], 4096);
  ::close(result[0]);
  EXPECT_EQ(said.substr(0, said.find('|')), "attach");
  EXPECT_TRUE(contains(said, "CAP_SYS_PTRACE")) << said;
  EXPECT_FALSE(served.written());
}

// This kernel has no Yama: its setting is faked through the seam.
TEST(AttachRefusal, YamasPtraceScopeIsNamed) {
  Served served;
  const std::string scope_file = served.dir.file("ptrace_scope");
  test::write_file(scope_file, "1\n");
  for (const bool with_yama : {true, false}) {
    sys::ScopedOverride seam;
    const auto real_open = sys::real().open;
    seam->open = [&](const char* path, int flags, mode_t mode) {
      if (std::strcmp(path, "/proc/sys/kernel/yama/ptrace_scope") == 0) {
        if (!with_yama) {
          errno = ENOENT;
          return -1;
        }
        return real_open(scope_file.c_str(), flags, mode);
      }
      return real_open(path, flags, mode);
    };
    seam->ptrace = [](int request, pid_t tid, void* address, void* data) -> long {
      if (request == PTRACE_SEIZE) {
        errno = EPERM;
        return -1;
      }
      return sys::real().ptrace(request, tid, address, data);
    };
    const auto [key, message] = refusal(served.options, served.output);
    EXPECT_EQ(key, "attach");
    if (with_yama) {
      EXPECT_TRUE(contains(message, "kernel.yama.ptrace_scope is 1")) << message;
    } else {
      EXPECT_TRUE(contains(message, "CAP_SYS_PTRACE")) << message;
      EXPECT_FALSE(contains(message, "yama")) << message;
    }
  }
  EXPECT_FALSE(served.written());
  // Nothing was left seized.
  EXPECT_EQ(served.program.proc_status("TracerPid"), "0");
}

TEST(AttachDescriptors, ThePathIsMatchedByTheDeviceNotItsName) {
  Served served;
  const std::string link = served.dir.file("link-to-tty");
  std::filesystem::create_symlink(served.pty.path, link);
  const detail::AttachTarget target =
      detail::choose_descriptors(served.program.pid, link, std::nullopt);
  EXPECT_EQ(target.device.kind, detail::DeviceKind::tty);
  EXPECT_EQ(target.device.target, served.pty.path);
  ASSERT_EQ(target.fds.size(), 1u);
  // Neither --path nor --fd: the only tty.
  EXPECT_EQ(detail::choose_descriptors(served.program.pid, "", std::nullopt).fds, target.fds);
}

}  // namespace
}  // namespace wiretape
