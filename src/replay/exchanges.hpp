// The one segmentation of a session into exchanges (DESIGN.md section 17).
// Every feature that numbers exchanges uses it: mismatch reports, the fault
// plan's `exchange:N` (through RxItem::exchange) and the check of its places
// (served_shape), `wiretape edit --cut Ne`, `wiretape.faults`, the latencies
// of `wiretape stats` (LatencyMeter), client-session slicing of the exports.
//
// An exchange is a request of the client's and what the device sent until
// the client's next request:
// - a request is a run of consecutive tx records (rx ends it); with a
//   profile, one complete request frame of the profile's tx framer (the
//   exchange begins where the frame completes, however records split it:
//   rx sent while a frame was incomplete belongs to the exchange before);
//   in a datagram session, one tx datagram;
// - rx before the first request of a client session (a greeting) belongs to
//   that session's first exchange, as mismatch reports number it; under
//   match=request a greeting is an exchange of its own (exchange 0, the
//   first match exchange 1), as the replay serves it;
// - the request strategy's exchanges (what match=request matches) are cut
//   by it too; under match=request RxItem::exchange counts matches in
//   served order (the recorded order for a client that replays faithfully);
// - exchanges are numbered from 0 per file, across client sessions (a
//   virtual device's later client session starts at ReplayConfig::
//   first_exchange). A
//   client session begins at a controlling client's `client_connect` (a
//   read-only monitor's connect is none) and ends at its
//   `client_disconnect`; a connect ends the exchange before it. What the
//   device said between a client's disconnect and the next connect was
//   said to nobody and belongs to no exchange (a replay serves it to none).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "replay/client_session.hpp"
#include "replay/profile.hpp"
#include "replay/replay_config.hpp"
#include "session/record_source.hpp"

namespace wiretape::detail {

// How a session is cut: the profile whose request frames are the requests
// (none: tx runs), datagrams, and the match mode (a greeting is an exchange
// of its own under match=request).
struct Segmentation {
  std::shared_ptr<const Profile> profile;
  bool datagrams = false;
  ReplayMatch match = ReplayMatch::sequence;
  std::uint64_t first_index = 0;  // the number of the first exchange
};

// A request answered: how long after its request was complete the answer
// began (Exchange::request_end_t_ns to response_start_t_ns).
struct RequestLatency {
  std::uint64_t exchange = 0;
  std::string request_name;  // with a profile: its request frame's name ("?": none)
  std::uint64_t wait_ns = 0;
};

// The streaming form: fed every record in recorded order, it says which
// exchange each belongs to. Without a profile no allocation per record;
// with one, what the profile's framer allocates for the frames it cuts.
class ExchangeCursor {
 public:
  explicit ExchangeCursor(const Segmentation& segmentation);

  // Feeds one record (any kind; `payload` its data, an event's JSON for
  // events; `t_ns` its time, for a framer that cuts by silence); returns
  // the exchange it belongs to.
  std::uint64_t feed(RecordKind kind, std::uint64_t t_ns, std::string_view payload);
  std::uint64_t feed(const Record& record) { return feed(record.kind, record.t_ns, record.data); }
  // The exchange the next rx record would belong to.
  std::uint64_t current() const { return index_; }
  // Whether the record just fed began an exchange.
  bool began() const { return began_; }
  // The controlling client session the cursor is in (0-based), if any.
  std::optional<std::uint64_t> client_session() const {
    return tracker_.open() ? std::optional<std::uint64_t>(client_sessions_ - 1) : std::nullopt;
  }
  std::uint64_t client_sessions() const { return client_sessions_; }
  // With a profile: the request frames the last record fed completed, each
  // with the time of the record holding its first byte (a framer that cuts
  // by silence completes one when the device speaks).
  const std::vector<TimedFramer::TimedFrame>& frames_completed() const { return frames_; }
  // When the current exchange's request was complete: the time of the
  // record holding its last byte (without a profile the last tx record of
  // the run; with one the record that completed its frame, or for a framer
  // that cuts by silence the last tx before the device spoke). None: no
  // request yet (a greeting).
  std::optional<std::uint64_t> request_end_t_ns() const { return request_end_; }
  // The first rx record after request_end_t_ns(), said to a client: when the
  // answer began. None: not answered yet.
  std::optional<std::uint64_t> response_start_t_ns() const { return response_start_; }
  // Whether the record just fed began the answer to the current request.
  bool answer_began() const { return answer_began_; }

 private:
  void begin_request(std::optional<std::uint64_t> end_t_ns);
  void end_exchange();

  std::unique_ptr<TimedFramer> request_framer_;
  bool datagrams_;
  bool greeting_alone_;  // match=request
  std::vector<TimedFramer::TimedFrame> frames_;  // of the last record fed (reused)
  std::uint64_t index_ = 0;
  bool fresh_ = true;       // the current exchange has no request yet
  bool has_rx_ = false;     // the current exchange has rx
  bool request_open_ = false;  // no rx since the current request's last tx
  bool began_ = false;
  std::uint64_t client_sessions_ = 0;
  ClientSessionTracker tracker_;
  // What the device says after its client left, before the next came, is
  // said to nobody: no answer.
  bool said_to_nobody_ = false;
  std::optional<std::uint64_t> last_tx_t_ns_;
  std::optional<std::uint64_t> request_end_;
  std::optional<std::uint64_t> response_start_;
  bool answer_began_ = false;
};

// The latency pairing of `wiretape stats`, streamed over the one
// segmentation: fed a channel's records in order, it keeps each answered
// request (RequestLatency); memory grows with the answers, not the records.
class LatencyMeter {
 public:
  explicit LatencyMeter(const Segmentation& segmentation);
  void feed(RecordKind kind, std::uint64_t t_ns, std::string_view payload);
  const std::vector<RequestLatency>& answered() const { return answered_; }

 private:
  std::shared_ptr<const Profile> profile_;
  ExchangeCursor cursor_;
  std::string request_name_;  // with a profile: the current request frame's
  std::vector<RequestLatency> answered_;
};

// The whole-session form: one Exchange per exchange, in order.
struct Exchange {
  std::uint64_t index = 0;
  std::optional<std::uint64_t> client_session;  // where its first record is
  // Records [first_record, end_record) of the file (counted from 0, every
  // kind): the exchange's request, response and the events among them.
  std::uint64_t first_record = 0;
  std::uint64_t end_record = 0;
  // Session times of its first and last tx and rx records (none: it has none).
  std::optional<std::uint64_t> request_first_t_ns;
  std::optional<std::uint64_t> request_last_t_ns;
  std::optional<std::uint64_t> response_first_t_ns;
  std::optional<std::uint64_t> response_last_t_ns;
  // When its request was complete: the record holding the request's last
  // byte (without a profile the last tx record of the run; with one the
  // record that completed its request frame, tx written after it being the
  // next frame's). None: it has no request (a greeting of its own).
  std::optional<std::uint64_t> request_end_t_ns;
  // The first rx record after request_end_t_ns: when its answer began (a
  // greeting before the request is not one). None: not answered.
  std::optional<std::uint64_t> response_start_t_ns;
  // The channel of the session it was said on (segment_session_file sets
  // them; "" for the one channel of a session without named channels).
  std::uint16_t channel_id = 0;
  std::string channel_name;
  std::uint64_t request_bytes = 0;
  std::uint64_t response_bytes = 0;
  std::uint64_t response_records = 0;
  // With a profile: the request frame and the response frames (a response
  // frame belongs to the exchange its first byte came in).
  std::vector<std::string> request_frames;
  std::vector<std::string> response_frames;
};

// A controlling client's connection: records [first_record, end_record),
// from its client_connect to its client_disconnect (inclusive) or the next
// connect or the end.
struct ClientSession {
  std::uint64_t index = 0;
  std::uint64_t first_record = 0;
  std::uint64_t end_record = 0;
  std::uint64_t connect_t_ns = 0;
  std::optional<std::uint64_t> disconnect_t_ns;
};

struct SessionSegments {
  std::vector<Exchange> exchanges;
  std::vector<ClientSession> client_sessions;
};

// Reads `source` from where it is to its end.
SessionSegments segment_session(RecordSource& source, const Segmentation& segmentation);

// The number of the first exchange of client session `k` (1-based, as
// client_session_sources counts them): the exchanges before it in the file.
std::uint64_t first_exchange_of_client_session(RecordSource& source,
                                               const Segmentation& segmentation, int k);

// The session file at `path` cut as a replay with the replay keys `options`
// (profile=, match=, channel=, a declared profile's framing= ...; file= is `path`)
// would cut it; a session recorded from one of `datagram_types` (the
// registry's, passed down: detail::datagram_port_types()) is datagrams.
// OptionError for a bad replay key, SessionError or PortError for a file
// that cannot be read.
SessionSegments segment_session_file(const std::string& path, const std::string& options,
                                     const std::vector<std::string>& datagram_types);

// Where faults can fire in what a replay serves of `segments`: the
// exchanges of every client session (a virtual device serves its k-th
// client the k-th, and a fault's place may be in any), or all of them in a
// recording without client sessions.
SessionShape served_shape(const SessionSegments& segments);

// served_shape() of the file at `path` (replay keys `options`, as
// segment_session_file takes them): of each channel of a session of several
// ports, or of its one port.
SessionPlaces session_places_file(const std::string& path, const std::string& options,
                                  const std::vector<std::string>& datagram_types);

}  // namespace wiretape::detail
