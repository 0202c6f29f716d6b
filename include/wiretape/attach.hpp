// Recording a program that is already running (DESIGN §26): ptrace follows
// its system calls on the device's descriptors and writes what it reads,
// writes and sets into an ordinary session file, then lets it go as it was.
//
//   wiretape::AttachOptions options;
//   options.pid = 4242;
//   options.path = "/dev/ttyUSB0";
//   wiretape::Attachment attachment(options, "driver.wtape");
//   attachment.wait(std::chrono::seconds(60));
//   attachment.stop();
//
// Linux on x86_64 only.
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "wiretape/errors.hpp"
#include "wiretape/session.hpp"

namespace wiretape {

struct AttachOptions {
  std::int64_t pid = 0;
  // The device, matched by stat against what the program holds (never by
  // comparing paths); or `fd`; or neither: the program's only tty or socket.
  std::string path;
  std::optional<int> fd;
  std::map<std::string, std::string> user_metadata;  // --meta
  FlushPolicy flush{};
};

// How an attached recording ended and what it holds.
struct AttachSummary {
  // "stopped" (stop(), Ctrl-C, --duration), "exited" (the program ended),
  // "execed" (it executed another program, which is not followed).
  std::string ended_by;
  // The program's exit status (as waitpid reports it) when it exited.
  std::optional<int> exit_status;
  std::uint64_t rx_bytes = 0;
  std::uint64_t tx_bytes = 0;
  std::uint64_t records = 0;
  std::vector<std::string> warnings;  // as the header's attached.warnings
};

class Attachment {
 public:
  // Attaches to the program and starts recording into `output`. A refusal
  // throws OptionError (key "attach", "path" or "fd") saying why, and
  // nothing is written: no such process, no permission (another user's
  // process without CAP_SYS_PTRACE, kernel.yama.ptrace_scope), already
  // traced, a descriptor or path the program does not hold. PortError when
  // `output` cannot be written (then the program is let go first).
  Attachment(const AttachOptions& options, const std::string& output);
  // Stops and detaches, if not yet done.
  ~Attachment();
  Attachment(const Attachment&) = delete;
  Attachment& operator=(const Attachment&) = delete;

  // Ends the recording: every thread of the program is detached and goes
  // on as if never traced. Returns at once; wait() until it is done.
  void stop();
  // Until the recording ended (stop(), the program's exit or exec), at most
  // `timeout`; whether it ended.
  bool wait(std::optional<std::chrono::milliseconds> timeout = std::nullopt);
  bool finished() const;
  // What was recorded so far; complete once finished(). Throws the failure
  // that ended the recording early (a full disk).
  AttachSummary summary() const;
  // The session header as written (its attached member included).
  SessionHeader header() const;
  const std::string& path() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace wiretape
