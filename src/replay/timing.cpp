#include "replay/timing.hpp"

#include <cmath>
#include <cstdio>

namespace wiretape::detail {

namespace {

std::string milliseconds_text(std::chrono::nanoseconds ns) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3f",
                static_cast<double>(ns.count()) / 1e6);
  return text;
}

}  // namespace

ReplayTimeline::ReplayTimeline(const ReplayConfig& config, ReplayTime open_time,
                               std::uint64_t origin_ns)
    : timing_(config.timing),
      speed_(config.speed),
      checked_(config.check == ReplayCheck::timing),
      tolerance_(config.tolerance),
      open_time_(open_time),
      origin_ns_(origin_ns) {}

std::chrono::nanoseconds ReplayTimeline::since_origin(std::uint64_t t_ns) const {
  return scaled(t_ns > origin_ns_ ? t_ns - origin_ns_ : 0);
}

std::chrono::nanoseconds ReplayTimeline::scaled(std::uint64_t ns) const {
  return std::chrono::nanoseconds(
      static_cast<std::int64_t>(std::llround(static_cast<double>(ns) / speed_)));
}

ReplayTime ReplayTimeline::due(std::uint64_t t_ns,
                               const std::optional<Anchor>& anchor) const {
  switch (timing_) {
    case ReplayTiming::none:
      return open_time_;
    case ReplayTiming::session:
      return open_time_ + since_origin(t_ns);
    case ReplayTiming::causal:
      break;
  }
  if (!anchor) return open_time_ + since_origin(t_ns);
  // A record stamped before its anchor (clock granularity) is due at once.
  const std::uint64_t gap =
      t_ns > anchor->recorded_t_ns ? t_ns - anchor->recorded_t_ns : 0;
  return anchor->finished + scaled(gap);
}

std::optional<ReplayTimeline::Miss> ReplayTimeline::check(ReplayTime due,
                                                          ReplayTime now) const {
  if (!checked_) return std::nullopt;
  const std::chrono::nanoseconds offset = now - due;
  if (offset >= -tolerance_ && offset <= tolerance_) return std::nullopt;
  Miss miss;
  miss.early = offset < std::chrono::nanoseconds::zero();
  const char* when = miss.early ? "early" : "late";
  miss.title = std::string("the client wrote too ") + when;
  miss.detail = "  the write came " +
                milliseconds_text(miss.early ? -offset : offset) + " ms " +
                when + " (tolerance " + milliseconds_text(tolerance_) +
                " ms, timing=" +
                (timing_ == ReplayTiming::session ? "session" : "causal") + ")\n";
  return miss;
}

}  // namespace wiretape::detail
