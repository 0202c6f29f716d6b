// When recorded things are due on the replay clock. This is the one place
// that turns a recorded time into a due time, for every timing mode and both
// match strategies (DESIGN.md section 7), and that checks a client's write
// against its due time under check=timing.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>

#include "replay/replay_config.hpp"

namespace wiretape::detail {

using ReplayClock = std::chrono::steady_clock;
using ReplayTime = ReplayClock::time_point;

class ReplayTimeline {
 public:
  // `origin_ns`: the recorded time that `open_time` stands for (a client
  // session of a virtual device starts at its recorded client_connect).
  ReplayTimeline(const ReplayConfig& config, ReplayTime open_time,
                 std::uint64_t origin_ns = 0);

  // The client's write that a record follows in the recording: when the
  // client finished it, and when it was recorded. Causal timing counts from
  // here.
  struct Anchor {
    ReplayTime finished;
    std::uint64_t recorded_t_ns = 0;
  };

  // When something recorded at `t_ns` is due, once the client is entitled to
  // it. timing=none: at once (the open time, already past). session: the
  // open time + t / speed. causal: the anchor's finish + the recorded gap
  // from the anchor / speed; with no anchor (nothing written before it), as
  // session.
  ReplayTime due(std::uint64_t t_ns, const std::optional<Anchor>& anchor) const;

  // check=timing: a write outside its due time +- tolerance.
  struct Miss {
    bool early = false;
    std::string title;   // "the client wrote too early"
    std::string detail;  // how early or late, the tolerance and timing mode
  };
  // nullopt when `now` is within the window around `due`, or when timing is
  // not checked.
  std::optional<Miss> check(ReplayTime due, ReplayTime now) const;
  // check() for a client's write of what was recorded at `t_ns`, anchored on
  // the write before it when the client has finished one (finished at
  // `previous_finished`, recorded at `previous_t_ns`).
  std::optional<Miss> check_write(std::uint64_t t_ns,
                                  std::optional<ReplayTime> previous_finished,
                                  std::uint64_t previous_t_ns, ReplayTime now) const {
    std::optional<Anchor> anchor;
    if (previous_finished) anchor = Anchor{*previous_finished, previous_t_ns};
    return check(due(t_ns, anchor), now);
  }

 private:
  std::chrono::nanoseconds scaled(std::uint64_t ns) const;
  std::chrono::nanoseconds since_origin(std::uint64_t t_ns) const;

  ReplayTiming timing_;
  double speed_;
  bool checked_;
  std::chrono::nanoseconds tolerance_;
  ReplayTime open_time_;
  std::uint64_t origin_ns_;
};

}  // namespace wiretape::detail
