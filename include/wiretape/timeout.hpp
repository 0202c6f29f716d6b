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

inline Deadline deadline_after(Timeout timeout) {
  if (!timeout) return std::nullopt;
  return std::chrono::steady_clock::now() + *timeout;
}

// Time left until `deadline`, never negative; std::nullopt when unbounded.
inline Timeout remaining(Deadline deadline) {
  if (!deadline) return std::nullopt;
  auto left = *deadline - std::chrono::steady_clock::now();
  if (left < std::chrono::steady_clock::duration::zero()) left = {};
  return std::chrono::duration_cast<std::chrono::nanoseconds>(left);
}

}  // namespace wiretape
