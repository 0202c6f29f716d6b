#include "replay/exchanges.hpp"

#include <algorithm>
#include <utility>

#include "replay/client_session.hpp"
#include "replay/replay_port.hpp"
#include "session/reader.hpp"
#include "wiretape/options.hpp"

namespace wiretape::detail {

ExchangeCursor::ExchangeCursor(const Segmentation& segmentation)
    : request_framer_(segmentation.profile
                          ? std::make_unique<TimedFramer>(
                                segmentation.profile->make_framer(StreamDirection::tx))
                          : nullptr),
      datagrams_(segmentation.datagrams),
      greeting_alone_(segmentation.match == ReplayMatch::request),
      index_(segmentation.first_index) {}

void ExchangeCursor::begin_request(std::optional<std::uint64_t> end_t_ns) {
  began_ = true;
  request_end_ = end_t_ns;
  response_start_.reset();
  // The first request of a client session takes its greeting along, except
  // under match=request, where the greeting was served on its own.
  if (!fresh_ || (has_rx_ && greeting_alone_)) ++index_;
  fresh_ = false;
  has_rx_ = false;
}

void ExchangeCursor::end_exchange() {
  if (!fresh_ || has_rx_) ++index_;
  fresh_ = true;
  has_rx_ = false;
  request_open_ = false;
  request_end_.reset();
  response_start_.reset();
  if (request_framer_) request_framer_->finish();  // a frame cut short
}

std::uint64_t ExchangeCursor::feed(RecordKind kind, std::uint64_t t_ns,
                                   std::string_view payload) {
  began_ = false;
  answer_began_ = false;
  frames_.clear();
  switch (kind) {
    case RecordKind::tx: {
      if (payload.empty()) break;
      if (request_framer_) {
        // An exchange begins where its request frame is complete: rx the
        // device sent while the frame was incomplete belongs to the one
        // before (the replay releases it before the client's frame is whole).
        request_framer_->feed(t_ns, payload, frames_);
        for (std::size_t i = 0; i < frames_.size(); ++i) begin_request(t_ns);
      } else if (datagrams_ || !request_open_) {
        begin_request(t_ns);
      } else if (!response_start_) {
        request_end_ = t_ns;  // the run goes on
      }
      request_open_ = true;
      last_tx_t_ns_ = t_ns;
      break;
    }
    case RecordKind::rx:
    case RecordKind::close:
    case RecordKind::device_lost:
      if (kind == RecordKind::rx && payload.empty()) break;
      // A framer that cuts by silence: the device speaking (or going away)
      // ends the request.
      if (request_framer_ && request_framer_->framer().quiet_gap() &&
          request_framer_->framer().pending() > 0) {
        if (std::optional<TimedFramer::TimedFrame> tail = request_framer_->finish()) {
          frames_.push_back(std::move(*tail));
          begin_request(last_tx_t_ns_);
        }
      }
      if (kind != RecordKind::rx) break;
      has_rx_ = true;
      request_open_ = false;
      if (request_end_ && !response_start_ && !said_to_nobody_) {
        response_start_ = t_ns;
        answer_began_ = true;
      }
      break;
    case RecordKind::client_connect:
    case RecordKind::client_disconnect: {
      ClientSessionTracker::Change change = tracker_.feed(kind, payload);
      if (change == ClientSessionTracker::Change::began) {
        end_exchange();
        ++client_sessions_;
        said_to_nobody_ = false;
      } else if (change == ClientSessionTracker::Change::ended) {
        said_to_nobody_ = true;
      }
      break;
    }
    default:
      break;
  }
  return index_;
}

SessionSegments segment_session(RecordSource& source, const Segmentation& segmentation) {
  SessionSegments segments;
  ExchangeCursor cursor(segmentation);
  std::unique_ptr<Framer> response_framer =
      segmentation.profile ? segmentation.profile->make_framer(StreamDirection::rx) : nullptr;
  std::vector<Frame> frames;
  std::uint64_t response_frame_exchange = 0;  // where the framer's kept tail began
  std::vector<std::pair<std::uint64_t, std::string>> response_frames;  // (exchange, frame)
  const auto exchange_at = [&](std::uint64_t index) -> Exchange* {
    for (auto it = segments.exchanges.rbegin(); it != segments.exchanges.rend(); ++it) {
      if (it->index == index) return &*it;
      if (it->index < index) break;
    }
    return nullptr;
  };
  const auto flush_response_frames = [&] {
    if (!response_framer) return;
    if (std::optional<Frame> tail = response_framer->finish()) {
      response_frames.emplace_back(response_frame_exchange, std::move(tail->bytes));
    }
  };
  Record record;
  std::uint64_t ordinal = 0;
  bool in_client_session = false;
  bool said_to_nobody = false;
  ClientSessionTracker sessions;
  for (; source.next(record); ++ordinal) {
    const std::uint64_t before = cursor.current();
    const std::uint64_t index = cursor.feed(record);
    const bool has_bytes = (record.kind == RecordKind::tx || record.kind == RecordKind::rx) &&
                           !record.data.empty();
    // Client sessions.
    const ClientSessionTracker::Change change = sessions.feed(record.kind, record.data);
    if (change == ClientSessionTracker::Change::began) {
      ClientSession session;
      session.index = segments.client_sessions.size();
      session.first_record = ordinal;
      session.end_record = ordinal + 1;
      session.connect_t_ns = record.t_ns;
      segments.client_sessions.push_back(session);
      in_client_session = true;
      said_to_nobody = false;
    } else if (in_client_session) {
      segments.client_sessions.back().end_record = ordinal + 1;
      if (change == ClientSessionTracker::Change::ended) {
        segments.client_sessions.back().disconnect_t_ns = record.t_ns;
        in_client_session = false;
        said_to_nobody = true;
      }
    }
    // What the device said after its client left, before the next one came,
    // was said to nobody: a replay serves it to no one, so no exchange has it.
    if (said_to_nobody && has_bytes) continue;
    if (index != before) flush_response_frames();
    if (has_bytes) {
      // One tx record may begin several exchanges (request frames).
      std::uint64_t next = segments.exchanges.empty() ? 0 : segments.exchanges.back().index + 1;
      if (index + 1 > next && record.kind == RecordKind::rx) next = index;
      for (; next <= index; ++next) {
        Exchange added;
        added.index = next;
        added.client_session = cursor.client_session();
        added.first_record = ordinal;
        added.end_record = ordinal + 1;
        segments.exchanges.push_back(std::move(added));
      }
    }
    Exchange* exchange = exchange_at(index);
    if (exchange == nullptr) continue;  // events before anything was said
    if (cursor.began()) {
      // With a profile a record may complete several request frames: each
      // began an exchange, the last one this.
      const auto& completed = cursor.frames_completed();
      std::uint64_t owner = index + 1 >= completed.size() ? index + 1 - completed.size() : 0;
      for (const TimedFramer::TimedFrame& timed : completed) {
        if (Exchange* own = exchange_at(owner)) {
          own->request_frames.push_back(timed.frame.bytes);
          own->request_end_t_ns = cursor.request_end_t_ns();
        }
        ++owner;
      }
    }
    exchange->end_record = ordinal + 1;
    exchange->request_end_t_ns = cursor.request_end_t_ns();
    exchange->response_start_t_ns = cursor.response_start_t_ns();
    if (!has_bytes) continue;
    if (record.kind == RecordKind::tx) {
      if (!exchange->request_first_t_ns) exchange->request_first_t_ns = record.t_ns;
      exchange->request_last_t_ns = record.t_ns;
      exchange->request_bytes += record.data.size();
    } else {
      if (!exchange->response_first_t_ns) exchange->response_first_t_ns = record.t_ns;
      exchange->response_last_t_ns = record.t_ns;
      exchange->response_bytes += record.data.size();
      ++exchange->response_records;
      if (response_framer) {
        if (response_framer->pending() == 0) response_frame_exchange = index;
        frames.clear();
        response_framer->feed_at(record.t_ns, record.data, frames);
        for (Frame& frame : frames) {
          response_frames.emplace_back(response_frame_exchange, std::move(frame.bytes));
          response_frame_exchange = index;
        }
      }
    }
  }
  flush_response_frames();
  for (auto& [index, bytes] : response_frames) {
    if (Exchange* exchange = exchange_at(index)) exchange->response_frames.push_back(std::move(bytes));
  }
  return segments;
}

std::uint64_t first_exchange_of_client_session(RecordSource& source,
                                               const Segmentation& segmentation, int k) {
  const SessionSegments segments = segment_session(source, segmentation);
  for (const Exchange& exchange : segments.exchanges) {
    if (exchange.client_session && *exchange.client_session + 1 >= static_cast<std::uint64_t>(k)) {
      return exchange.index;
    }
  }
  return segments.exchanges.empty() ? 0 : segments.exchanges.back().index + 1;
}

SessionSegments segment_session_file(const std::string& path, const std::string& options,
                                     const std::vector<std::string>& datagram_types) {
  Options parsed = Options::parse(options);
  parsed.set("file", path);
  const ReplayConfig config = take_replay_config(parsed);
  SessionHeader header;
  open_session_source(config.file, header, Streams::refused);
  // Exchanges are numbered per channel (DESIGN.md section 19).
  const Channel channel = choose_channel(config, header);
  const std::unique_ptr<RecordSource> source =
      session_source_factory(config.file, channel.id)();
  SessionSegments segments = segment_session(
      *source, Segmentation{config.profile, recorded_as_datagrams(channel, datagram_types),
                              config.match});
  if (source->damage()) throw *source->damage();
  for (Exchange& exchange : segments.exchanges) {
    exchange.channel_id = channel.id;
    exchange.channel_name = channel.name;
  }
  return segments;
}

SessionShape served_shape(const SessionSegments& segments) {
  SessionShape shape;
  bool first = true;
  for (const Exchange& exchange : segments.exchanges) {
    // A virtual device serves each client the records after its connect,
    // numbered on, and faults fire in any of them (the fault memory lasts
    // across them): what no client was connected for is served to none.
    if (!segments.client_sessions.empty() && !exchange.client_session) continue;
    if (first) shape.first_exchange = exchange.index;
    first = false;
    if (exchange.response_bytes > 0) shape.exchange_end = exchange.index + 1;
    shape.rx_bytes += exchange.response_bytes;
    if (exchange.response_last_t_ns) {
      shape.last_rx_t_ns = std::max(shape.last_rx_t_ns, *exchange.response_last_t_ns);
    }
  }
  return shape;
}

SessionPlaces session_places_file(const std::string& path, const std::string& options,
                                  const std::vector<std::string>& datagram_types) {
  SessionHeader header;
  open_session_source(path, header, Streams::refused);
  SessionPlaces places;
  const std::vector<Channel> channels = header.channel_list();
  if (channels.size() < 2) {
    places.shapes.push_back(served_shape(segment_session_file(path, options, datagram_types)));
    return places;
  }
  for (const Channel& channel : channels) {
    Options keys = Options::parse(options);
    keys.set("channel", channel.name);
    places.channels.push_back(channel.name);
    places.shapes.push_back(served_shape(segment_session_file(path, keys.to_string(), datagram_types)));
  }
  return places;
}

LatencyMeter::LatencyMeter(const Segmentation& segmentation)
    : profile_(segmentation.profile), cursor_(segmentation) {}

void LatencyMeter::feed(RecordKind kind, std::uint64_t t_ns, std::string_view payload) {
  cursor_.feed(kind, t_ns, payload);
  if (cursor_.began() && profile_ && !cursor_.frames_completed().empty()) {
    request_name_ =
        profile_->frame_name(StreamDirection::tx, cursor_.frames_completed().back().frame.bytes);
    if (request_name_.empty()) request_name_ = "?";
  }
  if (!cursor_.answer_began()) return;
  RequestLatency latency;
  latency.exchange = cursor_.current();
  latency.request_name = request_name_;
  latency.wait_ns = *cursor_.response_start_t_ns() - *cursor_.request_end_t_ns();
  answered_.push_back(std::move(latency));
}

}  // namespace wiretape::detail
