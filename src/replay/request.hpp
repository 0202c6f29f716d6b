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
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

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

  // Ends a wait for a longer request once `gap` passed with no write.
  void release(ReplayTime now) override;
  bool more_to_release() const override;
  std::optional<ReplayTime> wake() const override;
  void write(const char* data, std::size_t size, ReplayTime now) override;
  void client_event(RecordKind, const std::map<std::string, std::string>&) override {
  }
  std::string unused_report(std::uint64_t queued_rx_bytes,
                            std::uint64_t queued_rx_records) override;

 private:
  struct Exchange {
    std::size_t group = 0;  // its request
    std::uint64_t first_tx_t_ns = 0;
    std::uint64_t last_tx_t_ns = 0;
    std::uint64_t tx_offset = 0;
    // Its rx records are either kept here or, once the kept bytes reached
    // kKeptResponseBytes, read from the session: records [first_record,
    // end_record) of the source (counted from its first record).
    std::vector<RxItem> kept;
    bool in_session = false;
    std::uint64_t first_record = 0;
    std::uint64_t end_record = 0;
    // A recorded close or device loss that ends the session after it.
    std::optional<RxItem> end;
    bool has_response = false;
    bool used = false;
  };
  // The exchanges with one request, in recorded order; they are used in
  // that order, so the unused ones are those from next_unused on.
  struct Group {
    std::string request;
    std::vector<std::size_t> members;
    std::size_t next_unused = 0;
    std::size_t next_cycle = 0;  // repeat=cycle
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

  void load_exchanges(RecordSource& source);
  void index_requests();
  std::optional<Rank> rank(const Group& group) const;
  // The best group whose request the pending bytes begin with (datagrams:
  // equal).
  std::optional<std::pair<std::size_t, Rank>> best_match() const;
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
  void serve(std::size_t group, std::string_view request);
  void push_response(const RxItem& item, const ReplayTimeline::Anchor& matched);
  void read_from_session(const Exchange& exchange,
                         const ReplayTimeline::Anchor& matched);
  [[noreturn]] void raise_unmatched();

  const ReplayConfig& config_;
  const ReplayTimeline& timeline_;
  ReleasedRx& released_;
  MismatchReport& report_;
  const RecordSourceFactory sources_;  // a copy: the engine's is gone after construction

  std::vector<Exchange> exchanges_;
  std::deque<Group> groups_;  // a deque: group_of_ views their requests
  std::unordered_map<std::string_view, std::size_t> group_of_;
  std::vector<std::size_t> groups_by_request_;  // sorted by request bytes
  std::set<std::size_t> request_lengths_;
  std::size_t unused_with_response_ = 0;
  std::size_t with_response_ = 0;

  // Reads served responses that are not kept (made on first use).
  std::unique_ptr<RecordSource> response_source_;
  std::uint64_t response_position_ = 0;

  std::string pending_;  // written since the last match
  std::uint64_t pending_offset_ = 0;
  std::uint64_t tx_written_ = 0;  // bytes the client wrote
  std::size_t exchanges_served_ = 0;
  ReplayTime last_write_{};
  bool waiting_for_longer_ = false;
  std::optional<ReplayTime> last_match_time_;
  std::uint64_t last_match_t_ns_ = 0;
};

}  // namespace wiretape::detail
