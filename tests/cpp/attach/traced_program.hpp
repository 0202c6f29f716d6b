// The program the attach tests attach to (traced_program.c), run with its
// stdin and stdout piped to the test.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "support/port_test_support.hpp"

namespace wiretape::test {

inline const std::string traced_program_path = std::string(WIRETAPE_BIN_DIR) + "/traced_program";

// The program, with its stdin and stdout piped to the test.
struct Program {
  explicit Program(std::vector<std::string> args) {
    int in[2], out[2];
    EXPECT_EQ(::pipe(in), 0);
    EXPECT_EQ(::pipe(out), 0);
    pid = ::fork();
    if (pid == 0) {
      ::dup2(in[0], 0);
      ::dup2(out[1], 1);
      ::close(in[1]);
      ::close(out[0]);
      ::close(in[0]);
      ::close(out[1]);
      // Only what the program opens itself: not the test's pty master.
      for (int fd = 3; fd < 1024; ++fd) ::close(fd);
      std::vector<char*> argv;
      argv.push_back(const_cast<char*>(traced_program_path.c_str()));
      for (auto& arg : args) argv.push_back(arg.data());
      argv.push_back(nullptr);
      ::execv(traced_program_path.c_str(), argv.data());
      ::_exit(127);
    }
    ::close(in[0]);
    ::close(out[1]);
    stdin_fd = in[1];
    stdout_fd = out[0];
  }
  ~Program() {
    if (pid > 0 && !reaped) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, nullptr, 0);
    }
    ::close(stdin_fd);
    ::close(stdout_fd);
  }
  // A line the program printed, "" at the deadline.
  std::string line() {
    std::string text;
    char c;
    while (test::fd_readable(stdout_fd, std::chrono::duration_cast<std::chrono::milliseconds>(
                                            test::kEventDeadline)) &&
           ::read(stdout_fd, &c, 1) == 1) {
      if (c == '\n') return text;
      text += c;
    }
    return text;
  }
  int wait_exit() {
    int status = 0;
    ::waitpid(pid, &status, 0);
    reaped = true;
    return status;
  }
  // "S (sleeping)", "t (tracing stop)"...
  std::string proc_status(const std::string& member) const {
    std::ifstream in("/proc/" + std::to_string(pid) + "/status");
    std::string text;
    while (std::getline(in, text)) {
      if (text.rfind(member + ":", 0) == 0) return text.substr(member.size() + 2);
    }
    return "";
  }
  pid_t pid = -1;
  int stdin_fd = -1;
  int stdout_fd = -1;
  bool reaped = false;
};

}  // namespace wiretape::test
