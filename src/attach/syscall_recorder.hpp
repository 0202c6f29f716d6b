// What a traced program's system calls on the device's descriptors mean
// for its recording (DESIGN §26): reads at their return with the bytes the
// program got, writes at their entry with the count their return says,
// termios and line ioctls as the events a bridge records, the descriptors
// followed through dup, close and a reopen of the same device; what cannot
// be seen (splice, sendfile, io_uring) said as a warning.
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "attach/process.hpp"
#include "attach/tracer.hpp"
#include "session/record_kinds.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

namespace wiretape::detail {

// Where the records go, on one clock.
class AttachSink {
 public:
  virtual ~AttachSink() = default;
  virtual std::uint64_t now_ns() = 0;
  // In time order: the recorder holds a record back until no write that
  // entered before it is still running.
  virtual void write(RecordKind kind, std::uint64_t t_ns, const std::string& data) = 0;
};

// The device's state read inside the program at attach.
struct DeviceState {
  std::optional<SerialSettings> settings;
  std::optional<bool> dtr, rts;
  std::optional<ModemInputs> inputs;
};

class SyscallRecorder : public SyscallHandler {
 public:
  SyscallRecorder(pid_t pid, AttachTarget target, AttachSink& sink);

  void entered(pid_t tid, const SyscallCall& call) override;
  void returned(pid_t tid, const SyscallCall& call, std::int64_t result) override;
  void first_stop(Injector& injector) override;

  // Every record still held back, written (at the end).
  void flush();
  const std::vector<std::string>& warnings() const { return warnings_; }
  // Warnings added since the last call (for the header).
  bool take_new_warnings();
  std::uint64_t rx_bytes() const { return rx_bytes_; }
  std::uint64_t tx_bytes() const { return tx_bytes_; }
  const DeviceState& state_at_attach() const { return at_attach_; }

 private:
  struct Held {
    std::uint64_t t_ns;
    std::uint64_t order;
    RecordKind kind;
    std::string data;
  };
  bool tracked(std::uint64_t fd) const { return fds_.count(static_cast<int>(fd)) != 0; }
  void emit(RecordKind kind, std::uint64_t t_ns, std::string data);
  void release();
  void warn(const std::string& text);
  std::string gather(std::uint64_t iov, std::uint64_t count, std::int64_t total) const;
  void on_read(const SyscallCall& call, std::int64_t result, std::uint64_t now);
  void on_write(pid_t tid, const SyscallCall& call, std::int64_t result);
  void on_ioctl(pid_t tid, const SyscallCall& call, std::int64_t result, std::uint64_t now);
  void on_descriptors(const SyscallCall& call, std::int64_t result, std::uint64_t now);
  void record_settings(const SerialSettings& settings, std::uint64_t now);
  void record_outputs(std::optional<bool> dtr, std::optional<bool> rts, std::uint64_t now,
                      std::optional<bool> applied = std::nullopt);
  void record_inputs(const ModemInputs& inputs, std::uint64_t now);
  void untrack(int fd, std::uint64_t now);

  pid_t pid_;
  AttachTarget target_;
  AttachSink& sink_;
  std::set<int> fds_;
  bool closed_ = false;  // the program closed every descriptor of the device
  bool at_end_ = false;  // a read returned 0: recorded once until data again
  std::map<pid_t, std::uint64_t> entered_at_;  // a running write's entry time, per thread
  std::multiset<std::uint64_t> running_writes_;
  std::vector<Held> held_;
  std::uint64_t order_ = 0;
  std::optional<SerialSettings> settings_;
  std::optional<bool> dtr_, rts_;
  std::optional<ModemInputs> inputs_;
  std::optional<std::uint64_t> break_since_;
  DeviceState at_attach_;
  std::vector<std::string> warnings_;
  std::set<std::string> warned_;
  bool new_warnings_ = false;
  std::uint64_t rx_bytes_ = 0, tx_bytes_ = 0;
};

}  // namespace wiretape::detail
