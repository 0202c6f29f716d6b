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
                           ReplayTime open_time, std::uint64_t origin_ns,
                           std::shared_ptr<FaultMemory> fault_memory)
    : config_(std::move(config)),
      timeline_(config_, open_time, origin_ns),
      released_(/*recycle_payloads=*/true),
      report_(config_.file, config_.match, config_.several_channels ? config_.channel : ""),
      stage_(config_.faults, config_.datagrams, released_, std::move(fault_memory),
             config_.speed),
      strategy_(make_strategy(config_, timeline_, released_, report_, sources)) {}

ReplayEngine::~ReplayEngine() = default;

void ReplayEngine::prepare(ReplayTime now) {
  strategy_->release(now);
  stage_.pull(now);
}

// Raises PortClosed for what the stage holds instead of due rx: a fault's
// loss, a recorded close or device loss.
void ReplayEngine::raise_device_gone(const RxItem& item) const {
  throw PortClosed("replay of " + config_.file + ": the recorded device " +
                   (item.kind == RecordKind::close ? "was closed" : "went away") +
                   " at session time " + session_seconds(item.t_ns) + " s");
}

std::size_t ReplayEngine::read(char* buffer, std::size_t size, ReplayTime now) {
  if (config_.datagrams) {
    // A read of 0 bytes says nothing is due: an empty datagram is passed
    // over here (read_datagram serves it).
    for (;;) {
      const std::optional<std::size_t> n = read_datagram(buffer, size, now);
      if (!n) return 0;
      if (*n > 0 || size == 0) return *n;
    }
  }
  prepare(now);
  std::size_t copied = 0;
  while (copied < size) {
    if (stage_.empty()) {
      prepare(now);
      if (stage_.empty()) break;
    }
    if (const RxItem* loss = stage_.loss(now)) {
      if (copied > 0) break;
      throw PortClosed("replay of " + config_.file + ": " + loss->data);
    }
    if (stage_.empty()) continue;  // a reconnect that is over was dropped
    RxItem& item = stage_.front();
    if (!is_due(item, now)) break;
    if (item.kind != RecordKind::rx) {
      if (copied > 0) break;
      raise_device_gone(item);
    }
    const std::string_view payload = item.payload();
    const std::size_t n = std::min(size - copied, payload.size() - item.consumed);
    std::memcpy(buffer + copied, payload.data() + item.consumed, n);
    item.consumed += n;
    copied += n;
    if (item.consumed == payload.size()) stage_.pop();
  }
  return copied;
}

std::optional<std::size_t> ReplayEngine::read_datagram(char* buffer, std::size_t size,
                                                       ReplayTime now) {
  prepare(now);
  for (;;) {
    if (stage_.empty()) {
      prepare(now);
      if (stage_.empty()) return std::nullopt;
    }
    if (const RxItem* loss = stage_.loss(now)) {
      throw PortClosed("replay of " + config_.file + ": " + loss->data);
    }
    if (stage_.empty()) continue;  // a reconnect that is over was dropped
    const RxItem& item = stage_.front();
    if (!is_due(item, now)) return std::nullopt;
    if (item.kind != RecordKind::rx) raise_device_gone(item);
    const std::string_view payload = item.payload();
    const std::size_t n = std::min(size, payload.size());
    if (n > 0) std::memcpy(buffer, payload.data(), n);
    stage_.pop();
    return n;
  }
}

std::optional<std::size_t> ReplayEngine::peek(char* buffer, std::size_t size, ReplayTime now) {
  if (config_.datagrams) return std::nullopt;
  prepare(now);
  if (stage_.loss(now) != nullptr) return std::nullopt;
  if (stage_.empty()) return 0;
  const RxItem& front = stage_.front();
  if (is_due(front, now) && front.kind != RecordKind::rx) return std::nullopt;
  std::size_t copied = 0;
  stage_.visit([&](const RxItem& item) {
    if (item.kind != RecordKind::rx || !is_due(item, now)) return false;
    const std::string_view payload = item.payload();
    const std::size_t n = std::min(size - copied, payload.size() - item.consumed);
    std::memcpy(buffer + copied, payload.data() + item.consumed, n);
    copied += n;
    return copied < size;
  });
  return copied;
}

std::size_t ReplayEngine::available(ReplayTime now) {
  prepare(now);
  std::size_t total = 0;
  stage_.loss(now);  // drops a reconnect that is over
  stage_.visit([&](const RxItem& item) {
    if (item.kind != RecordKind::rx || !is_due(item, now)) return false;
    if (config_.datagrams && item.payload().empty()) return true;  // read() passes it over
    total += config_.datagrams ? item.payload().size() : item.payload().size() - item.consumed;
    return !config_.datagrams;
  });
  return total;
}

ReplayEngine::Outlook ReplayEngine::outlook(ReplayTime now) {
  prepare(now);
  const std::optional<ReplayTime> strategy_wake = strategy_->wake();
  stage_.loss(now);  // drops a reconnect that is over
  if (!stage_.empty()) {
    const RxItem& front = stage_.front();
    if (is_due(front, now)) {
      return {front.kind == RecordKind::rx ? ReadState::readable
                                           : ReadState::device_gone,
              std::nullopt};
    }
    return {ReadState::waiting,
            strategy_wake ? std::min(front.due, *strategy_wake) : front.due};
  }
  if (stage_.rest_unreachable()) return {ReadState::ended, std::nullopt};
  if (strategy_wake) return {ReadState::waiting, strategy_wake};
  return {strategy_->more_to_release() ? ReadState::waiting : ReadState::ended,
          std::nullopt};
}

void ReplayEngine::flush_input(ReplayTime now) {
  prepare(now);
  while (!stage_.empty() && stage_.front().kind == RecordKind::rx &&
         is_due(stage_.front(), now)) {
    stage_.pop();
    if (stage_.empty()) prepare(now);
  }
  // What the flush entitles is released after it, not dropped by it.
  client_flushed();
}

void ReplayEngine::client_flushed() { strategy_->client_flushed(); }

ModemInputs ReplayEngine::device_lines(ReplayTime now) {
  // Released rx is left where it is: the fault stage takes it as reads do.
  strategy_->release(now);
  return released_.device_lines(now);
}

void ReplayEngine::write(const char* data, std::size_t size, ReplayTime now) {
  if (size == 0 && !replays_empty_datagrams(config_)) return;
  if (const RxItem* loss = stage_.loss(now)) {
    throw PortClosed("replay of " + config_.file + ": " + loss->data);
  }
  if (stage_.swallows_writes()) return;  // a device that stopped answering
  strategy_->write(data, size, now);
}

void ReplayEngine::client_event(RecordKind kind,
                                const std::map<std::string, std::string>& fields,
                                ReplayTime) {
  strategy_->client_event(kind, fields);
}

std::string ReplayEngine::unused_report() {
  const std::optional<FaultStage::Unread> unread = stage_.unread();
  if (!unread) return {};
  const std::string text = strategy_->unused_report(unread->bytes, unread->records);
  if (text.empty()) return text;
  const std::string channel =
      config_.several_channels ? "channel " + config_.channel + ": " : "";
  return "replay of " + config_.file + ": " + channel + text;
}

}  // namespace wiretape::detail
