// How an injected fault reaches whoever wraps the port that injected it
// (a recorder: each fault is also a `fault` event), without the wrapper
// knowing which port type injects faults (DESIGN.md section 25: ports/
// does not include replay/). A port that injects faults is a FaultSource.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "wiretape/port.hpp"

namespace wiretape::detail {

// One injected fault, as reported on stderr and recorded as a `fault` event.
struct FaultEvent {
  std::string kind;
  std::string where;
  std::string detail;
  std::uint64_t exchange = 0;
};

using FaultReporter = std::function<void(const FaultEvent&)>;

class FaultSource {
 public:
  // Each injected fault goes to `reporter` instead of a line on stderr.
  virtual void on_fault(FaultReporter reporter) = 0;

 protected:
  ~FaultSource() = default;
};

// Where `port`'s injected faults are reported, if it is a FaultSource (a
// replay with faults=); false for every other port.
inline bool report_faults_to(Port& port, FaultReporter reporter) {
  auto* source = dynamic_cast<FaultSource*>(&port);
  if (source == nullptr) return false;
  source->on_fault(std::move(reporter));
  return true;
}

}  // namespace wiretape::detail
