#include "replay/sequence.hpp"

#include <algorithm>

#include "replay/channel_hub.hpp"
#include "replay/recorded_events.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

SequenceStrategy::SequenceStrategy(const ReplayConfig& config,
                                   const ReplayTimeline& timeline,
                                   ReleasedRx& released, MismatchReport& report,
                                   const RecordSourceFactory& sources)
    : config_(config),
      empty_datagrams_(replays_empty_datagrams(config)),
      timeline_(timeline),
      released_(released),
      report_(report),
      rx_source_(sources()),
      rx_exchanges_(Segmentation{config.profile, config.datagrams, ReplayMatch::sequence,
                                 config.first_exchange}),
      tx_source_(sources()),
      tx_exchanges_(Segmentation{config.profile, config.datagrams, ReplayMatch::sequence,
                                 config.first_exchange}),
      frame_source_(config.profile ? sources() : nullptr) {
  if (config.profile && config.profile->fixes_responses()) {
    fixer_ = std::make_unique<ResponseFixer>(config.profile);
  }
  fill();
  entitle();
}

// --- the read cursor -----------------------------------------------------------

void SequenceStrategy::release(ReplayTime now) {
  now_ = std::max(now_, now);
  const bool nothing_ahead = released_.empty() && ahead_.empty();
  if (nothing_ahead || released_.bytes() + ahead_bytes_ < kLookaheadBytes / 2) {
    fill();
  }
  entitle();
}

void SequenceStrategy::client_flushed() {
  ++client_flushes_;
  entitle();
}

bool SequenceStrategy::more_to_release() const {
  return !ahead_.empty() || !rx_exhausted_ || (fixer_ && fixer_->holding());
}

void SequenceStrategy::fill() {
  const auto room = [this] {
    return !rx_exhausted_ && released_.size() + ahead_.size() < kLookaheadRecords &&
           released_.bytes() + ahead_bytes_ < kLookaheadBytes;
  };
  // Called at every read: once a short recording is all read ahead, that
  // costs no buffer taken and given back.
  if (!room()) return;
  Record record;
  PayloadView view;
  record.data = released_.spare_payload();
  while (room()) {
    if (!rx_source_->next(record, view)) {
      rx_exhausted_ = true;
      break;
    }
    const std::size_t size = view ? view.bytes.size() : record.data.size();
    const std::uint64_t exchange =
        rx_exchanges_.feed(record.kind, record.t_ns,
                           view ? view.bytes : std::string_view(record.data));
    switch (record.kind) {
      case RecordKind::tx:
        if (empty_datagrams_) ++rx_tx_datagrams_seen_;
        if (size == 0) break;
        rx_tx_seen_ += size;
        rx_last_tx_t_ns_ = record.t_ns;
        break;
      case RecordKind::flush_input:
      case RecordKind::flush_output:
        ++rx_flushes_seen_;
        break;
      case RecordKind::line_break:
        rx_line_records_seen_ = true;
        break;
      case RecordKind::modem_lines: {
        rx_line_records_seen_ = true;
        // The device's lines are released like rx; the host's are checked
        // by the write cursor.
        const std::string_view payload = view ? view.bytes : std::string_view(record.data);
        const std::optional<ModemInputs> inputs = modem_inputs_of(payload, rx_device_lines_);
        if (!inputs) break;
        rx_device_lines_ = *inputs;
        Ahead ahead;
        ahead.item.kind = RecordKind::modem_lines;
        ahead.item.t_ns = record.t_ns;
        ahead.item.exchange = exchange;
        ahead.item.data = modem_inputs_payload(*inputs);  // all four: read back alone
        ahead.tx_before = rx_tx_progress();
        ahead.anchor_t_ns = rx_last_tx_t_ns_;
        ahead.flushes_before = rx_flushes_seen_;
        ahead_bytes_ += ahead.item.data.size();
        ahead_.push_back(std::move(ahead));
        break;
      }
      case RecordKind::rx:
      case RecordKind::close:
      case RecordKind::device_lost: {
        if (record.kind == RecordKind::rx && size == 0 && !empty_datagrams_) break;
        if (record.kind == RecordKind::close && !session_goes_on(*rx_source_)) {
          rx_exhausted_ = true;
          break;
        }
        Ahead ahead;
        ahead.item.kind = record.kind;
        ahead.item.t_ns = record.t_ns;
        ahead.item.exchange = exchange;
        ahead.tx_before = rx_tx_progress();
        ahead.anchor_t_ns = rx_last_tx_t_ns_;
        ahead.flushes_before = rx_flushes_seen_;
        ahead_bytes_ += size;
        if (view) {
          ahead.item.view = std::move(view);
        } else {
          ahead.item.data = std::move(record.data);
          record.data = released_.spare_payload();
        }
        ahead_.push_back(std::move(ahead));
        // The device is gone: nothing after this point is served.
        if (record.kind != RecordKind::rx) rx_exhausted_ = true;
        break;
      }
      default:
        break;  // events are not replayed to the client
    }
  }
  released_.recycle_payload(std::move(record.data));
}

std::optional<ReplayTime> SequenceStrategy::finish_of(std::uint64_t tx_offset) const {
  for (const TxEnd& end : tx_ends_) {
    if (end.end_offset >= tx_offset) return end.finished;
  }
  return previous_tx_finished_;
}

void SequenceStrategy::entitle() {
  while (true) {
    // A response frame the fixer holds may go on in the next record.
    if (ahead_.empty() && fixer_ && fixer_->holding() && !rx_exhausted_) fill();
    if (ahead_.empty()) break;
    Ahead& ahead = ahead_.front();
    // timing=session: time alone decides, writes do not gate.
    // A client flush recorded before it (pyserial's, gpsd's on open) would
    // have discarded it had it come earlier: it waits for the client's, for
    // flush_wait at most.
    const bool entitled = config_.timing == ReplayTiming::session ||
                          (tx_progress() >= ahead.tx_before && !held_by_flush_gate());
    if (!entitled) break;  // later records need at least as many tx bytes
    ahead.item.due = due_of(ahead);
    // Across channels (DESIGN.md section 19): the client's tx recorded
    // before it on the other channels come first, and the latest of them
    // anchors it as the write before it on this channel does.
    if (config_.member && config_.timing == ReplayTiming::causal) {
      const ChannelMember::Gate gate = config_.member->gate(ahead.item.t_ns);
      if (!gate.open) break;  // another channel's write wakes this replay
      if (gate.anchor) {
        // With no write before it on its own channel, the other channel's
        // is its anchor (not the open); else the later of the two.
        const ReplayTime across = timeline_.due(ahead.item.t_ns, gate.anchor);
        const bool anchored_here = ahead.anchor_t_ns && finish_of(ahead.tx_before);
        ahead.item.due = anchored_here ? std::max(ahead.item.due, across) : across;
      }
    }
    ahead_bytes_ -= ahead.item.payload().size();
    release_item(std::move(ahead.item), ahead.tx_before);
    ahead_.pop_front();
  }
  // The response ends where the client must act before more is released
  // (or the recording ends): nothing is held back across that.
  if (fixer_ && fixer_->holding() && (!ahead_.empty() || rx_exhausted_)) {
    fixer_->end_response();
    release_fixed();
  }
  // Finish times the read cursor will never ask for again.
  const std::uint64_t still_needed =
      ahead_.empty() ? rx_tx_progress() : ahead_.front().tx_before;
  while (tx_ends_.size() > 1 && tx_ends_.front().end_offset < still_needed) {
    tx_ends_.pop_front();
  }
}

// When an entitled record is due: anchored on the client's write that the
// recording shows before it, once the client finished it.
ReplayTime SequenceStrategy::due_of(const Ahead& ahead) const {
  std::optional<ReplayTimeline::Anchor> anchor;
  if (ahead.anchor_t_ns) {
    if (const auto finished = finish_of(ahead.tx_before)) {
      anchor = ReplayTimeline::Anchor{*finished, *ahead.anchor_t_ns};
    }
  }
  return timeline_.due(ahead.item.t_ns, anchor);
}

// A recorded flush gates rx only as long as the client could still make it
// (DESIGN.md section 12): flushes made back to back may reach the bridge as
// one (TIOCPKT), and a probing client (gpsd) flushes a number of times that
// depends on timing. So the gate holds the record for flush_wait after it
// would otherwise be due, then counts the missing flushes as made.
bool SequenceStrategy::held_by_flush_gate() {
  const Ahead& ahead = ahead_.front();
  if (client_flushes_ + flushes_forgiven_ >= ahead.flushes_before) {
    flush_gate_ends_.reset();
    return false;
  }
  if (!flush_gate_ends_) {
    flush_gate_ends_ = std::max(due_of(ahead), now_) +
                       std::chrono::duration_cast<ReplayClock::duration>(config_.flush_wait);
  }
  if (now_ < *flush_gate_ends_) return true;
  flushes_forgiven_ = ahead.flushes_before - client_flushes_;
  flush_gate_ends_.reset();
  return false;
}

// The client wrote a byte recorded after the flushes before the current tx
// record: a flush of those it did not make can no longer come, so the rx
// they held is due at once (DESIGN.md section 12).
void SequenceStrategy::wrote_past_recorded_flushes() {
  if (client_flushes_ + flushes_forgiven_ < tx_record_flushes_before_) {
    flushes_forgiven_ = tx_record_flushes_before_ - client_flushes_;
  }
}

void SequenceStrategy::release_item(RxItem&& item, std::uint64_t tx_before) {
  if (item.kind == RecordKind::modem_lines) {
    released_.push_lines(item.due, modem_inputs_of(item.data, {}).value_or(ModemInputs{}));
    return;
  }
  if (!fixer_) {
    released_.push(std::move(item));
    return;
  }
  // Rx after another request of the client's is another response.
  if (fixer_->holding() && fixer_->held_after() != tx_before) fixer_->end_response();
  fixer_->push(std::move(item), tx_before);
  release_fixed();
}

void SequenceStrategy::release_fixed() {
  while (fixer_->ready()) released_.push(fixer_->take());
}

// --- the write cursor ------------------------------------------------------------

bool SequenceStrategy::next_tx_record() {
  Record record;
  while (!have_tx_record_ && !tx_exhausted_) {
    if (!tx_source_->next(record)) {
      tx_exhausted_ = true;
      break;
    }
    const std::uint64_t exchange = tx_exchanges_.feed(record);
    switch (record.kind) {
      case RecordKind::tx:
        if (record.data.empty() && !empty_datagrams_) break;
        tx_exchange_ = static_cast<std::int64_t>(exchange);
        tx_record_ = std::move(record);
        tx_position_ = 0;
        have_tx_record_ = true;
        tx_wildcards_.clear();
        std::swap(tx_wildcards_, pending_wildcards_);
        tx_record_flushes_before_ = tx_flushes_seen_;
        break;
      case RecordKind::rx:
        pending_wildcards_.clear();  // the redaction was of this rx record
        break;
      case RecordKind::flush_input:
      case RecordKind::flush_output:
        ++tx_flushes_seen_;
        break;
      case RecordKind::redaction:
        pending_wildcards_.add_event(record.data);
        break;
      case RecordKind::settings:
        if (checks_events()) expected_events_.push_back(std::move(record));
        break;
      case RecordKind::modem_lines:
        // The device's lines recorded: this recording's client lines are
        // checked from here on (the recorders write them first).
        if (modem_inputs_of(record.data, {})) lines_recorded_ = true;
        if (records_host_lines(record.data) && checks_lines()) {
          expected_events_.push_back(std::move(record));
        }
        break;
      case RecordKind::line_break:
        if (checks_lines()) expected_events_.push_back(std::move(record));
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

std::optional<SequenceStrategy::RecordedFrame> SequenceStrategy::next_recorded_frame() {
  Record record;
  const auto add = [&](TimedFramer::TimedFrame&& timed) {
    recorded_frames_.push_back({std::move(timed.frame), timed.t_ns,
                                static_cast<std::int64_t>(config_.first_exchange) +
                                    recorded_frames_seen_++});
  };
  while (recorded_frames_.empty() && !frame_source_done_) {
    if (!frame_source_->next(record)) {
      frame_source_done_ = true;
      if (std::optional<TimedFramer::TimedFrame> tail = recorded_framer_->finish()) {
        add(std::move(*tail));
      }
      break;
    }
    if (record.kind != RecordKind::tx || record.data.empty()) continue;
    scratch_frames_.clear();
    recorded_framer_->feed(record.t_ns, record.data, scratch_frames_);
    for (TimedFramer::TimedFrame& timed : scratch_frames_) add(std::move(timed));
  }
  if (recorded_frames_.empty()) return std::nullopt;
  RecordedFrame frame = std::move(recorded_frames_.front());
  recorded_frames_.pop_front();
  return frame;
}

void SequenceStrategy::write_frames(const char* data, std::size_t size, ReplayTime now) {
  const Profile& profile = *config_.profile;
  if (!client_framer_) {
    client_framer_ = profile.make_framer(StreamDirection::tx);
    recorded_framer_ = std::make_unique<TimedFramer>(profile.make_framer(StreamDirection::tx));
  }
  std::vector<Frame> frames;
  client_framer_->feed(std::string_view(data, size), frames);
  for (const Frame& frame : frames) {
    const std::optional<RecordedFrame> recorded_frame = next_recorded_frame();
    if (!recorded_frame) {
      write_records(frame.bytes.data(), frame.bytes.size(), now);  // raises: past the end
      continue;
    }
    const Frame* recorded = &recorded_frame->frame;
    if (recorded->end == FrameEnd::broken || recorded->end == FrameEnd::size_limit) {
      report_.raise("the recording's " + std::string(profile.name()) +
                        " frame at this point is broken" +
                        (recorded->problem.empty() ? std::string() : " (" + recorded->problem + ")") +
                        ": the profile cannot frame this recording",
                    tx_written_, std::string_view(recorded->bytes).substr(0, kReplayContext),
                    std::string_view(frame.bytes).substr(0, kReplayContext),
                    recorded_frame->t_ns, recorded_frame->exchange);
    }
    if (frame.end != FrameEnd::delimited ||
        profile.match_key(frame.bytes) != profile.match_key(recorded->bytes)) {
      std::string title = "the client's frame " +
                          profile.frame_name(StreamDirection::tx, frame.bytes) +
                          " differs from the recorded " +
                          profile.frame_name(StreamDirection::tx, recorded->bytes);
      if (frame.end != FrameEnd::delimited) {
        title = "the client's bytes are not a whole " + std::string(profile.name()) + " frame";
        if (!frame.problem.empty()) title += " (" + frame.problem + ")";
      } else {
        title += differing_field_text(profile, recorded->bytes, frame.bytes);
      }
      const std::size_t at =
          first_key_difference(profile, recorded->bytes, frame.bytes).value_or(0);
      report_.raise(title, tx_written_ + at,
                    std::string_view(recorded->bytes).substr(std::min(at, recorded->bytes.size()), kReplayContext),
                    std::string_view(frame.bytes).substr(std::min(at, frame.bytes.size()), kReplayContext),
                    recorded_frame->t_ns, recorded_frame->exchange);
    }
    // The recorded frame's bytes stand for the client's: its counters may
    // differ, and the recording's byte counts decide what is released.
    write_records(recorded->bytes.data(), recorded->bytes.size(), now);
    if (fixer_) fixer_->request(tx_written_, recorded->bytes, frame.bytes);
  }
}

void SequenceStrategy::write(const char* data, std::size_t size, ReplayTime now) {
  now_ = std::max(now_, now);
  try {
    if (config_.profile && config_.check != ReplayCheck::off) {
      write_frames(data, size, now);
    } else {
      write_records(data, size, now);
    }
  } catch (...) {
    entitle();  // what was accepted before the mismatch still counts
    throw;
  }
  entitle();
}

void SequenceStrategy::write_records(const char* data, std::size_t size,
                                     ReplayTime now) {
  const bool compare = config_.check != ReplayCheck::off;
  if (size == 0 && !empty_datagrams_) return;
  std::size_t done = 0;
  // Once at least: an empty datagram is a write of one record.
  do {
    const std::string_view rest(data + done, size - done);
    if (!next_tx_record()) {
      if (tx_hit_close_) {
        throw PortClosed("replay of " + config_.file +
                         ": the recorded device was closed at session time " +
                         session_seconds(tx_close_t_ns_) +
                         " s; it takes no more writes");
      }
      if (compare) {
        report_.raise_past_the_end(tx_written_, rest.substr(0, kReplayContext),
                                   previous_tx_t_ns_, config_.first_exchange, tx_exchange_,
                                   config_.first_exchange > 0 ? " of this client session" : "");
      }
      tx_written_ += rest.size();
      report_.accepted(rest);
      return;
    }
    const std::string& expected = tx_record_.data;
    if (tx_position_ == 0 && !expected_events_.empty()) {
      const Record& missing = expected_events_.front();
      report_.raise("the recording has " + recorded_event_text(missing) +
                        " before these bytes, and the client did not make it",
                    tx_written_,
                    std::string_view(expected).substr(0, kReplayContext),
                    rest.substr(0, kReplayContext), missing.t_ns, tx_exchange_,
                    event_mismatch_lines(missing, std::nullopt));
    }
    if (tx_position_ == 0 && config_.check == ReplayCheck::timing) {
      if (const auto miss = timeline_.check_write(tx_record_.t_ns, previous_tx_finished_,
                                                  previous_tx_t_ns_, now)) {
        report_.raise(miss->title, tx_written_,
                      std::string_view(expected).substr(0, kReplayContext),
                      rest.substr(0, kReplayContext), tx_record_.t_ns,
                      tx_exchange_, miss->detail);
      }
    }
    std::size_t accepted;
    if (config_.datagrams) {
      if (compare && (done != 0 || rest.size() != expected.size() ||
                      common_prefix(expected, rest, tx_wildcards_, 0) != rest.size())) {
        report_.raise("the client's datagram differs from the recorded one (" +
                          std::to_string(rest.size()) + " bytes written, " +
                          std::to_string(expected.size()) + " recorded)",
                      tx_written_,
                      std::string_view(expected).substr(0, kReplayContext),
                      rest.substr(0, kReplayContext), tx_record_.t_ns,
                      tx_exchange_, {}, /*expected_is_datagram=*/true);
      }
      // One datagram is one record, whatever its length.
      tx_written_ += expected.size();
      report_.accepted(expected);
      accepted = rest.size();
      wrote_past_recorded_flushes();
    } else {
      const std::size_t n = std::min(rest.size(), expected.size() - tx_position_);
      const std::string_view want(expected.data() + tx_position_, n);
      if (compare) {
        const std::size_t same =
            common_prefix(want, rest.substr(0, n), tx_wildcards_, tx_position_);
        if (same < n) {
          // The equal part was accepted; the report starts at the difference.
          tx_position_ += same;
          tx_written_ += same;
          report_.accepted(rest.substr(0, same));
          report_.raise(
              "the client wrote bytes that differ from the recording",
              tx_written_,
              std::string_view(expected).substr(tx_position_, kReplayContext),
              rest.substr(same, kReplayContext), tx_record_.t_ns, tx_exchange_);
        }
      }
      tx_position_ += n;
      tx_written_ += n;
      report_.accepted(rest.substr(0, n));
      accepted = n;
      if (n > 0) wrote_past_recorded_flushes();
      if (tx_position_ < expected.size()) {
        done += accepted;
        continue;
      }
    }
    tx_recorded_done_ += expected.size();
    if (empty_datagrams_) ++tx_datagrams_written_;
    tx_ends_.push_back({tx_progress(), now});
    previous_tx_finished_ = now;
    previous_tx_t_ns_ = tx_record_.t_ns;
    have_tx_record_ = false;
    done += accepted;
    if (config_.datagrams) return;
  } while (done < size);
}

// --- recorded events ---------------------------------------------------------------

bool SequenceStrategy::checks_events() const {
  return config_.check == ReplayCheck::timing;
}

bool SequenceStrategy::checks_lines() const {
  return checks_events() || (config_.check == ReplayCheck::data && lines_recorded_);
}

std::string_view SequenceStrategy::recorded_writes_next() const {
  if (!have_tx_record_) return {};
  return std::string_view(tx_record_.data).substr(tx_position_, kReplayContext);
}

void SequenceStrategy::client_event(RecordKind kind, const EventFields& fields) {
  const bool line = is_line_event(kind);
  // Settings are checked under check=timing; the client's lines also under
  // check=data, where the recording holds the device's lines.
  if (!checks_events() && !(line && config_.check == ReplayCheck::data)) return;
  if (!have_tx_record_ || tx_position_ == 0) next_tx_record();
  if (line && !checks_lines()) return;
  const ClientEvent made{kind, fields};
  const std::string made_text =
      line ? event_text(kind, fields) : "a " + event_text(kind, fields) + " event";
  if (expected_events_.empty()) {
    report_.raise_event("the client made " + made_text + " where the recording has none",
                        tx_written_, previous_tx_t_ns_, tx_exchange_,
                        event_mismatch_lines(std::nullopt, made), recorded_writes_next());
  }
  const Record& recorded = expected_events_.front();
  if (!event_matches(recorded, made, /*compare_break_length=*/checks_events())) {
    report_.raise_event("the client made " + made_text + "; the recording has " +
                            recorded_event_text(recorded),
                        tx_written_, recorded.t_ns, tx_exchange_,
                        event_mismatch_lines(recorded, made), recorded_writes_next());
  }
  expected_events_.pop_front();
}

// --- at close ------------------------------------------------------------------------

namespace {

// At close, the recording beyond the read cursor is read only this far once
// something unused has been found: enough to say what was left, and that
// there was more, without reading (under the port's lock) the whole rest of
// a long session the client left early.
constexpr std::uint64_t kUnusedScanBytes = 1 << 20;
constexpr std::uint64_t kUnusedScanRecords = 4096;

// "1 record", "3 records": a count and its noun agreeing.
std::string counted(std::uint64_t count, const std::string& noun) {
  return std::to_string(count) + " " + noun + (count == 1 ? "" : "s");
}

}  // namespace

std::uint64_t SequenceStrategy::rx_tx_progress() const {
  return empty_datagrams_ ? rx_tx_datagrams_seen_ : rx_tx_seen_;
}

std::uint64_t SequenceStrategy::tx_progress() const {
  return empty_datagrams_ ? tx_datagrams_written_ : tx_written_;
}

std::uint64_t SequenceStrategy::tx_consumed() const {
  return tx_recorded_done_ + (have_tx_record_ ? tx_position_ : 0);
}

std::string SequenceStrategy::unused_report(std::uint64_t queued_rx_bytes,
                                            std::uint64_t queued_rx_records) {
  // A flush gate holds rx at the end only where the client's last write
  // ended at the recorded flush (a write past it opens the gate): that rx is
  // recorded after the client's last write, and only unused (DESIGN.md
  // section 12).
  // Line changes the recording has after the client's last write, which
  // the client never made (those before a write it made were a mismatch).
  // The write cursor looks for them up to its next tx record. When the read
  // cursor reached the end without passing a line record, there is none,
  // and a session the client never wrote to is not read a second time.
  const bool no_line_change_ahead = rx_exhausted_ && !rx_line_records_seen_;
  if (!have_tx_record_ && !no_line_change_ahead) next_tx_record();
  std::string lines_never_made;
  std::size_t line_changes = 0;
  const Record* first_line_change = nullptr;
  for (const Record& event : expected_events_) {
    if (event.kind != RecordKind::modem_lines && event.kind != RecordKind::line_break) continue;
    if (line_changes++ == 0) first_line_change = &event;
  }
  if (first_line_change != nullptr) {
    lines_never_made = std::to_string(line_changes) +
                       " recorded line changes of the client were never made (the first: " +
                       recorded_event_text(*first_line_change) + " at session time " +
                       session_seconds(first_line_change->t_ns) + " s)";
  }
  expected_events_.clear();
  std::uint64_t rx_bytes = queued_rx_bytes;
  std::uint64_t rx_records = queued_rx_records;
  if (fixer_) {  // held back for the rest of a response frame
    rx_bytes += fixer_->held_rx_bytes();
    rx_records += fixer_->held_rx_records();
  }
  for (const Ahead& ahead : ahead_) {
    if (ahead.item.kind != RecordKind::rx) continue;
    rx_bytes += ahead.item.payload().size();
    ++rx_records;
  }
  // The read cursor has counted the recorded tx up to where it is; the write
  // cursor says how much of it the client wrote. Beyond the read cursor one
  // scan counts both directions, so the write cursor's source is not read.
  std::uint64_t tx_seen = rx_tx_seen_;
  const auto tx_unused = [&] {
    return tx_seen > tx_consumed() ? tx_seen - tx_consumed() : 0;
  };
  // Where empty datagrams are records, one unused is unused too.
  std::uint64_t tx_datagrams_seen = rx_tx_datagrams_seen_;
  const auto tx_datagrams_unused = [&]() -> std::uint64_t {
    if (!empty_datagrams_) return 0;
    return tx_datagrams_seen > tx_datagrams_written_ ? tx_datagrams_seen - tx_datagrams_written_
                                                     : 0;
  };
  const auto rx_unused = [&] { return rx_bytes > 0 || (empty_datagrams_ && rx_records > 0); };
  bool more = false;
  std::uint64_t scanned_records = 0;
  std::uint64_t scanned_bytes = 0;
  Record record;
  PayloadView view;
  while (!rx_exhausted_ && rx_source_->next(record, view)) {
    const std::size_t size = view ? view.bytes.size() : record.data.size();
    if (record.kind == RecordKind::close ||
        record.kind == RecordKind::device_lost) {
      break;
    }
    if (record.kind == RecordKind::rx && (size > 0 || empty_datagrams_)) {
      rx_bytes += size;
      ++rx_records;
    }
    if (record.kind == RecordKind::tx) {
      tx_seen += size;
      ++tx_datagrams_seen;
    }
    ++scanned_records;
    scanned_bytes += size;
    // Until something unused is found the scan is still within what the
    // client wrote (or events), so it only stops once it has.
    if ((scanned_bytes >= kUnusedScanBytes ||
         scanned_records >= kUnusedScanRecords) &&
        (rx_unused() || tx_unused() > 0 || tx_datagrams_unused() > 0)) {
      more = true;
      break;
    }
  }
  rx_exhausted_ = true;
  const std::uint64_t tx_bytes = tx_unused();
  const std::uint64_t tx_datagrams = tx_datagrams_unused();
  tx_exhausted_ = true;
  have_tx_record_ = false;
  const std::string at_least = more ? "at least " : "";
  std::string report;
  if (rx_unused()) {
    report = at_least + counted(rx_bytes, "recorded rx byte") + " (" + at_least +
             counted(rx_records, "record") + ") " + (rx_bytes == 1 && !more ? "was" : "were") +
             " never read";
  }
  if (tx_bytes > 0 || tx_datagrams > 0) {
    if (!report.empty()) report += "; ";
    report += at_least + counted(tx_bytes, "recorded tx byte") + " " +
              (empty_datagrams_ ? "(" + at_least + counted(tx_datagrams, "datagram") + ") "
                                : std::string()) +
              (tx_bytes == 1 && !more ? "was" : "were") + " never written";
  }
  if (more) report += " (the rest of the recording was not counted)";
  if (!lines_never_made.empty()) {
    if (!report.empty()) report += "; ";
    report += lines_never_made;
  }
  return report;
}

}  // namespace wiretape::detail
