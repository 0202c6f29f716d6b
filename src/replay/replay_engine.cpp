#include "replay/replay_engine.hpp"

#include <algorithm>
#include <cstdio>
#include <cstring>

#include "replay/request.hpp"
#include "replay/sequence.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

namespace {

std::unique_ptr<ReplayStrategy> make_strategy(const ReplayConfig& config,
                                              const ReplayTimeline& timeline,
                                              ReleasedRx& released,
                                              MismatchReport& report,
                                              const RecordSourceFactory& sources) {
  switch (config.match) {
    case ReplayMatch::sequence:
      return std::make_unique<SequenceStrategy>(config, timeline, released,
                                                report, sources);
    case ReplayMatch::request:
      break;
  }
  return std::make_unique<RequestStrategy>(config, timeline, released, report,
                                           sources);
}

bool is_due(const RxItem& item, ReplayTime now) { return item.due <= now; }

}  // namespace

ReplayEngine::ReplayEngine(ReplayConfig config, RecordSourceFactory sources,
                           ReplayTime open_time, std::uint64_t origin_ns)
    : config_(std::move(config)),
      timeline_(config_, open_time, origin_ns),
      released_(/*recycle_payloads=*/true),
      report_(config_.file, config_.match),
      strategy_(make_strategy(config_, timeline_, released_, report_, sources)) {
  // --- fault injection hook ---
  if (!config_.faults.empty()) {
    FaultPlan plan = parse_faults(config_.faults, config_.seed);
    if (!plan.empty()) {
      faults_ = std::make_unique<FaultInjector>(
          std::move(plan), config_.datagrams, [this](const FaultEvent& event) {
            if (fault_reporter_) {
              fault_reporter_(event);
              return;
            }
            std::fprintf(stderr, "wiretape: fault %s@%s: %s\n", event.kind.c_str(),
                         event.where.c_str(), event.detail.c_str());
          });
    }
  }
}

ReplayEngine::~ReplayEngine() = default;

void ReplayEngine::prepare(ReplayTime now) {
  strategy_->release(now);
  if (faults_) inject_faults(now);
}

// --- fault injection ---------------------------------------------------------

void ReplayEngine::inject_faults(ReplayTime now) {
  while (!released_.empty() && faulted_.size() < kLookaheadRecords &&
         faulted_bytes_ < kLookaheadBytes) {
    RxItem item = released_.front();  // a copy: pop_front counts its bytes
    released_.pop_front();
    const std::uint64_t exchange = item.exchange;  // numbered by the strategy
    const std::size_t before = faulted_.size();
    faults_->apply(std::move(item), exchange, faulted_, now);
    for (std::size_t i = before; i < faulted_.size(); ++i) {
      faulted_bytes_ += faulted_[i].item.payload().size();
    }
  }
}

void ReplayEngine::queue_pop() {
  if (!faults_) {
    released_.pop_front();
    return;
  }
  faulted_bytes_ -= faulted_.front().item.payload().size();
  faulted_.pop_front();
}

const RxItem* ReplayEngine::fault_loss(ReplayTime now) {
  while (faults_ && !faulted_.empty()) {
    const FaultedRx& front = faulted_.front();
    if (front.item.kind != RecordKind::device_lost || front.item.data.empty() ||
        !is_due(front.item, now)) {
      return nullptr;
    }
    if (!front.back_at || now < *front.back_at) return &front.item;
    queue_pop();  // reconnected
  }
  return nullptr;
}

std::size_t ReplayEngine::read(char* buffer, std::size_t size, ReplayTime now) {
  prepare(now);
  std::size_t copied = 0;
  while (copied < size) {
    if (faults_) fault_loss(now);
    if (queue_empty()) {
      prepare(now);
      if (queue_empty()) break;
    }
    RxItem& item = queue_front();
    if (!is_due(item, now)) break;
    if (item.kind != RecordKind::rx) {
      if (copied > 0) break;
      if (faults_ && !item.data.empty()) {
        throw PortClosed("replay of " + config_.file + ": " + item.data);
      }
      throw PortClosed("replay of " + config_.file + ": the recorded device " +
                       (item.kind == RecordKind::close ? "was closed"
                                                       : "went away") +
                       " at session time " + session_seconds(item.t_ns) + " s");
    }
    const std::string_view payload = item.payload();
    if (config_.datagrams) {
      if (copied > 0) break;
      // One datagram per read; a shorter read truncates it, as recv does.
      const std::size_t n = std::min(size, payload.size());
      std::memcpy(buffer, payload.data(), n);
      queue_pop();
      return n;
    }
    const std::size_t n = std::min(size - copied, payload.size() - item.consumed);
    std::memcpy(buffer + copied, payload.data() + item.consumed, n);
    item.consumed += n;
    copied += n;
    if (item.consumed == payload.size()) queue_pop();
  }
  return copied;
}

std::size_t ReplayEngine::available(ReplayTime now) {
  prepare(now);
  std::size_t total = 0;
  const auto count = [&](const RxItem& item) {
    if (item.kind != RecordKind::rx || !is_due(item, now)) return false;
    total += config_.datagrams ? item.payload().size() : item.payload().size() - item.consumed;
    return !config_.datagrams;
  };
  if (faults_) {
    fault_loss(now);
    for (const FaultedRx& faulted : faulted_) {
      if (!count(faulted.item)) break;
    }
    return total;
  }
  for (const RxItem& item : released_.items()) {
    if (!count(item)) break;
  }
  return total;
}

ReplayEngine::Outlook ReplayEngine::outlook(ReplayTime now) {
  prepare(now);
  const std::optional<ReplayTime> strategy_wake = strategy_->wake();
  if (faults_) fault_loss(now);
  if (!queue_empty()) {
    const RxItem& front = queue_front();
    if (is_due(front, now)) {
      return {front.kind == RecordKind::rx ? ReadState::readable
                                           : ReadState::device_gone,
              std::nullopt};
    }
    return {ReadState::waiting,
            strategy_wake ? std::min(front.due, *strategy_wake) : front.due};
  }
  if (faults_ && faults_->rest_unreachable()) return {ReadState::ended, std::nullopt};
  if (strategy_wake) return {ReadState::waiting, strategy_wake};
  return {strategy_->more_to_release() ? ReadState::waiting : ReadState::ended,
          std::nullopt};
}

void ReplayEngine::flush_input(ReplayTime now) {
  prepare(now);
  while (!queue_empty() && queue_front().kind == RecordKind::rx &&
         is_due(queue_front(), now)) {
    queue_pop();
    if (queue_empty()) prepare(now);
  }
  // What the flush entitles is released after it, not dropped by it.
  client_flushed();
}

void ReplayEngine::client_flushed() { strategy_->client_flushed(); }

void ReplayEngine::write(const char* data, std::size_t size, ReplayTime now) {
  if (size == 0) return;
  if (faults_) {
    if (const RxItem* loss = fault_loss(now)) {
      throw PortClosed("replay of " + config_.file + ": " + loss->data);
    }
    if (faults_->silenced()) return;  // a device that stopped answering
    strategy_->write(data, size, now);
    return;
  }
  strategy_->write(data, size, now);
}

void ReplayEngine::client_event(RecordKind kind,
                                const std::map<std::string, std::string>& fields,
                                ReplayTime) {
  strategy_->client_event(kind, fields);
}

std::string ReplayEngine::unused_report() {
  std::uint64_t rx_bytes = 0;
  std::uint64_t rx_records = 0;
  if (faults_) {
    // What a fault made unreachable is not unused; and a client that gave
    // up after a fault (the right answer to most) left the rest unread for
    // the fault's sake.
    if (faults_->injected() > 0) return {};
    for (const FaultedRx& faulted : faulted_) {
      if (faulted.item.kind != RecordKind::rx) continue;
      rx_bytes += faulted.item.payload().size() - faulted.item.consumed;
      ++rx_records;
    }
  }
  for (const RxItem& item : released_.items()) {
    if (item.kind != RecordKind::rx) continue;
    rx_bytes += item.payload().size() - item.consumed;
    ++rx_records;
  }
  const std::string text = strategy_->unused_report(rx_bytes, rx_records);
  if (text.empty()) return text;
  return "replay of " + config_.file + ": " + text;
}

}  // namespace wiretape::detail
