// The replay engine: decides which recorded rx bytes a client may read and
// when, and checks what it writes. It holds no threads and reads no clock:
// every call is given `now`, so tests can drive it deterministically; the
// replaying port (replay_port.cpp) adds locking, blocking and the pollable
// handle.
//
// The engine is the front of three parts: a match strategy decides what the
// client is entitled to and checks its writes (sequence.hpp for
// match=sequence, request.hpp for match=request), timing.hpp says when
// entitled bytes are due, and the engine serves the released rx, reports
// mismatches and, at close, what was never used (strategy.hpp). The client
// reads the released rx through the fault stage (fault_stage.hpp), a
// pass-through without faults=.
#pragma once

#include <cstddef>
#include <map>
#include <memory>
#include <optional>
#include <string>

#include "replay/fault_stage.hpp"
#include "replay/replay_config.hpp"
#include "replay/strategy.hpp"
#include "replay/timing.hpp"
#include "session/record_source.hpp"
#include "wiretape/session.hpp"

namespace wiretape::detail {

class ReplayEngine {
 public:
  // `origin_ns`: the recorded time that `open_time` stands for (see
  // ReplayTimeline). `fault_memory`: what faults of earlier client sessions
  // of the same device left behind (FaultMemory); nullptr: none.
  ReplayEngine(ReplayConfig config, RecordSourceFactory sources,
               ReplayTime open_time, std::uint64_t origin_ns = 0,
               std::shared_ptr<FaultMemory> fault_memory = nullptr);
  ~ReplayEngine();
  ReplayEngine(const ReplayEngine&) = delete;
  ReplayEngine& operator=(const ReplayEngine&) = delete;

  // Copies released, due bytes (at most one datagram in datagram sessions);
  // 0 when nothing is readable now. Raises PortClosed when the next thing
  // the recording holds is a close or a device loss that is due.
  // An empty datagram is passed over: 0 would say that nothing is due.
  std::size_t read(char* buffer, std::size_t size, ReplayTime now);
  // In a datagram session: the next due datagram, truncated to `size` as
  // recv does (0 for an empty one); nothing when none is due now. Raises as
  // read() does.
  std::optional<std::size_t> read_datagram(char* buffer, std::size_t size, ReplayTime now);
  // Copies what read() would return now without consuming it: 0 when
  // nothing is due; nullopt when read() would not return plain bytes (a
  // loss, a recorded close, a datagram session): the caller reads instead.
  // Lets a compound read take a whole line in one read() instead of a byte
  // at a time.
  std::optional<std::size_t> peek(char* buffer, std::size_t size, ReplayTime now);
  // Bytes read() would return at once.
  std::size_t available(ReplayTime now);

  enum class ReadState {
    readable,     // read() returns data now
    device_gone,  // read() raises PortClosed now (recorded close)
    waiting,      // nothing yet: see wake
    ended,        // the recording has nothing more for the client to read
  };
  struct Outlook {
    ReadState state = ReadState::waiting;
    // When a waiting read becomes readable without any write; nullopt when
    // only a write by the client can release more.
    std::optional<ReplayTime> wake;
  };
  Outlook outlook(ReplayTime now);

  // Accepts the whole write or raises ReplayMismatch (or PortClosed past a
  // recorded close).
  void write(const char* data, std::size_t size, ReplayTime now);
  // The client changed line settings, a modem line or sent a break: under
  // check=timing (match=sequence) it must match the next recorded event of
  // that kind, in order with the writes; a modem line or break also under
  // check=data where the recording holds the device's lines (DESIGN.md
  // section 20). `fields` are the event's JSON members as text (baud ->
  // "115200", dtr -> "true").
  void client_event(RecordKind kind,
                    const std::map<std::string, std::string>& fields,
                    ReplayTime now);
  // The device's modem inputs released and due by `now` (DESIGN.md section
  // 20): CTS, DSR and CD up and RI down until the recording says otherwise.
  ModemInputs device_lines(ReplayTime now);
  // Drops rx that was released and is due but not yet read; a client flush.
  void flush_input(ReplayTime now);
  // The client flushed without dropping released rx (its output, or its
  // input where the bytes dropped are delivered again).
  void client_flushed();
  // What the recording held that the client never consumed; empty if all.
  std::string unused_report();

  const ReplayConfig& config() const { return config_; }

  // Where injected faults are reported (faults=); by default a line on
  // stderr.
  void on_fault(FaultStage::Reporter reporter) { stage_.on_fault(std::move(reporter)); }
  // Reads fail now because of an injected loss of the device.
  bool lost_by_fault(ReplayTime now) { return stage_.loss(now) != nullptr; }

 private:
  // Lets the strategy release what the client is now entitled to, and
  // passes it through the fault stage.
  void prepare(ReplayTime now);
  [[noreturn]] void raise_device_gone(const RxItem& item) const;

  ReplayConfig config_;
  ReplayTimeline timeline_;
  ReleasedRx released_;
  MismatchReport report_;
  FaultStage stage_;
  std::unique_ptr<ReplayStrategy> strategy_;  // made last: it uses the above
};

}  // namespace wiretape::detail
