#include "replay/request.hpp"

#include <algorithm>
#include <sstream>

#include "util/hex.hpp"

namespace wiretape::detail {

namespace {

bool starts_with(std::string_view text, std::string_view prefix) {
  return text.size() >= prefix.size() &&
         text.compare(0, prefix.size(), prefix) == 0;
}

}  // namespace

RequestStrategy::RequestStrategy(const ReplayConfig& config,
                                 const ReplayTimeline& timeline,
                                 ReleasedRx& released, MismatchReport& report,
                                 const RecordSourceFactory& sources)
    : config_(config), timeline_(timeline), released_(released), report_(report) {
  const std::unique_ptr<RecordSource> source = sources();
  load_exchanges(*source);
}

void RequestStrategy::load_exchanges(RecordSource& source) {
  Record record;
  bool in_request = false;
  std::uint64_t tx_offset = 0;
  bool device_gone = false;
  while (!device_gone && source.next(record)) {
    switch (record.kind) {
      case RecordKind::tx: {
        if (record.data.empty()) break;
        if (!in_request || config_.datagrams) {
          exchanges_.emplace_back();
          exchanges_.back().first_tx_t_ns = record.t_ns;
          exchanges_.back().tx_offset = tx_offset;
          in_request = true;
        }
        Exchange& exchange = exchanges_.back();
        exchange.request += record.data;
        exchange.last_tx_t_ns = record.t_ns;
        tx_offset += record.data.size();
        break;
      }
      case RecordKind::rx:
      case RecordKind::close:
      case RecordKind::device_lost: {
        if (record.kind == RecordKind::rx && record.data.empty()) break;
        device_gone = record.kind != RecordKind::rx;
        if (record.kind == RecordKind::close && !session_goes_on(source)) break;
        RxItem item;
        item.kind = record.kind;
        item.t_ns = record.t_ns;
        item.data = std::move(record.data);
        in_request = false;
        if (exchanges_.empty()) {
          // A greeting: released at open.
          item.due = timeline_.due(item.t_ns, std::nullopt);
          released_.push(std::move(item));
        } else {
          exchanges_.back().responses.push_back(std::move(item));
        }
        break;
      }
      default:
        break;
    }
  }
  for (std::size_t i = 0; i < exchanges_.size(); ++i) {
    groups_[exchanges_[i].request].push_back(i);
  }
}

bool RequestStrategy::more_to_release() const {
  for (const Exchange& exchange : exchanges_) {
    if (exchange.responses.empty()) continue;
    if (!exchange.used || config_.repeat != ReplayRepeat::none) return true;
  }
  return false;
}

void RequestStrategy::serve(std::size_t index, std::string_view request,
                            ReplayTime now) {
  Exchange& exchange = exchanges_[index];
  if (config_.check == ReplayCheck::timing) {
    if (const auto miss = timeline_.check_write(exchange.last_tx_t_ns, last_match_time_,
                                                last_match_t_ns_, now)) {
      report_.raise(miss->title, tx_written_,
                    std::string_view(exchange.request).substr(0, kReplayContext),
                    request.substr(0, kReplayContext), last_match_t_ns_,
                    static_cast<std::int64_t>(exchanges_served_), miss->detail);
    }
  }
  exchange.used = true;
  ++exchanges_served_;
  last_match_time_ = now;
  last_match_t_ns_ = exchange.last_tx_t_ns;
  // Causal timing counts each response from this match.
  const ReplayTimeline::Anchor matched{now, exchange.last_tx_t_ns};
  for (const RxItem& response : exchange.responses) {
    RxItem item = response;
    item.due = timeline_.due(item.t_ns, matched);
    released_.push(std::move(item));
  }
}

bool RequestStrategy::match_pending(ReplayTime now) {
  const auto matches = [&](const std::string& request) {
    return config_.datagrams ? pending_ == request : starts_with(pending_, request);
  };
  std::optional<std::size_t> chosen;
  for (std::size_t i = 0; i < exchanges_.size() && !chosen; ++i) {
    if (!exchanges_[i].used && matches(exchanges_[i].request)) chosen = i;
  }
  if (!chosen && config_.repeat != ReplayRepeat::none) {
    // Every exchange with this request is used up: serve one again.
    for (std::size_t i = 0; i < exchanges_.size() && !chosen; ++i) {
      const std::string& request = exchanges_[i].request;
      if (!matches(request)) continue;
      const std::vector<std::size_t>& uses = groups_[request];
      if (config_.repeat == ReplayRepeat::last) {
        chosen = uses.back();
      } else {
        std::size_t& cursor = group_cursor_[request];
        chosen = uses[cursor % uses.size()];
        ++cursor;
      }
    }
  }
  if (!chosen) return false;
  const std::size_t length = exchanges_[*chosen].request.size();
  serve(*chosen, std::string_view(pending_).substr(0, length), now);
  report_.accepted(std::string_view(pending_).substr(0, length));
  pending_.erase(0, length);
  pending_offset_ += length;
  return true;
}

void RequestStrategy::raise_unmatched() {
  // The closest unused requests: longest common prefix first, then order.
  std::vector<std::pair<std::size_t, std::size_t>> ranked;  // (prefix, index)
  for (std::size_t i = 0; i < exchanges_.size(); ++i) {
    if (exchanges_[i].used && config_.repeat == ReplayRepeat::none) continue;
    ranked.emplace_back(common_prefix(pending_, exchanges_[i].request), i);
  }
  std::stable_sort(ranked.begin(), ranked.end(),
                   [](const auto& a, const auto& b) { return a.first > b.first; });
  std::ostringstream extra;
  if (ranked.empty()) {
    extra << "  no unused request is left in the recording\n";
  } else {
    extra << "  closest unused requests:\n";
    for (std::size_t k = 0; k < ranked.size() && k < 3; ++k) {
      const Exchange& exchange = exchanges_[ranked[k].second];
      extra << "    exchange " << ranked[k].second << " (session time "
            << session_seconds(exchange.first_tx_t_ns) << " s): "
            << hex_ascii(std::string_view(exchange.request).substr(0, kReplayContext))
            << "\n";
    }
  }
  const std::size_t same = ranked.empty() ? 0 : ranked.front().first;
  const std::string_view expected =
      ranked.empty() ? std::string_view()
                     : std::string_view(exchanges_[ranked.front().second].request);
  const std::string actual = pending_;
  const std::uint64_t offset = pending_offset_ + same;
  const std::uint64_t t_ns =
      ranked.empty() ? last_match_t_ns_
                     : exchanges_[ranked.front().second].first_tx_t_ns;
  const std::int64_t exchange_number =
      ranked.empty() ? -1 : static_cast<std::int64_t>(ranked.front().second);
  // The unmatched bytes are dropped, so that the client can go on.
  pending_offset_ += pending_.size();
  pending_.clear();
  report_.raise("the client wrote a request that matches no unused exchange",
                offset, expected.substr(same, kReplayContext),
                std::string_view(actual).substr(same, kReplayContext), t_ns,
                exchange_number, extra.str());
}

void RequestStrategy::write(const char* data, std::size_t size, ReplayTime now) {
  // check=off replays as a device that ignores what it does not understand.
  const bool silent = config_.unmatched == ReplayUnmatched::silent ||
                      config_.check == ReplayCheck::off;
  if (config_.datagrams) {
    pending_.assign(data, size);
    pending_offset_ = tx_written_;
    tx_written_ += size;
    if (match_pending(now)) return;
    if (silent) {
      pending_.clear();
      return;
    }
    raise_unmatched();
  }
  pending_.append(data, size);
  tx_written_ += size;
  while (!pending_.empty()) {
    if (match_pending(now)) continue;
    bool could_complete = false;
    for (const Exchange& exchange : exchanges_) {
      if (exchange.used && config_.repeat == ReplayRepeat::none) continue;
      if (exchange.request.size() > pending_.size() &&
          starts_with(exchange.request, pending_)) {
        could_complete = true;
        break;
      }
    }
    if (could_complete) break;
    if (!silent) raise_unmatched();
    pending_.erase(0, 1);  // a device that ignores the byte
    ++pending_offset_;
  }
}

std::string RequestStrategy::unused_report(std::uint64_t queued_rx_bytes,
                                           std::uint64_t) {
  std::size_t unused = 0;
  std::ostringstream first;
  for (std::size_t i = 0; i < exchanges_.size(); ++i) {
    if (exchanges_[i].used) continue;
    if (unused < 3) {
      first << "\n  exchange " << i << ": "
            << hex_ascii(std::string_view(exchanges_[i].request).substr(0, kReplayContext));
    }
    ++unused;
  }
  std::ostringstream report;
  if (queued_rx_bytes > 0) {
    report << queued_rx_bytes << " released rx bytes were never read";
  }
  if (unused > 0) {
    if (queued_rx_bytes > 0) report << "; ";
    report << unused << " of " << exchanges_.size()
           << " recorded exchanges were never requested" << first.str();
  }
  return report.str();
}

}  // namespace wiretape::detail
