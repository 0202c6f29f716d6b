#include "replay/replay_engine.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <sstream>

#include "util/json.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

namespace {

// Look-ahead of the read cursor: enough that a large read is served in one
// go, small enough that memory does not depend on the session's size.
constexpr std::size_t kLookaheadRecords = 256;
constexpr std::size_t kLookaheadBytes = 1 << 20;
constexpr std::size_t kContext = 16;

std::string seconds(std::uint64_t ns) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6f", static_cast<double>(ns) / 1e9);
  return text;
}

std::string milliseconds_text(std::chrono::nanoseconds ns) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3f",
                static_cast<double>(ns.count()) / 1e6);
  return text;
}

bool starts_with(std::string_view text, std::string_view prefix) {
  return text.size() >= prefix.size() &&
         text.compare(0, prefix.size(), prefix) == 0;
}

std::size_t common_prefix(std::string_view a, std::string_view b) {
  const std::size_t limit = std::min(a.size(), b.size());
  std::size_t i = 0;
  while (i < limit && a[i] == b[i]) ++i;
  return i;
}

void keep_tail(std::string& history, std::string_view added) {
  if (added.size() >= kContext) {
    history.assign(added.substr(added.size() - kContext));
    return;
  }
  history.append(added);
  if (history.size() > kContext) history.erase(0, history.size() - kContext);
}

// A recorded close is the device going away only when the session goes on
// after it; the close that ends a recording (the client closing its port) is
// just the end, where at_end applies. Consumes the source.
bool session_goes_on(RecordSource& source) {
  Record record;
  while (source.next(record)) {
    if ((record.kind == RecordKind::rx || record.kind == RecordKind::tx) &&
        !record.data.empty()) {
      return true;
    }
    if (record.kind == RecordKind::device_lost) return true;
  }
  return false;
}

}  // namespace

std::string hex_ascii(std::string_view bytes) {
  static const char digits[] = "0123456789abcdef";
  std::string hex;
  std::string ascii;
  for (unsigned char byte : bytes) {
    if (!hex.empty()) hex.push_back(' ');
    hex.push_back(digits[byte >> 4]);
    hex.push_back(digits[byte & 0xf]);
    ascii.push_back(byte >= 0x20 && byte < 0x7f ? static_cast<char>(byte) : '.');
  }
  if (bytes.empty()) return "(none)";
  return hex + "  |" + ascii + "|";
}

ReplayEngine::ReplayEngine(ReplayConfig config, RecordSourceFactory sources,
                           ReplayTime open_time)
    : config_(std::move(config)),
      sources_(std::move(sources)),
      open_time_(open_time) {
  if (config_.match == ReplayMatch::sequence) {
    rx_source_ = sources_();
    tx_source_ = sources_();
    fill_rx();
    entitle();
  } else {
    load_exchanges();
  }
}

ReplayEngine::~ReplayEngine() = default;

std::chrono::nanoseconds ReplayEngine::scaled(std::uint64_t ns) const {
  return std::chrono::nanoseconds(
      static_cast<std::int64_t>(std::llround(static_cast<double>(ns) / config_.speed)));
}

ReplayTime ReplayEngine::due_by_session_clock(std::uint64_t t_ns) const {
  return config_.timing == ReplayTiming::none ? open_time_ : open_time_ + scaled(t_ns);
}

// --- the read side -----------------------------------------------------------

void ReplayEngine::fill_rx() {
  if (config_.match != ReplayMatch::sequence) return;
  Record record;
  PayloadView view;
  record.data = spare_payload();
  while (!rx_exhausted_ && rx_queue_.size() < kLookaheadRecords &&
         rx_queue_bytes_ < kLookaheadBytes) {
    if (!rx_source_->next(record, view)) {
      rx_exhausted_ = true;
      break;
    }
    const std::size_t size = view ? view.bytes.size() : record.data.size();
    switch (record.kind) {
      case RecordKind::tx:
        if (size == 0) break;
        rx_tx_seen_ += size;
        rx_last_tx_t_ns_ = record.t_ns;
        break;
      case RecordKind::rx:
      case RecordKind::close:
      case RecordKind::device_lost: {
        if (record.kind == RecordKind::rx && size == 0) break;
        if (record.kind == RecordKind::close && !session_goes_on(*rx_source_)) {
          rx_exhausted_ = true;
          break;
        }
        RxItem item;
        item.kind = record.kind;
        item.t_ns = record.t_ns;
        item.tx_before = rx_tx_seen_;
        item.anchor_t_ns = rx_last_tx_t_ns_;
        rx_queue_bytes_ += size;
        if (view) {
          item.view = std::move(view);
        } else {
          item.data = std::move(record.data);
          record.data = spare_payload();
        }
        rx_queue_.push_back(std::move(item));
        // The device is gone: nothing after this point is served.
        if (record.kind != RecordKind::rx) rx_exhausted_ = true;
        break;
      }
      default:
        break;  // events are not replayed to the client
    }
  }
  recycle_payload(std::move(record.data));
}

std::string ReplayEngine::spare_payload() {
  if (spare_payloads_.empty()) return {};
  std::string buffer = std::move(spare_payloads_.back());
  spare_payloads_.pop_back();
  spare_bytes_ -= buffer.capacity();
  return buffer;
}

void ReplayEngine::recycle_payload(std::string&& buffer) {
  // Bounded like the look-ahead, so memory stays independent of the session.
  if (config_.match != ReplayMatch::sequence || buffer.capacity() == 0 ||
      spare_payloads_.size() >= kLookaheadRecords ||
      spare_bytes_ + buffer.capacity() > kLookaheadBytes) {
    return;
  }
  buffer.clear();
  spare_bytes_ += buffer.capacity();
  spare_payloads_.push_back(std::move(buffer));
}

void ReplayEngine::entitle() {
  if (config_.match != ReplayMatch::sequence) return;
  // Items before first_unentitled_ all have their due time already.
  for (; first_unentitled_ < rx_queue_.size(); ++first_unentitled_) {
    RxItem& item = rx_queue_[first_unentitled_];
    const bool entitled = config_.timing == ReplayTiming::session ||
                          tx_written_ >= item.tx_before;
    if (!entitled) break;  // later records need at least as many tx bytes
    switch (config_.timing) {
      case ReplayTiming::none:
      case ReplayTiming::session:
        item.due = due_by_session_clock(item.t_ns);
        break;
      case ReplayTiming::causal: {
        if (!item.anchor_t_ns) {
          item.due = due_by_session_clock(item.t_ns);
          break;
        }
        ReplayTime finished = previous_tx_finished_.value_or(open_time_);
        for (const TxEnd& end : tx_ends_) {
          if (end.end_offset >= item.tx_before) {
            finished = end.finished;
            break;
          }
        }
        const std::uint64_t gap =
            item.t_ns > *item.anchor_t_ns ? item.t_ns - *item.anchor_t_ns : 0;
        item.due = finished + scaled(gap);
        break;
      }
    }
  }
  // Finish times the read cursor will never ask for again.
  const std::uint64_t still_needed =
      rx_queue_.empty() ? rx_tx_seen_ : rx_queue_.front().tx_before;
  while (tx_ends_.size() > 1 && tx_ends_.front().end_offset < still_needed) {
    tx_ends_.pop_front();
  }
}

void ReplayEngine::prepare(ReplayTime) {
  if (rx_queue_.empty() || rx_queue_bytes_ < kLookaheadBytes / 2) fill_rx();
  entitle();
}

void ReplayEngine::pop_rx() {
  recycle_payload(std::move(rx_queue_.front().data));
  rx_queue_.pop_front();
  if (first_unentitled_ > 0) --first_unentitled_;
}

bool ReplayEngine::is_due(const RxItem& item, ReplayTime now) const {
  return item.due && *item.due <= now;
}

std::size_t ReplayEngine::read(char* buffer, std::size_t size, ReplayTime now) {
  prepare(now);
  std::size_t copied = 0;
  while (copied < size) {
    if (rx_queue_.empty()) {
      if (config_.match != ReplayMatch::sequence || rx_exhausted_) break;
      fill_rx();
      entitle();
      if (rx_queue_.empty()) break;
    }
    RxItem& item = rx_queue_.front();
    if (!is_due(item, now)) break;
    if (item.kind != RecordKind::rx) {
      if (copied > 0) break;
      throw PortClosed("replay of " + config_.file + ": the recorded device " +
                       (item.kind == RecordKind::close ? "was closed"
                                                       : "went away") +
                       " at session time " + seconds(item.t_ns) + " s");
    }
    const std::string_view payload = item.payload();
    if (config_.datagrams) {
      if (copied > 0) break;
      // One datagram per read; a shorter read truncates it, as recv does.
      const std::size_t n = std::min(size, payload.size());
      std::memcpy(buffer, payload.data(), n);
      rx_queue_bytes_ -= payload.size();
      pop_rx();
      return n;
    }
    const std::size_t n = std::min(size - copied, payload.size() - item.consumed);
    std::memcpy(buffer + copied, payload.data() + item.consumed, n);
    item.consumed += n;
    copied += n;
    if (item.consumed == payload.size()) {
      rx_queue_bytes_ -= payload.size();
      pop_rx();
    }
  }
  return copied;
}

std::size_t ReplayEngine::available(ReplayTime now) {
  prepare(now);
  std::size_t total = 0;
  for (const RxItem& item : rx_queue_) {
    if (item.kind != RecordKind::rx || !is_due(item, now)) break;
    if (config_.datagrams) return item.payload().size();
    total += item.payload().size() - item.consumed;
  }
  return total;
}

ReplayEngine::Outlook ReplayEngine::outlook(ReplayTime now) {
  prepare(now);
  if (!rx_queue_.empty()) {
    const RxItem& front = rx_queue_.front();
    if (!front.due) return {ReadState::waiting, std::nullopt};
    if (*front.due <= now) {
      return {front.kind == RecordKind::rx ? ReadState::readable
                                           : ReadState::device_gone,
              std::nullopt};
    }
    return {ReadState::waiting, front.due};
  }
  if (config_.match == ReplayMatch::sequence) {
    return {rx_exhausted_ ? ReadState::ended : ReadState::waiting, std::nullopt};
  }
  for (const Exchange& exchange : exchanges_) {
    if (exchange.responses.empty()) continue;
    if (!exchange.used || config_.repeat != ReplayRepeat::none) {
      return {ReadState::waiting, std::nullopt};
    }
  }
  return {ReadState::ended, std::nullopt};
}

void ReplayEngine::flush_input(ReplayTime now) {
  prepare(now);
  while (!rx_queue_.empty() && rx_queue_.front().kind == RecordKind::rx &&
         is_due(rx_queue_.front(), now)) {
    rx_queue_bytes_ -= rx_queue_.front().payload().size();
    pop_rx();
    if (rx_queue_.empty()) prepare(now);
  }
}

// --- the write side, match=sequence --------------------------------------------

bool ReplayEngine::next_tx_record() {
  Record record;
  while (!have_tx_record_ && !tx_exhausted_) {
    if (!tx_source_->next(record)) {
      tx_exhausted_ = true;
      break;
    }
    switch (record.kind) {
      case RecordKind::tx:
        if (record.data.empty()) break;
        if (tx_after_rx_) {
          ++tx_exchange_;
          tx_after_rx_ = false;
        }
        tx_record_ = std::move(record);
        tx_position_ = 0;
        have_tx_record_ = true;
        break;
      case RecordKind::rx:
        if (!record.data.empty()) tx_after_rx_ = true;
        break;
      case RecordKind::settings:
      case RecordKind::modem_lines:
      case RecordKind::line_break:
        if (checks_events()) expected_events_.push_back(std::move(record));
        break;
      case RecordKind::close:
      case RecordKind::device_lost:
        tx_hit_close_ = record.kind == RecordKind::device_lost ||
                        session_goes_on(*tx_source_);
        tx_close_t_ns_ = record.t_ns;
        tx_exhausted_ = true;
        break;
      default:
        break;
    }
  }
  return have_tx_record_;
}

void ReplayEngine::check_tx_timing(ReplayTime due, ReplayTime now) {
  if (config_.check != ReplayCheck::timing) return;
  const auto offset = now - due;
  if (offset >= -config_.tolerance && offset <= config_.tolerance) return;
  const bool early = offset < decltype(offset)::zero();
  const std::string extra =
      "  the write came " +
      milliseconds_text(std::chrono::duration_cast<std::chrono::nanoseconds>(
          early ? -offset : offset)) +
      " ms " + (early ? "early" : "late") + " (tolerance " +
      milliseconds_text(config_.tolerance) + " ms, timing=" +
      (config_.timing == ReplayTiming::session ? "session" : "causal") + ")\n";
  const std::string_view expected =
      config_.match == ReplayMatch::sequence
          ? std::string_view(tx_record_.data).substr(0, kContext)
          : std::string_view();
  raise_mismatch(std::string("the client wrote too ") +
                     (early ? "early" : "late"),
                 tx_written_, expected, expected,
                 config_.match == ReplayMatch::sequence ? tx_record_.t_ns
                                                        : last_match_t_ns_,
                 config_.match == ReplayMatch::sequence
                     ? tx_exchange_
                     : static_cast<std::int64_t>(exchanges_served_),
                 extra);
}

void ReplayEngine::write_sequence(const char* data, std::size_t size,
                                  ReplayTime now) {
  const bool compare = config_.check != ReplayCheck::off;
  std::size_t done = 0;
  while (done < size) {
    const std::string_view rest(data + done, size - done);
    if (!next_tx_record()) {
      if (tx_hit_close_) {
        throw PortClosed("replay of " + config_.file +
                         ": the recorded device was closed at session time " +
                         seconds(tx_close_t_ns_) + " s; it takes no more writes");
      }
      if (compare) {
        raise_mismatch("the client wrote more than the recording holds",
                       tx_written_, {}, rest.substr(0, kContext),
                       previous_tx_t_ns_, tx_exchange_);
      }
      tx_written_ += rest.size();
      keep_tail(tx_history_, rest);
      return;
    }
    const std::string& expected = tx_record_.data;
    if (tx_position_ == 0 && !expected_events_.empty()) {
      const Record& missing = expected_events_.front();
      raise_mismatch("the recording has a " + std::string(to_string(missing.kind)) +
                         " event " + missing.data +
                         " before these bytes, and the client did not make it",
                     tx_written_, std::string_view(expected).substr(0, kContext),
                     rest.substr(0, kContext), missing.t_ns, tx_exchange_);
    }
    if (tx_position_ == 0 && config_.check == ReplayCheck::timing) {
      const ReplayTime due =
          config_.timing == ReplayTiming::session || !previous_tx_finished_
              ? open_time_ + scaled(tx_record_.t_ns)
              : *previous_tx_finished_ +
                    scaled(tx_record_.t_ns > previous_tx_t_ns_
                               ? tx_record_.t_ns - previous_tx_t_ns_
                               : 0);
      check_tx_timing(due, now);
    }
    std::size_t accepted;
    if (config_.datagrams) {
      if (compare && (done != 0 || rest != expected)) {
        raise_mismatch("the client's datagram differs from the recorded one (" +
                           std::to_string(rest.size()) + " bytes written, " +
                           std::to_string(expected.size()) + " recorded)",
                       tx_written_, std::string_view(expected).substr(0, kContext),
                       rest.substr(0, kContext), tx_record_.t_ns, tx_exchange_);
      }
      // One datagram is one record, whatever its length.
      tx_written_ += expected.size();
      keep_tail(tx_history_, expected);
      accepted = rest.size();
    } else {
      const std::size_t n = std::min(rest.size(), expected.size() - tx_position_);
      const std::string_view want(expected.data() + tx_position_, n);
      if (compare) {
        const std::size_t same = common_prefix(want, rest.substr(0, n));
        if (same < n) {
          // The equal part was accepted; the report starts at the difference.
          tx_position_ += same;
          tx_written_ += same;
          keep_tail(tx_history_, rest.substr(0, same));
          raise_mismatch(
              "the client wrote bytes that differ from the recording",
              tx_written_,
              std::string_view(expected).substr(tx_position_, kContext),
              rest.substr(same, kContext), tx_record_.t_ns, tx_exchange_);
        }
      }
      tx_position_ += n;
      tx_written_ += n;
      keep_tail(tx_history_, rest.substr(0, n));
      accepted = n;
      if (tx_position_ < expected.size()) {
        done += accepted;
        continue;
      }
    }
    tx_ends_.push_back({tx_written_, now});
    previous_tx_finished_ = now;
    previous_tx_t_ns_ = tx_record_.t_ns;
    have_tx_record_ = false;
    done += accepted;
    if (config_.datagrams) return;
  }
}

bool ReplayEngine::checks_events() const {
  return config_.check == ReplayCheck::timing &&
         config_.match == ReplayMatch::sequence;
}

namespace {

std::string member_text(const json::Value& value) {
  switch (value.type) {
    case json::Value::Type::boolean:
      return value.boolean ? "true" : "false";
    case json::Value::Type::number:
    case json::Value::Type::string:
      return value.text;
    default:
      return json::serialize(value);
  }
}

std::string fields_json(const std::map<std::string, std::string>& fields) {
  std::string text = "{";
  for (const auto& [key, value] : fields) {
    if (text.size() > 1) text += ",";
    const bool bare = value == "true" || value == "false" ||
                      (!value.empty() &&
                       value.find_first_not_of("-0123456789.") == std::string::npos);
    text += json::quote(key) + ":" + (bare ? value : json::quote(value));
  }
  return text + "}";
}

}  // namespace

void ReplayEngine::client_event(RecordKind kind,
                                const std::map<std::string, std::string>& fields,
                                ReplayTime) {
  if (!checks_events()) return;
  if (!have_tx_record_ || tx_position_ == 0) next_tx_record();
  const std::string made = std::string(to_string(kind)) + " " + fields_json(fields);
  if (expected_events_.empty()) {
    raise_mismatch("the client made a " + made +
                       " event where the recording has none",
                   tx_written_, {}, {}, previous_tx_t_ns_, tx_exchange_);
  }
  const Record& recorded = expected_events_.front();
  bool same = recorded.kind == kind;
  if (same) {
    try {
      const json::Value value = json::parse(recorded.data.empty() ? "{}" : recorded.data);
      // Only what both say is compared (set_baud against a full configure).
      for (const auto& [key, text] : fields) {
        const json::Value* member = value.find(key);
        if (member != nullptr && member_text(*member) != text) same = false;
      }
    } catch (const json::ParseError&) {
      same = false;
    }
  }
  if (!same) {
    raise_mismatch("the client made a " + made + " event; the recording has " +
                       std::string(to_string(recorded.kind)) + " " + recorded.data,
                   tx_written_, {}, {}, recorded.t_ns, tx_exchange_);
  }
  expected_events_.pop_front();
}

// --- the write side, match=request ---------------------------------------------

void ReplayEngine::load_exchanges() {
  auto source = sources_();
  Record record;
  bool in_request = false;
  std::uint64_t tx_offset = 0;
  bool device_gone = false;
  while (!device_gone && source->next(record)) {
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
        if (record.kind == RecordKind::close && !session_goes_on(*source)) break;
        RxItem item;
        item.kind = record.kind;
        item.t_ns = record.t_ns;
        item.data = std::move(record.data);
        in_request = false;
        if (exchanges_.empty()) {
          // A greeting: released at open.
          item.due = due_by_session_clock(item.t_ns);
          rx_queue_bytes_ += item.data.size();
          rx_queue_.push_back(std::move(item));
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

void ReplayEngine::serve(std::size_t index, ReplayTime now) {
  Exchange& exchange = exchanges_[index];
  if (config_.check == ReplayCheck::timing) {
    const ReplayTime due =
        config_.timing == ReplayTiming::session || !last_match_time_
            ? open_time_ + scaled(exchange.last_tx_t_ns)
            : *last_match_time_ +
                  scaled(exchange.last_tx_t_ns > last_match_t_ns_
                             ? exchange.last_tx_t_ns - last_match_t_ns_
                             : 0);
    check_tx_timing(due, now);
  }
  exchange.used = true;
  ++exchanges_served_;
  last_match_time_ = now;
  last_match_t_ns_ = exchange.last_tx_t_ns;
  for (const RxItem& response : exchange.responses) {
    RxItem item = response;
    switch (config_.timing) {
      case ReplayTiming::none:
      case ReplayTiming::session:
        item.due = due_by_session_clock(item.t_ns);
        break;
      case ReplayTiming::causal:
        item.due = now + scaled(item.t_ns > exchange.last_tx_t_ns
                                    ? item.t_ns - exchange.last_tx_t_ns
                                    : 0);
        break;
    }
    rx_queue_bytes_ += item.data.size();
    rx_queue_.push_back(std::move(item));
  }
}

bool ReplayEngine::match_pending(ReplayTime now) {
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
  serve(*chosen, now);
  keep_tail(tx_history_, std::string_view(pending_).substr(0, length));
  pending_.erase(0, length);
  pending_offset_ += length;
  return true;
}

void ReplayEngine::raise_unmatched(ReplayTime) {
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
            << seconds(exchange.first_tx_t_ns) << " s): "
            << hex_ascii(std::string_view(exchange.request).substr(0, kContext))
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
  raise_mismatch("the client wrote a request that matches no unused exchange",
                 offset, expected.substr(same, kContext),
                 std::string_view(actual).substr(same, kContext), t_ns,
                 exchange_number, extra.str());
}

void ReplayEngine::write_request(const char* data, std::size_t size,
                                 ReplayTime now) {
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
    raise_unmatched(now);
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
    if (!silent) raise_unmatched(now);
    pending_.erase(0, 1);  // a device that ignores the byte
    ++pending_offset_;
  }
}

// --- both ----------------------------------------------------------------------

void ReplayEngine::write(const char* data, std::size_t size, ReplayTime now) {
  if (size == 0) return;
  if (config_.match == ReplayMatch::sequence) {
    try {
      write_sequence(data, size, now);
    } catch (...) {
      entitle();
      throw;
    }
    entitle();
  } else {
    write_request(data, size, now);
  }
}

void ReplayEngine::raise_mismatch(const std::string& title,
                                  std::uint64_t offset,
                                  std::string_view expected,
                                  std::string_view actual,
                                  std::uint64_t session_t_ns,
                                  std::int64_t exchange,
                                  const std::string& extra) {
  std::ostringstream report;
  report << "replay mismatch in " << config_.file << ": " << title << "\n"
         << "  at tx byte offset " << offset << ", session time "
         << seconds(session_t_ns) << " s, exchange ";
  if (exchange >= 0) {
    report << exchange;
  } else {
    report << "-";
  }
  report << "\n";
  report << "  before:   " << hex_ascii(tx_history_) << "\n"
         << "  expected: "
         << (expected.empty() && config_.match == ReplayMatch::sequence
                 ? std::string("(nothing: the recorded writes end here)")
                 : hex_ascii(expected))
         << "\n"
         << "  actual:   " << hex_ascii(actual) << "\n"
         << extra;
  throw ReplayMismatch(report.str(), offset, session_t_ns, exchange);
}

std::string ReplayEngine::unused_report() {
  std::uint64_t rx_bytes = 0;
  std::uint64_t rx_records = 0;
  for (const RxItem& item : rx_queue_) {
    if (item.kind != RecordKind::rx) continue;
    rx_bytes += item.payload().size() - item.consumed;
    ++rx_records;
  }
  std::ostringstream report;
  if (config_.match == ReplayMatch::sequence) {
    Record record;
    while (!rx_exhausted_ && rx_source_->next(record)) {
      if (record.kind == RecordKind::rx && !record.data.empty()) {
        rx_bytes += record.data.size();
        ++rx_records;
      }
      if (record.kind == RecordKind::close ||
          record.kind == RecordKind::device_lost) {
        break;
      }
    }
    rx_exhausted_ = true;
    std::uint64_t tx_bytes =
        have_tx_record_ ? tx_record_.data.size() - tx_position_ : 0;
    while (!tx_exhausted_ && tx_source_->next(record)) {
      if (record.kind == RecordKind::tx) tx_bytes += record.data.size();
      if (record.kind == RecordKind::close ||
          record.kind == RecordKind::device_lost) {
        break;
      }
    }
    tx_exhausted_ = true;
    have_tx_record_ = false;
    if (rx_bytes > 0) {
      report << rx_bytes << " recorded rx bytes (" << rx_records
             << " records) were never read";
    }
    if (tx_bytes > 0) {
      if (rx_bytes > 0) report << "; ";
      report << tx_bytes << " recorded tx bytes were never written";
    }
  } else {
    std::size_t unused = 0;
    std::ostringstream first;
    for (std::size_t i = 0; i < exchanges_.size(); ++i) {
      if (exchanges_[i].used) continue;
      if (unused < 3) {
        first << "\n  exchange " << i << ": "
              << hex_ascii(std::string_view(exchanges_[i].request).substr(0, kContext));
      }
      ++unused;
    }
    if (rx_bytes > 0) {
      report << rx_bytes << " released rx bytes were never read";
    }
    if (unused > 0) {
      if (rx_bytes > 0) report << "; ";
      report << unused << " of " << exchanges_.size()
             << " recorded exchanges were never requested" << first.str();
    }
  }
  const std::string text = report.str();
  if (text.empty()) return text;
  return "replay of " + config_.file + ": " + text;
}

}  // namespace wiretape::detail
