#include "replay/replay_engine.hpp"

#include <algorithm>
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
      strategy_(make_strategy(config_, timeline_, released_, report_, sources)) {}

ReplayEngine::~ReplayEngine() = default;

void ReplayEngine::prepare(ReplayTime now) { strategy_->release(now); }

std::size_t ReplayEngine::read(char* buffer, std::size_t size, ReplayTime now) {
  prepare(now);
  std::size_t copied = 0;
  while (copied < size) {
    if (released_.empty()) {
      prepare(now);
      if (released_.empty()) break;
    }
    RxItem& item = released_.front();
    if (!is_due(item, now)) break;
    if (item.kind != RecordKind::rx) {
      if (copied > 0) break;
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
      released_.pop_front();
      return n;
    }
    const std::size_t n = std::min(size - copied, payload.size() - item.consumed);
    std::memcpy(buffer + copied, payload.data() + item.consumed, n);
    item.consumed += n;
    copied += n;
    if (item.consumed == payload.size()) released_.pop_front();
  }
  return copied;
}

std::size_t ReplayEngine::available(ReplayTime now) {
  prepare(now);
  std::size_t total = 0;
  for (const RxItem& item : released_.items()) {
    if (item.kind != RecordKind::rx || !is_due(item, now)) break;
    if (config_.datagrams) return item.payload().size();
    total += item.payload().size() - item.consumed;
  }
  return total;
}

ReplayEngine::Outlook ReplayEngine::outlook(ReplayTime now) {
  prepare(now);
  const std::optional<ReplayTime> strategy_wake = strategy_->wake();
  if (!released_.empty()) {
    const RxItem& front = released_.front();
    if (is_due(front, now)) {
      return {front.kind == RecordKind::rx ? ReadState::readable
                                           : ReadState::device_gone,
              std::nullopt};
    }
    return {ReadState::waiting,
            strategy_wake ? std::min(front.due, *strategy_wake) : front.due};
  }
  if (strategy_wake) return {ReadState::waiting, strategy_wake};
  return {strategy_->more_to_release() ? ReadState::waiting : ReadState::ended,
          std::nullopt};
}

void ReplayEngine::flush_input(ReplayTime now) {
  prepare(now);
  while (!released_.empty() && released_.front().kind == RecordKind::rx &&
         is_due(released_.front(), now)) {
    released_.pop_front();
    if (released_.empty()) prepare(now);
  }
  // What the flush entitles is released after it, not dropped by it.
  client_flushed();
}

void ReplayEngine::client_flushed() { strategy_->client_flushed(); }

void ReplayEngine::write(const char* data, std::size_t size, ReplayTime now) {
  if (size == 0) return;
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
