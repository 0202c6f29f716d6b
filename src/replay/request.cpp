#include "replay/request.hpp"

#include <algorithm>
#include <sstream>

#include "replay/client_session.hpp"
#include "replay/exchanges.hpp"
#include "replay/profile.hpp"
#include "util/hex.hpp"
#include "wiretape/errors.hpp"

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
    : config_(config),
      timeline_(timeline),
      released_(released),
      report_(report),
      sources_(sources) {
  const std::unique_ptr<RecordSource> source = sources_();
  if (config_.profile) {
    client_framer_ = config_.profile->make_framer(StreamDirection::tx);
    if (config_.profile->fixes_responses()) {
      fixer_ = std::make_unique<ResponseFixer>(config_.profile);
    }
    load_frames(*source);
  } else {
    load_exchanges(*source);
  }
  index_requests();
}

std::uint32_t RequestStrategy::find_group(std::string_view request,
                                          std::size_t hash) const {
  if (slots_.empty()) return kNone;
  const std::size_t mask = slots_.size() - 1;
  for (std::size_t slot = hash & mask;; slot = (slot + 1) & mask) {
    const std::uint32_t entry = slots_[slot];
    if (entry == 0) return kNone;
    const Group& group = groups_[entry - 1];
    if (group.hash == hash && request_of(group) == request) return entry - 1;
  }
}

std::uint32_t RequestStrategy::group_for(std::string_view request) {
  const std::size_t hash = std::hash<std::string_view>()(request);
  const std::uint32_t found = find_group(request, hash);
  if (found != kNone) return found;
  if (slots_.empty()) slots_.assign(1024, 0);
  const std::size_t mask = slots_.size() - 1;
  Group group;
  group.offset = request_bytes_.size();
  group.size = static_cast<std::uint32_t>(request.size());
  group.hash = hash;
  request_bytes_.append(request);
  groups_.push_back(group);
  if (groups_.size() * 2 > slots_.size()) {
    grow_slots();
  } else {
    std::size_t slot = hash & mask;
    while (slots_[slot] != 0) slot = (slot + 1) & mask;
    slots_[slot] = static_cast<std::uint32_t>(groups_.size());
  }
  return static_cast<std::uint32_t>(groups_.size() - 1);
}

void RequestStrategy::grow_slots() {
  slots_.assign(slots_.size() * 2, 0);
  const std::size_t mask = slots_.size() - 1;
  for (std::size_t i = 0; i < groups_.size(); ++i) {
    std::size_t slot = groups_[i].hash & mask;
    while (slots_[slot] != 0) slot = (slot + 1) & mask;
    slots_[slot] = static_cast<std::uint32_t>(i + 1);
  }
}

void RequestStrategy::join_group(std::uint32_t index) {
  Group& group = groups_[index];
  const auto exchange = static_cast<std::uint32_t>(exchanges_.size() - 1);
  if (group.first == kNone) {
    group.first = group.next_unused = group.next_cycle = exchange;
  } else {
    exchanges_[group.last].next_in_group = exchange;
  }
  group.last = exchange;
  exchanges_.back().group = index;
}

std::vector<std::pair<std::size_t, std::size_t>> RequestStrategy::closest_exchanges(
    std::string_view request, std::size_t count) const {
  std::vector<std::pair<std::size_t, std::size_t>> ranked;  // (common prefix, exchange)
  for (std::size_t i = 0; i < exchanges_.size(); ++i) {
    if (exchanges_[i].used && config_.repeat == ReplayRepeat::none) continue;
    ranked.emplace_back(common_prefix(request, request_of_exchange(i)), i);
  }
  const std::size_t shown = std::min(ranked.size(), count);
  std::partial_sort(ranked.begin(), ranked.begin() + static_cast<std::ptrdiff_t>(shown),
                    ranked.end(), [](const auto& a, const auto& b) {
                      return a.first != b.first ? a.first > b.first : a.second < b.second;
                    });
  ranked.resize(shown);
  return ranked;
}

void RequestStrategy::load_exchanges(RecordSource& source) {
  Record record;
  PayloadView view;
  bool in_request = false;
  std::string request;  // of the exchange being gathered
  Wildcards request_wildcards;  // its scrubbed bytes
  Wildcards next_record_wildcards;  // redaction events before the next record
  const auto close_request = [&] {
    const std::uint32_t group = group_for(request);
    join_group(group);
    if (!request_wildcards.empty()) add_wildcards(group, request_wildcards);
    request.clear();
    request_wildcards.clear();
    in_request = false;
  };
  std::uint64_t tx_offset = 0;
  std::uint64_t records_read = 0;
  bool device_gone = false;
  // Where requests begin: the one segmentation (exchanges.hpp).
  ExchangeCursor cursor(Segmentation{nullptr, config_.datagrams, ReplayMatch::request});
  while (!device_gone && source.next(record, view)) {
    const std::uint64_t ordinal = records_read++;
    const std::string_view payload = view ? view.bytes : std::string_view(record.data);
    cursor.feed(record.kind, record.t_ns, payload);
    if (another_client_session(record.kind, payload)) {
      if (in_request) close_request();
      continue;
    }
    switch (record.kind) {
      case RecordKind::tx: {
        if (payload.empty()) break;
        greeting_of_another_ = false;
        if (cursor.began()) {
          if (in_request) close_request();
          exchanges_.emplace_back();
          exchanges_.back().first_tx_t_ns = record.t_ns;
          exchanges_.back().tx_offset = tx_offset;
          in_request = true;
        }
        request_wildcards.append_shifted(next_record_wildcards, request.size());
        next_record_wildcards.clear();
        request.append(payload);
        exchanges_.back().last_tx_t_ns = record.t_ns;
        tx_offset += payload.size();
        break;
      }
      case RecordKind::rx:
      case RecordKind::close:
      case RecordKind::device_lost: {
        if (record.kind == RecordKind::rx && payload.empty()) break;
        next_record_wildcards.clear();  // the redaction was of this rx record
        if (greeting_of_another_) break;
        device_gone = record.kind != RecordKind::rx;
        if (record.kind == RecordKind::close && !session_goes_on(source)) break;
        if (in_request) close_request();
        add_response(record.kind, record.t_ns, payload, ordinal);
        break;
      }
      case RecordKind::redaction:
        next_record_wildcards.add_event(payload);
        break;
      case RecordKind::modem_lines:
        if (!greeting_of_another_) serve_greeting_lines(payload);
        break;
      default:
        break;
    }
  }
  if (in_request) close_request();
}

// With sessions_first_sources (client_session.hpp): the recording's other
// client sessions follow this one's, each opened by its client_connect.
// Their exchanges are matched after this session's; their greetings were
// for their own clients and are not served.
bool RequestStrategy::another_client_session(RecordKind kind, std::string_view payload) {
  if (config_.client_session == 0) return false;
  if (kind != RecordKind::client_connect && kind != RecordKind::client_disconnect) return false;
  // The first session begun is this one's.
  if (sessions_.feed(kind, payload) != ClientSessionTracker::Change::began ||
      ++sessions_begun_ < 2) {
    return false;
  }
  if (own_exchanges_ == kAllExchanges) own_exchanges_ = exchanges_.size();
  greeting_of_another_ = true;
  return true;
}

void RequestStrategy::add_wildcards(std::uint32_t group, const Wildcards& wildcards) {
  auto found = std::find_if(wildcard_groups_.begin(), wildcard_groups_.end(),
                            [&](const auto& entry) { return entry.first == group; });
  if (found == wildcard_groups_.end()) {
    wildcard_groups_.emplace_back(group, Wildcards());
    found = wildcard_groups_.end() - 1;
  }
  found->second.append_shifted(wildcards, 0);
}

void RequestStrategy::add_response(RecordKind kind, std::uint64_t t_ns,
                                   std::string_view payload, std::uint64_t ordinal) {
  RxItem item;
  item.kind = kind;
  item.t_ns = t_ns;
  if (exchanges_.empty()) {
    // A greeting: released at open, the first exchange.
    greeting_ = true;
    item.exchange = config_.first_exchange;
    item.data.assign(payload);
    item.due = timeline_.due(item.t_ns, std::nullopt);
    released_.push(std::move(item));
    return;
  }
  Exchange& exchange = exchanges_.back();
  if (!exchange.has_response) {
    exchange.first_record = ordinal;
    exchange.kept_first = exchange.kept_end = static_cast<std::uint32_t>(kept_.size());
  }
  exchange.has_response = true;
  if (kind != RecordKind::rx) {
    end_ = std::move(item);
    end_exchange_ = exchanges_.size() - 1;
    return;
  }
  exchange.end_record = ordinal + 1;
  if (!exchange.in_session && kept_bytes_.size() + payload.size() > kKeptResponseBytes) {
    // From here on read from the session: its kept records are the last ones.
    exchange.in_session = true;
    if (exchange.kept_first < kept_.size()) {
      kept_bytes_.resize(kept_[exchange.kept_first].offset);
      kept_.resize(exchange.kept_first);
    }
    exchange.kept_end = exchange.kept_first;
  }
  if (!exchange.in_session) {
    kept_.push_back({kept_bytes_.size(), static_cast<std::uint32_t>(payload.size()), t_ns});
    kept_bytes_.append(payload);
    exchange.kept_end = static_cast<std::uint32_t>(kept_.size());
  }
}

void RequestStrategy::load_frames(RecordSource& source) {
  const Profile& profile = *config_.profile;
  Record record;
  PayloadView view;
  std::uint64_t tx_offset = 0;  // of the frame being gathered
  std::uint64_t records_read = 0;
  // first_t_ns: of the record holding the frame's first byte; last_t_ns: of
  // the one completing it.
  const auto add_frame = [&](const Frame& frame, std::uint64_t first_t_ns,
                             std::uint64_t last_t_ns) {
    if (frame.end == FrameEnd::broken || frame.end == FrameEnd::size_limit) {
      throw OptionError(
          "profile", "profile '" + std::string(profile.name()) + "' cannot frame " +
                         config_.file + ": the request frame at tx byte offset " +
                         std::to_string(tx_offset) + " (session time " +
                         session_seconds(last_t_ns) + " s) is broken" +
                         (frame.problem.empty() ? std::string() : ": " + frame.problem) +
                         "; is this the protocol's recording?");
    }
    exchanges_.emplace_back();
    Exchange& exchange = exchanges_.back();
    exchange.first_tx_t_ns = first_t_ns;
    exchange.last_tx_t_ns = last_t_ns;
    exchange.tx_offset = tx_offset;
    exchange.raw_offset = raw_requests_.size();
    exchange.raw_size = static_cast<std::uint32_t>(frame.bytes.size());
    raw_requests_.append(frame.bytes);
    tx_offset += frame.bytes.size();
    join_group(group_for(profile.match_key(frame.bytes)));
  };
  // Request frames: the one segmentation (exchanges.hpp) frames them.
  ExchangeCursor cursor(Segmentation{config_.profile, config_.datagrams, ReplayMatch::request});
  std::uint64_t last_tx_t_ns = 0;
  bool device_gone = false;
  while (!device_gone && source.next(record, view)) {
    const std::uint64_t ordinal = records_read++;
    const std::string_view payload = view ? view.bytes : std::string_view(record.data);
    cursor.feed(record.kind, record.t_ns, payload);
    // A frame a tx record completes ends there; one the device's speaking
    // ended (framed by silence), at the last tx.
    if (record.kind == RecordKind::tx && !payload.empty()) last_tx_t_ns = record.t_ns;
    for (const TimedFramer::TimedFrame& timed : cursor.frames_completed()) {
      add_frame(timed.frame, timed.t_ns, last_tx_t_ns);
      greeting_of_another_ = false;
    }
    if (another_client_session(record.kind, payload) || greeting_of_another_) continue;
    if (record.kind == RecordKind::modem_lines) serve_greeting_lines(payload);
    if (record.kind != RecordKind::rx && record.kind != RecordKind::close &&
        record.kind != RecordKind::device_lost) {
      continue;
    }
    if (record.kind == RecordKind::rx && payload.empty()) continue;
    device_gone = record.kind != RecordKind::rx;
    if (record.kind == RecordKind::close && !session_goes_on(source)) break;
    add_response(record.kind, record.t_ns, payload, ordinal);
  }
}

// Served, not checked (docs/replay.md): the device's lines as the recording
// shows them before the first request, from open on.
void RequestStrategy::serve_greeting_lines(std::string_view payload) {
  if (!exchanges_.empty()) return;
  if (const auto inputs = modem_inputs_of(payload, greeting_lines_)) {
    greeting_lines_ = *inputs;
    released_.push_lines(ReplayTime::min(), *inputs);
  }
}

void RequestStrategy::index_requests() {
  groups_by_request_.resize(groups_.size());
  for (std::size_t i = 0; i < groups_.size(); ++i) {
    groups_by_request_[i] = static_cast<std::uint32_t>(i);
    request_lengths_.push_back(groups_[i].size);
  }
  std::sort(request_lengths_.begin(), request_lengths_.end());
  request_lengths_.erase(std::unique(request_lengths_.begin(), request_lengths_.end()),
                         request_lengths_.end());
  std::sort(groups_by_request_.begin(), groups_by_request_.end(),
            [&](std::uint32_t a, std::uint32_t b) {
              return request_of(groups_[a]) < request_of(groups_[b]);
            });
  // Every request that begins with another comes right after it in this
  // order (or after requests that begin with it too).
  for (std::size_t i = 0; i + 1 < groups_by_request_.size(); ++i) {
    Group& group = groups_[groups_by_request_[i]];
    group.extended = starts_with(request_of(groups_[groups_by_request_[i + 1]]),
                                 request_of(group));
  }
  for (const Exchange& exchange : exchanges_) {
    if (exchange.has_response) ++with_response_;
  }
  unused_with_response_ = with_response_;
}

bool RequestStrategy::more_to_release() const {
  if (waiting_for_longer_) return true;
  return config_.repeat != ReplayRepeat::none ? with_response_ > 0
                                              : unused_with_response_ > 0;
}

std::optional<ReplayTime> RequestStrategy::wake() const {
  if (!waiting_for_longer_) return std::nullopt;
  if (config_.profile) {
    return last_write_ + std::chrono::duration_cast<ReplayClock::duration>(
                             client_framer_->quiet_gap().value_or(std::chrono::nanoseconds(0)));
  }
  return last_write_ + config_.gap;
}

void RequestStrategy::release(ReplayTime now) {
  if (!waiting_for_longer_ || now < *wake()) return;
  if (config_.profile) {
    // A frame cut by the client's silence.
    waiting_for_longer_ = false;
    client_frames_.clear();
    if (std::optional<Frame> tail = client_framer_->finish()) {
      client_frames_.push_back(std::move(*tail));
    }
    take_frames(/*may_raise=*/false);
    return;
  }
  match_pending(/*quiet=*/true, /*may_raise=*/false);
}

std::optional<RequestStrategy::Rank> RequestStrategy::rank(const Group& group) const {
  if (group.next_unused != kNone) return Rank{0, group.next_unused};
  if (config_.repeat != ReplayRepeat::none) return Rank{1, group.first};
  return std::nullopt;
}

std::optional<std::pair<std::uint32_t, RequestStrategy::Rank>>
RequestStrategy::best_match() const {
  std::optional<std::pair<std::uint32_t, Rank>> best;
  const auto consider = [&](std::string_view request) {
    const std::uint32_t index =
        find_group(request, std::hash<std::string_view>()(request));
    if (index == kNone) return;
    const std::optional<Rank> ranked = rank(groups_[index]);
    if (ranked && (!best || *ranked < best->second)) best.emplace(index, *ranked);
  };
  // Scrubbed requests match with their scrubbed bytes as wildcards; they are
  // few (what edit --redact marked), so they are tried one by one.
  const auto consider_scrubbed = [&] {
    for (const auto& [index, wildcards] : wildcard_groups_) {
      const std::string_view recorded = request_of(groups_[index]);
      if (config_.datagrams ? pending_.size() != recorded.size()
                            : pending_.size() < recorded.size()) {
        continue;
      }
      if (common_prefix(recorded, pending_, wildcards, 0) < recorded.size()) continue;
      const std::optional<Rank> ranked = rank(groups_[index]);
      if (ranked && (!best || *ranked < best->second)) best.emplace(index, *ranked);
    }
  };
  if (config_.datagrams) {
    consider(pending_);
    consider_scrubbed();
    return best;
  }
  for (const std::size_t length : request_lengths_) {
    if (length > pending_.size()) break;
    consider(std::string_view(pending_).substr(0, length));
  }
  consider_scrubbed();
  return best;
}

bool RequestStrategy::longer_request_pending(std::optional<Rank> before) const {
  auto it = std::lower_bound(groups_by_request_.begin(), groups_by_request_.end(),
                             pending_, [&](std::uint32_t group, const std::string& bytes) {
                               return request_of(groups_[group]) < bytes;
                             });
  for (; it != groups_by_request_.end(); ++it) {
    const Group& group = groups_[*it];
    if (!starts_with(request_of(group), pending_)) break;
    if (group.size == pending_.size()) continue;
    const std::optional<Rank> ranked = rank(group);
    if (ranked && (!before || *ranked < *before)) return true;
  }
  return false;
}

void RequestStrategy::push_response(const RxItem& response,
                                    const ReplayTimeline::Anchor& matched) {
  RxItem item = response;
  item.due = timeline_.due(item.t_ns, matched);
  push_served(std::move(item));
}

void RequestStrategy::read_from_session(const Exchange& exchange,
                                        const ReplayTimeline::Anchor& matched) {
  if (!response_source_) response_source_ = sources_();
  if (exchange.first_record < response_position_) {
    response_source_->rewind();
    response_position_ = 0;
  }
  Record record;
  PayloadView view;
  while (response_position_ < exchange.end_record &&
         response_source_->next(record, view)) {
    if (response_position_++ < exchange.first_record) continue;
    if (record.kind != RecordKind::rx) continue;
    RxItem item;
    item.t_ns = record.t_ns;
    if (view) {
      item.view = std::move(view);
    } else {
      item.data = std::move(record.data);
    }
    if (item.payload().empty()) continue;
    item.due = timeline_.due(item.t_ns, matched);
    push_served(std::move(item));
  }
}

void RequestStrategy::push_served(RxItem&& item) {
  item.exchange = serving_exchange_;
  if (!fixer_) {
    released_.push(std::move(item));
    return;
  }
  fixer_->push(std::move(item), matches_);
  while (fixer_->ready()) released_.push(fixer_->take());
}

void RequestStrategy::serve(std::uint32_t group_index, std::string_view request,
                            std::string_view actual_frame) {
  Group& group = groups_[group_index];
  std::uint32_t index = 0;
  if (group.next_unused != kNone) {
    index = group.next_unused;
    group.next_unused = exchanges_[index].next_in_group;
  } else if (config_.repeat == ReplayRepeat::last) {
    index = group.last;
  } else {
    index = group.next_cycle;
    group.next_cycle = exchanges_[index].next_in_group != kNone
                           ? exchanges_[index].next_in_group
                           : group.first;
  }
  Exchange& exchange = exchanges_[index];
  const ReplayTime now = last_write_;  // the client finished the request then
  if (config_.check == ReplayCheck::timing) {
    if (const auto miss = timeline_.check_write(exchange.last_tx_t_ns, last_match_time_,
                                                last_match_t_ns_, now)) {
      report_.raise(miss->title, tx_written_, request_of(group).substr(0, kReplayContext),
                    request.substr(0, kReplayContext), last_match_t_ns_,
                    static_cast<std::int64_t>(exchanges_served_), miss->detail);
    }
  }
  if (!exchange.used && exchange.has_response) --unused_with_response_;
  exchange.used = true;
  serving_exchange_ = config_.first_exchange + exchanges_served_++ + (greeting_ ? 1 : 0);
  last_match_time_ = now;
  last_match_t_ns_ = exchange.last_tx_t_ns;
  // Causal timing counts each response from this match.
  const ReplayTimeline::Anchor matched{now, exchange.last_tx_t_ns};
  if (fixer_) fixer_->request(++matches_, raw_request(exchange), actual_frame);
  if (exchange.in_session) {
    read_from_session(exchange, matched);
  } else {
    for (std::uint32_t k = exchange.kept_first; k < exchange.kept_end; ++k) {
      const KeptRx& kept = kept_[k];
      RxItem item;
      item.t_ns = kept.t_ns;
      item.data = released_.spare_payload();
      item.data.assign(kept_bytes_, kept.offset, kept.size);
      item.due = timeline_.due(item.t_ns, matched);
      push_served(std::move(item));
    }
  }
  if (end_ && end_exchange_ == index) push_response(*end_, matched);
  if (fixer_) {
    // The whole response is known: its incomplete frame is served now.
    fixer_->end_response();
    while (fixer_->ready()) released_.push(fixer_->take());
  }
}

void RequestStrategy::match_pending(bool quiet, bool may_raise) {
  waiting_for_longer_ = false;
  // check=off replays as a device that ignores what it does not understand.
  const bool silent = config_.unmatched == ReplayUnmatched::silent ||
                      config_.check == ReplayCheck::off;
  while (!pending_.empty()) {
    if (const auto match = best_match()) {
      // A longer request recorded earlier may be on its way in another
      // write: wait for it, up to gap of quiet (DESIGN.md section 13).
      if (!quiet && !config_.datagrams && groups_[match->first].extended &&
          longer_request_pending(match->second)) {
        waiting_for_longer_ = true;
        return;
      }
      const std::size_t length = groups_[match->first].size;
      const std::string_view matched = std::string_view(pending_).substr(0, length);
      serve(match->first, matched);
      report_.accepted(matched);
      pending_.erase(0, length);
      pending_offset_ += length;
      continue;
    }
    if (!config_.datagrams && longer_request_pending(std::nullopt)) return;
    if (!silent) {
      if (!may_raise) return;
      raise_unmatched();
    }
    // A device that ignores the byte (a datagram: the whole datagram).
    const std::size_t dropped = config_.datagrams ? pending_.size() : 1;
    pending_.erase(0, dropped);
    pending_offset_ += dropped;
  }
}

void RequestStrategy::raise_past_the_end(std::uint64_t offset, std::string_view actual) const {
  // Every recorded exchange was served (repeat=none): numbered as served.
  const std::uint64_t first = config_.first_exchange + (greeting_ ? 1 : 0);
  report_.raise_past_the_end(offset, actual.substr(0, kReplayContext), last_match_t_ns_, first,
                             static_cast<std::int64_t>(first + exchanges_.size()) - 1);
}

void RequestStrategy::raise_unmatched() {
  // The closest unused requests: longest common prefix first, then order.
  const auto ranked = closest_exchanges(pending_, 3);
  if (ranked.empty()) {
    const std::string actual = pending_;
    const std::uint64_t offset = pending_offset_;
    // The unmatched bytes are dropped, so that the client can go on.
    pending_offset_ += pending_.size();
    pending_.clear();
    raise_past_the_end(offset, actual);
  }
  std::ostringstream extra;
  extra << "  closest unused requests:\n";
  for (const auto& [same, index] : ranked) {
    extra << "    exchange " << index << " (session time "
          << session_seconds(exchanges_[index].first_tx_t_ns) << " s): "
          << hex_ascii(request_of_exchange(index).substr(0, kReplayContext)) << "\n";
  }
  const std::size_t same = ranked.front().first;
  const std::string_view expected = request_of_exchange(ranked.front().second);
  const std::string actual = pending_;
  const std::uint64_t offset = pending_offset_ + same;
  const std::uint64_t t_ns = exchanges_[ranked.front().second].first_tx_t_ns;
  const auto reported_exchange = static_cast<std::int64_t>(ranked.front().second);
  // The unmatched bytes are dropped, so that the client can go on.
  pending_offset_ += pending_.size();
  pending_.clear();
  report_.raise("the client wrote a request that matches no unused exchange",
                offset, expected.substr(same, kReplayContext),
                std::string_view(actual).substr(same, kReplayContext), t_ns,
                reported_exchange, extra.str());
}

void RequestStrategy::write_frames(const char* data, std::size_t size) {
  client_frames_.clear();
  client_framer_->feed_at(static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                              last_write_.time_since_epoch())
                              .count()),
                          std::string_view(data, size), client_frames_);
  take_frames(/*may_raise=*/true);
  // Framed by silence: the frame ends when the client is quiet (release()).
  waiting_for_longer_ = client_framer_->quiet_gap() && client_framer_->pending() > 0;
}

void RequestStrategy::take_frames(bool may_raise) {
  const Profile& profile = *config_.profile;
  const bool silent = config_.unmatched == ReplayUnmatched::silent ||
                      config_.check == ReplayCheck::off;
  for (std::size_t i = 0; i < client_frames_.size(); ++i) {
    const Frame& frame = client_frames_[i];
    const std::string key = profile.match_key(frame.bytes);
    const std::uint32_t index = frame.end == FrameEnd::delimited
                                    ? find_group(key, std::hash<std::string_view>()(key))
                                    : kNone;
    if (index != kNone && rank(groups_[index])) {
      serve(index, frame.bytes, frame.bytes);
      report_.accepted(frame.bytes);
      pending_offset_ += frame.bytes.size();
      continue;
    }
    if (silent) {
      pending_offset_ += frame.bytes.size();
      continue;
    }
    if (!may_raise) {
      // Found when no write is under way: the client's next write raises.
      deferred_unmatched_ = frame;
      continue;
    }
    // The frames after this one in the write are dropped with it.
    const Frame unmatched = frame;
    for (std::size_t k = i + 1; k < client_frames_.size(); ++k) {
      pending_offset_ += client_frames_[k].bytes.size();
    }
    raise_unmatched_frame(unmatched, key);
  }
}

void RequestStrategy::raise_unmatched_frame(const Frame& frame, const std::string& key) {
  const Profile& profile = *config_.profile;
  // The closest recorded frames: longest common key prefix first, then order.
  const auto ranked = closest_exchanges(key, 3);
  if (ranked.empty() && frame.end == FrameEnd::delimited) {
    const std::uint64_t offset = pending_offset_;
    pending_offset_ += frame.bytes.size();
    raise_past_the_end(offset, frame.bytes);
  }
  const std::string name = profile.frame_name(StreamDirection::tx, frame.bytes);
  std::ostringstream title;
  std::ostringstream extra;
  std::string_view expected;
  std::size_t same = 0;
  if (frame.end != FrameEnd::delimited) {
    title << "the client's bytes are not a whole " << profile.name() << " frame";
    if (!frame.problem.empty()) title << " (" << frame.problem << ")";
  } else {
    title << "the client's frame " << name << " matches no unused exchange";
  }
  if (!ranked.empty()) {
    const Exchange& closest = exchanges_[ranked.front().second];
    expected = raw_request(closest);
    same = common_prefix(expected, frame.bytes);
    if (frame.end == FrameEnd::delimited) {
      title << differing_field_text(profile, expected, frame.bytes);
      same = first_key_difference(profile, expected, frame.bytes).value_or(same);
    }
    extra << "  closest recorded frames:\n";
    for (const auto& ranked_exchange : ranked) {
      const Exchange& exchange = exchanges_[ranked_exchange.second];
      extra << "    exchange " << ranked_exchange.second << " (session time "
            << session_seconds(exchange.first_tx_t_ns) << " s): "
            << profile.frame_name(StreamDirection::tx, raw_request(exchange)) << "  "
            << hex_ascii(raw_request(exchange).substr(0, kReplayContext * 2)) << "\n";
    }
  } else {
    // Not a whole frame, and no request left: what is wrong with it is the news.
    extra << "  no unused request is left in the recording\n";
  }
  const std::uint64_t offset = pending_offset_ + same;
  pending_offset_ += frame.bytes.size();
  const std::uint64_t t_ns =
      ranked.empty() ? last_match_t_ns_ : exchanges_[ranked.front().second].first_tx_t_ns;
  const std::int64_t reported_exchange =
      ranked.empty() ? -1 : static_cast<std::int64_t>(ranked.front().second);
  const std::string_view actual(frame.bytes);
  report_.raise(title.str(), offset,
                expected.substr(std::min(same, expected.size()), kReplayContext),
                actual.substr(std::min(same, actual.size()), kReplayContext), t_ns,
                reported_exchange, extra.str());
}

void RequestStrategy::write(const char* data, std::size_t size, ReplayTime now) {
  if (config_.profile) {
    // Frames decide: no wait for a longer request.
    release(now);
    if (deferred_unmatched_) {
      const Frame unmatched = std::move(*deferred_unmatched_);
      deferred_unmatched_.reset();
      raise_unmatched_frame(unmatched, config_.profile->match_key(unmatched.bytes));
    }
    tx_written_ += size;
    last_write_ = now;
    write_frames(data, size);
    return;
  }
  release(now);  // a wait that ended before this write ended without it
  if (config_.datagrams) {
    // A datagram is one request; what was left of the last one is gone.
    pending_offset_ = tx_written_;
    pending_.assign(data, size);
  } else {
    pending_.append(data, size);
  }
  tx_written_ += size;
  last_write_ = now;
  match_pending(/*quiet=*/config_.gap.count() <= 0, /*may_raise=*/true);
}

std::string RequestStrategy::unused_report(std::uint64_t queued_rx_bytes,
                                           std::uint64_t) {
  std::size_t unused = 0;
  std::ostringstream first;
  // Other client sessions' exchanges are for other connections: this one
  // answers for its own (DESIGN.md section 12).
  const std::size_t own = std::min(own_exchanges_, exchanges_.size());
  for (std::size_t i = 0; i < own; ++i) {
    if (exchanges_[i].used) continue;
    if (unused < 3) {
      first << "\n  exchange " << i << ": "
            << hex_ascii(request_of_exchange(i).substr(0, kReplayContext));
    }
    ++unused;
  }
  std::ostringstream report;
  if (queued_rx_bytes > 0) {
    report << queued_rx_bytes << " released rx bytes were never read";
  }
  if (unused > 0) {
    if (queued_rx_bytes > 0) report << "; ";
    report << unused << " of " << own << " recorded exchanges"
           << (own < exchanges_.size() ? " of this client session" : "")
           << " were never requested" << first.str();
  }
  return report.str();
}

}  // namespace wiretape::detail
