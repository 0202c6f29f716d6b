// Fuzzes the faults= parser and the fault stage: any text either parses or
// raises an OptionError naming `faults`; a plan that parses is applied by
// the stage to a short stream of rx records (stream and datagram sessions)
// without crashing, and twice with the same seed gives the same bytes.
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <deque>
#include <string>
#include <string_view>

#include "replay/fault_stage.hpp"
#include "replay/faults.hpp"
#include "wiretape/errors.hpp"

namespace {

std::string run(const wiretape::detail::FaultPlan& plan, bool datagrams) {
  using namespace wiretape::detail;
  ReleasedRx released(/*recycle_payloads=*/false);
  FaultStage stage(plan, datagrams, released);
  stage.on_fault([](const FaultEvent&) {});
  const ReplayTime start{};
  std::string bytes;
  for (std::uint64_t i = 0; i < 12; ++i) {
    RxItem item;
    item.kind = i == 11 ? wiretape::RecordKind::close : wiretape::RecordKind::rx;
    item.data = std::string(1 + i * 7 % 23, static_cast<char>('a' + i));
    item.t_ns = i * 250'000'000;
    item.due = start + std::chrono::milliseconds(i);
    item.exchange = i / 2;
    released.push(std::move(item));
    const ReplayTime now = start + std::chrono::milliseconds(i / 2);
    stage.pull(now);
    stage.loss(now);
  }
  for (; !stage.empty(); stage.pop()) {
    bytes += std::string(stage.front().payload());
    bytes += '|';
  }
  return bytes;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > 4096) return 0;  // the plan's own bounds keep the rest cheap
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  wiretape::detail::FaultPlan plan;
  try {
    plan = wiretape::detail::parse_faults(text, size);
  } catch (const wiretape::OptionError& error) {
    if (error.key() != "faults") std::abort();
    return 0;
  }
  // Big amounts are fine to parse but slow to apply byte by byte.
  for (auto& fault : plan.faults) {
    if (fault.amount && *fault.amount > 4096) fault.amount = 4096;
  }
  for (const bool datagrams : {false, true}) {
    if (run(plan, datagrams) != run(plan, datagrams)) std::abort();
  }
  return 0;
}
