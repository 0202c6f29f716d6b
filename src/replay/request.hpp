// match=request: the session is cut into exchanges (consecutive tx bytes,
// then the rx up to the next tx); when the bytes the client wrote since the
// last match begin with an unused exchange's request, that exchange's
// response is released. Serves a client that reorders, repeats or drops
// commands (DESIGN.md sections 7 and 13).
//
// Requests are indexed by their bytes (a hash table per distinct request,
// a sorted list for "could this still become a request"), so a write costs
// a lookup per distinct request length, not a scan of the session.
// Responses are kept in memory up to kKeptResponseBytes; past that, an
// exchange keeps only where its records are, and they are read from the
// session when served, so memory does not grow with the session.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "replay/client_session.hpp"
#include "replay/response_fixer.hpp"
#include "replay/strategy.hpp"

namespace wiretape::detail {

// Response bytes match=request keeps in memory; later responses are read
// from the session when served.
inline constexpr std::size_t kKeptResponseBytes = 8 << 20;

class RequestStrategy final : public ReplayStrategy {
 public:
  RequestStrategy(const ReplayConfig& config, const ReplayTimeline& timeline,
                  ReleasedRx& released, MismatchReport& report,
                  const RecordSourceFactory& sources);

  // Ends a wait for a longer request once `gap` passed with no write (with
  // a profile that frames by silence: the frame the client's silence ends).
  void release(ReplayTime now) override;
  bool more_to_release() const override;
  std::optional<ReplayTime> wake() const override;
  void write(const char* data, std::size_t size, ReplayTime now) override;
  void client_event(RecordKind, const std::map<std::string, std::string>&) override {
  }
  std::string unused_report(std::uint64_t queued_rx_bytes,
                            std::uint64_t queued_rx_records) override;

 private:
  static constexpr std::uint32_t kNone = UINT32_MAX;
  ModemInputs greeting_lines_;  // the device's lines before the first request
  void serve_greeting_lines(std::string_view payload);
  struct Exchange {
    std::uint32_t group = 0;               // its request
    std::uint32_t next_in_group = kNone;   // the group's next exchange
    std::uint64_t first_tx_t_ns = 0;
    std::uint64_t last_tx_t_ns = 0;
    std::uint64_t tx_offset = 0;
    // Its rx records are either kept (kept_[kept_first, kept_end)) or, once
    // the kept bytes reached kKeptResponseBytes, read from the session:
    // records [first_record, end_record) of the source (counted from its
    // first record).
    std::uint64_t first_record = 0;
    std::uint64_t end_record = 0;
    std::uint32_t kept_first = 0;
    std::uint32_t kept_end = 0;
    // With a profile: the recorded request frame, in raw_requests_.
    std::uint64_t raw_offset = 0;
    std::uint32_t raw_size = 0;
    bool in_session = false;
    bool has_response = false;
    bool used = false;
  };
  // The exchanges with one request, linked in recorded order; they are used
  // in that order, so the unused ones are those from next_unused on.
  struct Group {
    std::uint64_t offset = 0;  // of its request in request_bytes_
    std::uint32_t size = 0;
    std::uint32_t first = kNone;
    std::uint32_t last = kNone;
    std::uint32_t next_unused = kNone;
    std::uint32_t next_cycle = kNone;  // repeat=cycle
    // Some longer request begins with this one (a wait may be needed).
    bool extended = false;
    std::size_t hash = 0;
  };
  // Scrubbed requests (redaction events) and their wildcard bytes.
  void add_wildcards(std::uint32_t group, const Wildcards& wildcards);
  std::vector<std::pair<std::uint32_t, Wildcards>> wildcard_groups_;

  struct KeptRx {
    std::uint64_t offset = 0;  // in kept_bytes_
    std::uint32_t size = 0;
    std::uint64_t t_ns = 0;
  };
  // Which exchange a group would serve now, and how early it comes in the
  // matching order: unused exchanges in recorded order first, then (with
  // repeat) used-up requests in the order they were first recorded.
  struct Rank {
    int pass = 0;
    std::size_t exchange = 0;
    bool operator<(const Rank& other) const {
      return pass != other.pass ? pass < other.pass : exchange < other.exchange;
    }
  };

  std::string_view request_of(const Group& group) const {
    return std::string_view(request_bytes_).substr(group.offset, group.size);
  }
  std::string_view request_of_exchange(std::size_t exchange) const {
    return request_of(groups_[exchanges_[exchange].group]);
  }
  // The group whose request is `request` (of that hash), or kNone.
  std::uint32_t find_group(std::string_view request, std::size_t hash) const;
  // find_group(), creating the group if there is none.
  std::uint32_t group_for(std::string_view request);
  void grow_slots();
  // Adds the last exchange to the group `index`.
  void join_group(std::uint32_t index);
  // The `count` usable exchanges whose requests (keys) share the longest
  // prefix with `request`, as (prefix length, exchange), closest first.
  std::vector<std::pair<std::size_t, std::size_t>> closest_exchanges(std::string_view request,
                                                                     std::size_t count) const;
  void load_exchanges(RecordSource& source);
  // With a profile: each request frame is an exchange, keyed by its match key.
  void load_frames(RecordSource& source);
  // Adds an rx record (or the close that ends the session) to the last
  // exchange, or releases it as a greeting.
  void add_response(RecordKind kind, std::uint64_t t_ns, std::string_view payload,
                    std::uint64_t ordinal);
  void write_frames(const char* data, std::size_t size);
  // Serves (or reports) the frames in client_frames_.
  void take_frames(bool may_raise);
  [[noreturn]] void raise_unmatched_frame(const Frame& frame, const std::string& key);
  std::string_view raw_request(const Exchange& exchange) const {
    return std::string_view(raw_requests_).substr(exchange.raw_offset, exchange.raw_size);
  }
  // Releases a served response's record, through the fixer if there is one.
  void push_served(RxItem&& item);
  void index_requests();
  std::optional<Rank> rank(const Group& group) const;
  // The best group whose request the pending bytes begin with (datagrams:
  // equal).
  std::optional<std::pair<std::uint32_t, Rank>> best_match() const;
  // Whether an available request ranked before `before` (any, if nullopt)
  // begins with all the pending bytes and is longer.
  bool longer_request_pending(std::optional<Rank> before) const;
  // Matches what it can of the pending bytes. `quiet`: gap has passed since
  // the last write, so a complete request is taken without waiting for a
  // longer one. `may_raise`: unmatched bytes raise (else they wait for the
  // next write, which raises).
  void match_pending(bool quiet, bool may_raise);
  // Releases the exchange's response for `request`, the client's bytes that
  // matched it.
  // `actual_frame`: with a profile, the client's frame (for response fixes).
  void serve(std::uint32_t group, std::string_view request,
             std::string_view actual_frame = {});
  void push_response(const RxItem& item, const ReplayTimeline::Anchor& matched);
  void read_from_session(const Exchange& exchange,
                         const ReplayTimeline::Anchor& matched);
  [[noreturn]] void raise_unmatched();
  // The client's request at `offset` came when every recorded exchange was
  // served: a request past them (MismatchReport::raise_past_the_end).
  [[noreturn]] void raise_past_the_end(std::uint64_t offset, std::string_view actual) const;
  // Whether a record read by the loaders opens another client session's
  // records (see the definition); notes where this session's end.
  bool another_client_session(RecordKind kind, std::string_view payload);
  ClientSessionTracker sessions_;  // of the records the loaders read
  int sessions_begun_ = 0;
  static constexpr std::size_t kAllExchanges = SIZE_MAX;
  // The exchanges of this client session (the first ones): all of them
  // unless the recording's other sessions follow.
  std::size_t own_exchanges_ = kAllExchanges;
  // The loaders are past another session's client_connect and before its
  // first request: its rx was a greeting for its own client.
  bool greeting_of_another_ = false;

  const ReplayConfig& config_;
  const ReplayTimeline& timeline_;
  ReleasedRx& released_;
  MismatchReport& report_;
  const RecordSourceFactory sources_;  // a copy: the engine's is gone after construction

  std::vector<Exchange> exchanges_;
  std::vector<Group> groups_;
  std::string request_bytes_;  // every distinct request, end to end
  // An open-addressing hash table of the groups: index + 1, 0 when free.
  std::vector<std::uint32_t> slots_;
  std::vector<std::uint32_t> groups_by_request_;  // sorted by request bytes
  std::vector<std::size_t> request_lengths_;      // distinct, ascending
  std::string raw_requests_;  // with a profile
  std::unique_ptr<Framer> client_framer_;
  std::vector<Frame> client_frames_;
  // With a profile that fixes responses.
  std::unique_ptr<ResponseFixer> fixer_;
  std::uint64_t matches_ = 0;  // orders requests and responses for fixer_
  std::optional<Frame> deferred_unmatched_;  // see take_frames()
  std::string kept_bytes_;
  std::vector<KeptRx> kept_;
  // A recorded close or device loss, which ends the session after this
  // exchange.
  std::optional<RxItem> end_;
  std::size_t end_exchange_ = 0;
  std::size_t unused_with_response_ = 0;
  std::size_t with_response_ = 0;

  // Reads served responses that are not kept (made on first use).
  std::unique_ptr<RecordSource> response_source_;
  std::uint64_t response_position_ = 0;

  std::string pending_;  // written since the last match
  std::uint64_t pending_offset_ = 0;
  std::uint64_t tx_written_ = 0;  // bytes the client wrote
  std::size_t exchanges_served_ = 0;
  // The served exchange's number for RxItem::exchange (exchanges.hpp with
  // match=request): matches in served order, after a greeting's exchange 0.
  // (Mismatch reports name recorded exchanges by their recorded index.)
  bool greeting_ = false;
  std::uint64_t serving_exchange_ = 0;
  ReplayTime last_write_{};
  bool waiting_for_longer_ = false;
  std::optional<ReplayTime> last_match_time_;
  std::uint64_t last_match_t_ns_ = 0;
};

}  // namespace wiretape::detail
