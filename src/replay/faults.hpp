// Fault injection on replay (DESIGN.md section 14): `faults=` parsed into a
// plan, and the injector that applies it to the rx a replay releases.
//
// The injector sees each released rx record once, in order, with the number
// of the exchange it answers; it hands back what the client gets instead
// (nothing, altered bytes, several pieces, a loss of the device) and reports
// each fault it injects. Every random choice comes from the plan's seed
// through a generator of our own, so a plan does the same on every platform.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "replay/strategy.hpp"
#include "replay/timing.hpp"
#include "wiretape/profile.hpp"

namespace wiretape::detail {

enum class FaultKind {
  drop,        // the exchange's rx lost (drop:N: N bytes of it, N datagrams)
  corrupt,     // N bit flips (default 1)
  garbage,     // N random bytes inserted (default 8)
  truncate,    // the response stops after N bytes (default: half of it)
  duplicate,   // the response's first record sent twice
  delay,       // the response comes MS later
  stall,       // a gap of MS inside the response
  trickle,     // one byte at a time (MS apart, default 1)
  silence,     // the device stops answering, for good
  disconnect,  // the device is lost: PortClosed from here on
  reconnect,   // the device is lost for MS, then answers again
};

enum class FaultWhereKind { exchange, rx, time, every, probability };

struct FaultSpec {
  FaultKind kind = FaultKind::drop;
  std::optional<std::uint64_t> amount;  // the :N or :MS, when given
  FaultWhereKind where = FaultWhereKind::exchange;
  std::uint64_t where_number = 0;  // exchange:N, rx:N, every:K
  double where_value = 0;          // t:SECONDS, p:P
  std::string kind_text;           // as written (normalised), for reports
  std::string where_text;
};

struct FaultPlan {
  std::vector<FaultSpec> faults;
  std::uint64_t seed = 0;
  bool empty() const { return faults.empty(); }
};

// The grammar, for error messages and docs.
extern const char* const kFaultGrammar;

// Parses `faults=` (a `;`-separated list of KIND@WHERE). Throws OptionError
// naming the key `faults`, the item and the grammar.
FaultPlan parse_faults(std::string_view text, std::uint64_t seed);

// splitmix64: small, fast, and the same everywhere.
std::uint64_t splitmix64(std::uint64_t x);

// One injected fault, as reported on stderr and recorded as a `fault` event.
struct FaultEvent {
  std::string kind;
  std::string where;
  std::string detail;
  std::uint64_t exchange = 0;
};

// A released rx record after the faults: the item, and for a loss of the
// device that ends (reconnect), when it is back.
struct FaultedRx {
  RxItem item;
  std::optional<ReplayTime> back_at;
};

class FaultInjector {
 public:
  using Reporter = std::function<void(const FaultEvent&)>;

  FaultInjector(FaultPlan plan, bool datagrams, Reporter reporter);

  // Passes one released record (rx, or a recorded close or loss) of
  // exchange `exchange` through the plan, appending what the client gets
  // to `out`. `now`: when it is released; a fault's waits count from the
  // exchange's release at the earliest (under timing=none everything is due
  // at the open time, long past).
  void apply(RxItem&& item, std::uint64_t exchange, std::deque<FaultedRx>& out,
             ReplayTime now);

  // The device stopped answering (silence): writes are swallowed.
  bool silenced() const { return silenced_; }
  // A fault made the rest of the recording unreachable (silence,
  // disconnect): it is not reported as unused.
  bool rest_unreachable() const { return silenced_ || disconnected_; }
  // Whether any fault was injected.
  std::uint64_t injected() const { return injected_; }

 private:
  bool fires(std::size_t index, const FaultSpec& spec, std::uint64_t exchange,
             const RxItem& item, std::uint64_t offset);
  void report(const FaultSpec& spec, std::uint64_t exchange, std::string detail);
  // A random number for (fault, exchange, purpose): independent of the order
  // in which things happen.
  std::uint64_t draw(std::size_t index, std::uint64_t exchange, std::uint64_t purpose) const;

  FaultPlan plan_;
  bool datagrams_;
  Reporter reporter_;
  std::vector<bool> once_fired_;  // rx:N and t:S fire once
  std::optional<std::uint64_t> current_exchange_;
  // Per exchange, what goes on for its later records.
  bool drop_rest_ = false;
  std::optional<std::uint64_t> trickle_ms_;
  std::chrono::nanoseconds shift_{0};  // delays and stalls so far in it
  ReplayTime released_at_;             // when its first record was released
  std::uint64_t rx_offset_ = 0;        // served rx bytes before this record
  bool silenced_ = false;
  bool disconnected_ = false;
  std::uint64_t injected_ = 0;
};

}  // namespace wiretape::detail
