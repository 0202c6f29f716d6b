// What the replay engine (replay_engine.hpp) shares with its two match
// strategies, match=sequence (sequence.hpp) and match=request (request.hpp):
// the queue of rx released to the client, the mismatch report, and the
// interface through which the engine drives a strategy.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "replay/replay_config.hpp"
#include "replay/timing.hpp"
#include "session/record_kinds.hpp"
#include "session/record_source.hpp"
#include "wiretape/session.hpp"

namespace wiretape::detail {

// Bytes of context a mismatch report shows on either side.
inline constexpr std::size_t kReplayContext = 16;

// A recorded rx record (or a recorded device loss) the client may read.
struct RxItem {
  RecordKind kind = RecordKind::rx;  // rx, close or device_lost
  std::string data;
  // The payload instead of data, when the source gave one: a view into the
  // session reader's 128 KiB read buffer, which it pins. The look-ahead's
  // record limit keeps that bounded (at most one buffer per queued record;
  // in practice the look-ahead's bytes plus one buffer).
  PayloadView view;
  std::size_t consumed = 0;
  std::string_view payload() const {
    return view ? view.bytes : std::string_view(data);
  }
  std::uint64_t t_ns = 0;
  ReplayTime due;  // readable from then on
  // The exchange it belongs to (exchanges.hpp), set by the strategy that
  // releases it: what `faults=exchange:N` and reports count.
  std::uint64_t exchange = 0;
};

// The rx the client is entitled to, in recorded order, each with its due
// time. Payload buffers of read records are kept (bounded) for the
// sequence strategy to read the next records into, so that a record costs
// no allocation once the look-ahead is warm.
class ReleasedRx {
 public:
  explicit ReleasedRx(bool recycle_payloads) : recycle_(recycle_payloads) {}

  bool empty() const { return items_.empty(); }
  std::size_t size() const { return items_.size(); }
  // Payload bytes of the queued records (read or not).
  std::size_t bytes() const { return bytes_; }
  RxItem& front() { return items_.front(); }
  const std::deque<RxItem>& items() const { return items_; }

  void push(RxItem&& item);
  void pop_front();

  // An empty string with capacity, if one was kept.
  std::string spare_payload();
  void recycle_payload(std::string&& buffer);

  // The device's modem inputs, released like rx (DESIGN.md section 20):
  // each recorded change is seen from its due time on, in recorded order,
  // whether or not the client read the rx before it.
  void push_lines(ReplayTime due, const ModemInputs& inputs) {
    lines_.push_back({due, inputs});
  }
  // The levels released and due by `now`.
  ModemInputs device_lines(ReplayTime now);

 private:
  struct LineChange {
    ReplayTime due;
    ModemInputs inputs;
  };
  std::deque<LineChange> lines_;
  ModemInputs device_lines_;  // the last change applied; a modem's line-up levels before any
  std::deque<RxItem> items_;
  std::size_t bytes_ = 0;
  bool recycle_;
  std::vector<std::string> spare_payloads_;
  std::size_t spare_bytes_ = 0;  // their capacity
};

// Look-ahead bounds of the sequence strategy's read cursor, which also bound
// the payload buffers kept for reuse, so memory does not depend on the
// session's size. A read larger than the look-ahead is still served in one
// go (ReplayEngine::read refills as it copies). The bytes are kept few so
// that the reader's buffers, refilled at half, are still in the CPU's cache
// when the client's read copies out of them: at 1 MiB (nine 128 KiB
// buffers in turn) a timing=none replay ran 20 % slower (docs/benchmarks.md).
inline constexpr std::size_t kLookaheadRecords = 256;
inline constexpr std::size_t kLookaheadBytes = 128 << 10;

// Raises ReplayMismatch with the report of DESIGN.md section 7; keeps the
// last bytes the client wrote for its "before" line.
class MismatchReport {
 public:
  // `channel`: the channel's name, said in reports of a file of several
  // channels; empty otherwise.
  MismatchReport(std::string file, ReplayMatch match, std::string channel = {})
      : file_(std::move(file)), match_(match), channel_(std::move(channel)) {}

  // The client wrote these bytes and they were accepted.
  void accepted(std::string_view bytes);

  // An empty `expected` is the end of the recorded writes, unless
  // `expected_is_datagram` (a recorded empty datagram).
  [[noreturn]] void raise(const std::string& title, std::uint64_t offset,
                          std::string_view expected, std::string_view actual,
                          std::uint64_t session_t_ns, std::int64_t exchange,
                          const std::string& extra = {},
                          bool expected_is_datagram = false) const;
  // The client wrote `actual` when no recorded request is left for it: a
  // request past the recorded exchanges `first` to `last` (none when last <
  // first), reported as the exchange after the last, by its number and the
  // count of those it is past; `whose` follows the count (" of this client
  // session").
  [[noreturn]] void raise_past_the_end(std::uint64_t offset, std::string_view actual,
                                       std::uint64_t session_t_ns, std::uint64_t first,
                                       std::int64_t last, std::string_view whose = {}) const;
  // A client event (settings, a line change, a break) that differs from the
  // recording: `event_lines` name the expected and the actual event, and
  // `writes_next` are the recorded writes that follow at that point (empty:
  // the recorded writes end there).
  [[noreturn]] void raise_event(const std::string& title, std::uint64_t offset,
                                std::uint64_t session_t_ns, std::int64_t exchange,
                                const std::string& event_lines,
                                std::string_view writes_next) const;

 private:
  [[noreturn]] void raise_with(const std::string& title, std::uint64_t offset,
                               std::string_view expected, std::string_view actual,
                               std::uint64_t session_t_ns, std::int64_t exchange,
                               const std::string& exchange_text, const std::string& extra,
                               bool expected_is_datagram) const;
  std::string heading(const std::string& title, std::uint64_t offset,
                      std::uint64_t session_t_ns, const std::string& exchange_text) const;

  std::string file_;
  ReplayMatch match_;
  std::string channel_;
  std::string history_;  // the last kReplayContext accepted bytes
};

// A match strategy: decides what the client is entitled to read and checks
// what it writes. Every call is given `now`; none reads a clock.
class ReplayStrategy {
 public:
  virtual ~ReplayStrategy() = default;
  // Moves whatever the client is now entitled to into the released queue.
  virtual void release(ReplayTime now) = 0;
  // Whether rx may still be released (by time, or by a write).
  virtual bool more_to_release() const = 0;
  // When release() may release more with no write by the client (the end of
  // match=request's wait for a longer request); nullopt: only a write can.
  virtual std::optional<ReplayTime> wake() const { return std::nullopt; }
  // Accepts the whole write or raises ReplayMismatch (or PortClosed past a
  // recorded close).
  virtual void write(const char* data, std::size_t size, ReplayTime now) = 0;
  // The client flushed its input or output: rx the recording shows after a
  // recorded client flush waits for the client's own (match=sequence).
  virtual void client_flushed() {}
  // See ReplayEngine::client_event.
  virtual void client_event(RecordKind kind,
                            const std::map<std::string, std::string>& fields) = 0;
  // What the recording held that the client never consumed, beyond the
  // released rx still queued (`queued_rx_bytes` in `queued_rx_records`);
  // empty if nothing.
  virtual std::string unused_report(std::uint64_t queued_rx_bytes,
                                    std::uint64_t queued_rx_records) = 0;
};

// --- small helpers both strategies use ----------------------------------------

// "%.6f" seconds of a session time.
std::string session_seconds(std::uint64_t ns);
std::size_t common_prefix(std::string_view a, std::string_view b);

// Bytes of a recorded tx record that `wiretape edit --redact` scrubbed
// (the redaction events before it): wildcards when the client's bytes are
// compared with it, so that a scrubbed recording replays to the driver that
// made it (DESIGN.md section 15).
class Wildcards {
 public:
  // Adds the range a redaction event's payload names; ignores a payload
  // that names none (the reader has checked its schema).
  void add_event(std::string_view payload);
  void add(std::size_t offset, std::size_t length);
  bool empty() const { return ranges_.empty(); }
  void clear() { ranges_.clear(); }
  bool covers(std::size_t position) const;
  // The same ranges, `shift` bytes later (a record's ranges within the
  // request it is part of).
  void append_shifted(const Wildcards& other, std::size_t shift);

 private:
  std::vector<std::pair<std::size_t, std::size_t>> ranges_;  // offset, length
};

// common_prefix of `recorded` (from byte `at` of its record, whose wildcards
// are `wildcards`) and the client's `written`: a wildcard byte matches any.
std::size_t common_prefix(std::string_view recorded, std::string_view written,
                          const Wildcards& wildcards, std::size_t at);

// A recorded close is the device going away only when the session goes on
// after it; the close that ends a recording (the client closing its port) is
// just the end, where at_end applies. Consumes the source.
bool session_goes_on(RecordSource& source);

}  // namespace wiretape::detail
