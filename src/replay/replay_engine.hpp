// The replay engine: decides which recorded rx bytes a client may read and
// when, and checks what it writes. It holds no threads and reads no clock:
// every call is given `now`, so tests can drive it deterministically; the
// replaying port adds locking, blocking and the pollable handle.
//
// Memory: match=sequence streams the session through two cursors (one for
// what the client reads, one for what it writes) with a bounded look-ahead;
// match=request keeps an index of the exchanges (requests and responses) in
// memory, because it may serve them in any order.
#pragma once

#include <chrono>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "session/record_source.hpp"
#include "replay/replay_config.hpp"
#include "wiretape/session.hpp"

namespace wiretape::detail {

using ReplayClock = std::chrono::steady_clock;
using ReplayTime = ReplayClock::time_point;

class ReplayEngine {
 public:
  ReplayEngine(ReplayConfig config, RecordSourceFactory sources,
               ReplayTime open_time);
  ~ReplayEngine();
  ReplayEngine(const ReplayEngine&) = delete;
  ReplayEngine& operator=(const ReplayEngine&) = delete;

  // Copies released, due bytes (at most one datagram in datagram sessions);
  // 0 when nothing is readable now. Raises PortClosed when the next thing
  // the recording holds is a close or a device loss that is due.
  std::size_t read(char* buffer, std::size_t size, ReplayTime now);
  // Bytes read() would return at once.
  std::size_t available(ReplayTime now);

  enum class ReadState {
    readable,     // read() returns data now
    device_gone,  // read() raises PortClosed now (recorded close)
    waiting,      // nothing yet: see wake
    ended,        // the recording has nothing more for the client to read
  };
  struct Outlook {
    ReadState state = ReadState::waiting;
    // When a waiting read becomes readable without any write; nullopt when
    // only a write by the client can release more.
    std::optional<ReplayTime> wake;
  };
  Outlook outlook(ReplayTime now);

  // Accepts the whole write or raises ReplayMismatch (or PortClosed past a
  // recorded close).
  void write(const char* data, std::size_t size, ReplayTime now);
  // The client changed line settings, a modem line or sent a break: under
  // check=timing (match=sequence) it must match the next recorded event of
  // that kind, in order with the writes. `fields` are the event's JSON
  // members as text (baud -> "115200", dtr -> "true").
  void client_event(RecordKind kind,
                    const std::map<std::string, std::string>& fields,
                    ReplayTime now);
  // Drops rx that was released and is due but not yet read.
  void flush_input(ReplayTime now);
  // What the recording held that the client never consumed; empty if all.
  std::string unused_report();

  const ReplayConfig& config() const { return config_; }

 private:
  struct RxItem {
    RecordKind kind = RecordKind::rx;  // rx, close or device_lost
    std::string data;
    // The payload instead of data, when the source gave one: a view into the
    // session reader's 64 KiB read buffer, which it pins. The look-ahead's
    // record limit keeps that bounded (at most one buffer per queued record;
    // in practice the look-ahead's bytes plus one buffer).
    PayloadView view;
    std::size_t consumed = 0;
    std::string_view payload() const {
      return view ? view.bytes : std::string_view(data);
    }
    std::uint64_t t_ns = 0;
    // match=sequence: tx bytes recorded before this record, and the time of
    // the last tx record before it (none: before any write).
    std::uint64_t tx_before = 0;
    std::optional<std::uint64_t> anchor_t_ns;
    std::optional<ReplayTime> due;  // set once the client is entitled to it
  };
  struct TxEnd {  // a recorded tx record the client finished writing
    std::uint64_t end_offset;
    ReplayTime finished;
  };
  struct Exchange {
    std::string request;
    std::uint64_t first_tx_t_ns = 0;
    std::uint64_t last_tx_t_ns = 0;
    std::uint64_t tx_offset = 0;
    std::vector<RxItem> responses;
    bool used = false;
  };

  std::chrono::nanoseconds scaled(std::uint64_t ns) const;
  // When a record recorded at `t_ns` is due by the session's clock alone:
  // at once (timing=none) or at its recorded time (timing=session, and
  // causal timing for records no write comes before).
  ReplayTime due_by_session_clock(std::uint64_t t_ns) const;
  void prepare(ReplayTime now);  // look-ahead and entitlement
  void fill_rx();
  void entitle();
  void pop_rx();
  // Payload buffers of consumed rx records, reused by the read cursor so a
  // record costs no allocation once the look-ahead is warm.
  std::string spare_payload();
  void recycle_payload(std::string&& buffer);
  bool is_due(const RxItem& item, ReplayTime now) const;

  // match=sequence
  bool next_tx_record();
  void write_sequence(const char* data, std::size_t size, ReplayTime now);
  void check_tx_timing(ReplayTime due, ReplayTime now);
  bool checks_events() const;

  // match=request
  void load_exchanges();
  void write_request(const char* data, std::size_t size, ReplayTime now);
  void serve(std::size_t exchange, ReplayTime now);
  bool match_pending(ReplayTime now);
  [[noreturn]] void raise_unmatched(ReplayTime now);

  [[noreturn]] void raise_mismatch(const std::string& title,
                                   std::uint64_t offset,
                                   std::string_view expected,
                                   std::string_view actual,
                                   std::uint64_t session_t_ns,
                                   std::int64_t exchange,
                                   const std::string& extra = {});

  ReplayConfig config_;
  RecordSourceFactory sources_;
  ReplayTime open_time_;

  std::deque<RxItem> rx_queue_;
  std::size_t rx_queue_bytes_ = 0;
  std::size_t first_unentitled_ = 0;  // match=sequence

  // match=sequence, the read cursor.
  std::unique_ptr<RecordSource> rx_source_;
  bool rx_exhausted_ = false;
  std::uint64_t rx_tx_seen_ = 0;
  std::optional<std::uint64_t> rx_last_tx_t_ns_;
  std::deque<TxEnd> tx_ends_;
  std::vector<std::string> spare_payloads_;
  std::size_t spare_bytes_ = 0;  // their capacity

  // match=sequence, the write cursor.
  std::unique_ptr<RecordSource> tx_source_;
  Record tx_record_;
  bool have_tx_record_ = false;
  bool tx_exhausted_ = false;
  bool tx_hit_close_ = false;
  std::uint64_t tx_close_t_ns_ = 0;
  std::size_t tx_position_ = 0;
  std::int64_t tx_exchange_ = -1;
  bool tx_after_rx_ = true;
  std::deque<Record> expected_events_;  // recorded before the next tx record
  std::optional<ReplayTime> previous_tx_finished_;
  std::uint64_t previous_tx_t_ns_ = 0;

  // Both modes.
  std::uint64_t tx_written_ = 0;  // bytes the client wrote
  std::string tx_history_;        // its last 16 accepted bytes

  // match=request.
  std::vector<Exchange> exchanges_;
  std::map<std::string, std::vector<std::size_t>> groups_;
  std::map<std::string, std::size_t> group_cursor_;
  std::string pending_;
  std::uint64_t pending_offset_ = 0;
  std::size_t exchanges_served_ = 0;
  std::optional<ReplayTime> last_match_time_;
  std::uint64_t last_match_t_ns_ = 0;
};

// "  56 56 0a  |VV.|" style rendering of up to 16 bytes.
std::string hex_ascii(std::string_view bytes);

}  // namespace wiretape::detail
