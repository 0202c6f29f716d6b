// The fault stage (DESIGN.md section 17): the one place between the rx a
// match strategy released and the client's reads where faults= acts.
//
// The engine reads the released rx through the stage only. Without a plan
// the stage is the released queue itself (no copy, no per-byte work); with
// one, each released record goes once, in order, through the injector into
// a queue of the stage's own, along with the state a fault leaves behind (a
// loss of the device, a silenced device).
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "replay/faults.hpp"
#include "replay/strategy.hpp"
#include "replay/timing.hpp"

namespace wiretape::detail {

// What a plan's faults leave behind that outlasts one client session of a
// virtual device (each session has an engine, and so a stage, of its own):
// a silenced device stays silent, a lost one lost, a once-only place (rx:N,
// t:S) does not fire again, rx bytes are counted on (rx:N is an offset in
// what the device served, as exchanges are numbered across client
// sessions), and once a fault was injected no session reports unused data.
// The replaying port keeps one and hands it to each session's stage.
struct FaultMemory {
  bool silenced = false;
  // The silence that did it (KIND@WHERE), for the replay's verdict.
  std::string silenced_by;
  std::uint64_t rx_served = 0;  // rx bytes through the stages so far
  // Why the device is gone (disconnect); a later session starts with it.
  std::optional<std::string> lost;
  std::vector<bool> once_fired;  // per fault of the plan
  std::uint64_t injected = 0;
};

// A released rx record after the faults: the item, and for a loss of the
// device that ends (reconnect), when it is back.
struct FaultedRx {
  RxItem item;
  std::optional<ReplayTime> back_at;
};

// Applies a plan to released records one by one: what the client gets
// instead (nothing, altered bytes, several pieces, a loss of the device),
// and a report of each fault it injects.
class FaultInjector {
 public:
  using Reporter = std::function<void(const FaultEvent&)>;

  // `memory`: what earlier client sessions' faults left behind (shared with
  // the later ones); nullptr: a memory of this injector's own. `speed`: the
  // replay's `speed` key, which scales the faults' waits (delay, stall,
  // trickle, reconnect) as it scales the recorded ones (DESIGN §14, §22).
  FaultInjector(FaultPlan plan, bool datagrams, Reporter reporter,
                std::shared_ptr<FaultMemory> memory = nullptr, double speed = 1.0);

  // Passes one released record (rx, or a recorded close or loss) of
  // exchange `item.exchange` through the plan, appending what the client
  // gets to `out`. `now`: when it is released; a fault's waits count from
  // the exchange's release at the earliest (under timing=none everything is
  // due at the open time, long past).
  void apply(RxItem&& item, std::deque<FaultedRx>& out, ReplayTime now);

  // The device stopped answering (silence): writes are swallowed.
  bool silenced() const { return memory_->silenced; }
  // A fault made the rest of the recording unreachable (silence,
  // disconnect): it is not reported as unused.
  bool rest_unreachable() const { return memory_->silenced || memory_->lost.has_value(); }
  // How many faults were injected, in this and earlier client sessions.
  std::uint64_t injected() const { return memory_->injected; }

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
  std::shared_ptr<FaultMemory> memory_;  // never null
  double speed_ = 1.0;
  // A fault's wait of `ms` milliseconds on the replay's clock.
  std::chrono::nanoseconds wait_of(std::uint64_t ms) const;
  std::optional<std::uint64_t> current_exchange_;
  // Per exchange, what goes on for its later records.
  bool drop_rest_ = false;
  std::optional<std::uint64_t> trickle_ms_;
  bool trickled_ = false;  // a byte of this exchange was trickled: the next waits
  std::chrono::nanoseconds shift_{0};  // delays and stalls so far in it
  ReplayTime released_at_;             // when its first record was released
};

class FaultStage {
 public:
  using Reporter = FaultInjector::Reporter;

  // Reads what `released` holds; `plan` empty: a pass-through. Faults are
  // reported to the reporter given to on_fault, by default as a line on
  // stderr. `memory`: what the faults of earlier client sessions left
  // behind (see FaultMemory); nullptr: the stage starts afresh. A device a
  // fault made lost is lost from the start.
  FaultStage(const FaultPlan& plan, bool datagrams, ReleasedRx& released,
             std::shared_ptr<FaultMemory> memory = nullptr, double speed = 1.0);
  FaultStage(const FaultStage&) = delete;
  FaultStage& operator=(const FaultStage&) = delete;

  void on_fault(Reporter reporter) { reporter_ = std::move(reporter); }
  // Whether there is a plan (otherwise the stage passes everything through).
  bool injects() const { return injector_ != nullptr; }

  // Moves released records through the faults, as far as the look-ahead
  // bounds; nothing to do without a plan.
  void pull(ReplayTime now);

  // --- the queue the client reads ---
  bool empty() const { return injector_ ? faulted_.empty() : released_.empty(); }
  RxItem& front() { return injector_ ? faulted_.front().item : released_.front(); }
  void pop();
  // Calls `visit(item)` for the queued records in order while it returns true.
  template <typename Visit>
  void visit(Visit&& visit) const {
    if (injector_) {
      for (const FaultedRx& faulted : faulted_) {
        if (!visit(faulted.item)) return;
      }
      return;
    }
    for (const RxItem& item : released_.items()) {
      if (!visit(item)) return;
    }
  }

  // --- what faults leave behind ---
  // The fault's loss of the device that is due now at the front of the
  // queue (its item's data says why); a reconnect that is over is dropped
  // first. nullptr when there is none.
  const RxItem* loss(ReplayTime now);
  // The device stopped answering: the client's writes go nowhere.
  bool swallows_writes() const { return injector_ && injector_->silenced(); }
  // Nothing more reaches the client, whatever the recording holds.
  bool rest_unreachable() const { return injector_ && injector_->rest_unreachable(); }

  // rx the client never read, queued before or after the faults: what a
  // fault made unreachable is not unused, and a client that gave up after a
  // fault (the right answer to most) left the rest unread for the fault's
  // sake, so nothing counts once a fault was injected.
  struct Unread {
    std::uint64_t bytes = 0;
    std::uint64_t records = 0;
  };
  std::optional<Unread> unread() const;

 private:
  void report(const FaultEvent& event) const;

  ReleasedRx& released_;
  std::unique_ptr<FaultInjector> injector_;
  std::deque<FaultedRx> faulted_;
  std::size_t faulted_bytes_ = 0;
  Reporter reporter_;
};

}  // namespace wiretape::detail
