#pragma once

#include <chrono>
#include <optional>

namespace wiretape {

// How long a call may wait. std::nullopt (wiretape::forever) blocks until the
// call can complete; zero polls; anything else waits at most that long.
using Timeout = std::optional<std::chrono::nanoseconds>;
inline constexpr Timeout forever = std::nullopt;

// An absolute point a call must return by; std::nullopt means never.
using Deadline = std::optional<std::chrono::steady_clock::time_point>;

// A zero (or negative) timeout is a deadline already past without reading
// the clock: the clock's epoch, before any now(). The bridge's reads and
// writes all poll: two clock reads fewer in each turn of its loop.
inline Deadline deadline_after(Timeout timeout) {
  if (!timeout) return std::nullopt;
  if (timeout->count() <= 0) return std::chrono::steady_clock::time_point{};
  return std::chrono::steady_clock::now() + *timeout;
}

// Whether `deadline` has passed; a zero timeout's, without a clock read.
inline bool is_past(Deadline deadline) {
  if (!deadline) return false;
  return *deadline == std::chrono::steady_clock::time_point{} ||
         std::chrono::steady_clock::now() >= *deadline;
}

// Time left until `deadline`, never negative; std::nullopt when unbounded.
inline Timeout remaining(Deadline deadline) {
  if (!deadline) return std::nullopt;
  auto left = *deadline - std::chrono::steady_clock::now();
  if (left < std::chrono::steady_clock::duration::zero()) left = {};
  return std::chrono::duration_cast<std::chrono::nanoseconds>(left);
}

}  // namespace wiretape
