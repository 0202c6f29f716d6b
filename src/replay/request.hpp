// match=request: the session is cut into exchanges (consecutive tx bytes,
// then the rx up to the next tx), indexed in memory; when the bytes the
// client wrote since the last match begin with an unused exchange's request,
// that exchange's response is released. Serves a client that reorders,
// repeats or drops commands (DESIGN.md sections 7 and 13).
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "replay/strategy.hpp"

namespace wiretape::detail {

class RequestStrategy final : public ReplayStrategy {
 public:
  RequestStrategy(const ReplayConfig& config, const ReplayTimeline& timeline,
                  ReleasedRx& released, MismatchReport& report,
                  const RecordSourceFactory& sources);

  void release() override {}  // only a match releases, and it does so at once
  bool more_to_release() const override;
  void write(const char* data, std::size_t size, ReplayTime now) override;
  void client_event(RecordKind, const std::map<std::string, std::string>&) override {
  }
  std::string unused_report(std::uint64_t queued_rx_bytes,
                            std::uint64_t queued_rx_records) override;

 private:
  struct Exchange {
    std::string request;
    std::uint64_t first_tx_t_ns = 0;
    std::uint64_t last_tx_t_ns = 0;
    std::uint64_t tx_offset = 0;
    std::vector<RxItem> responses;
    bool used = false;
  };

  void load_exchanges(RecordSource& source);
  // Releases the exchange's response for `request`, the client's bytes that
  // matched it.
  void serve(std::size_t exchange, std::string_view request, ReplayTime now);
  bool match_pending(ReplayTime now);
  [[noreturn]] void raise_unmatched();

  const ReplayConfig& config_;
  const ReplayTimeline& timeline_;
  ReleasedRx& released_;
  MismatchReport& report_;

  std::vector<Exchange> exchanges_;
  std::map<std::string, std::vector<std::size_t>> groups_;
  std::map<std::string, std::size_t> group_cursor_;
  std::string pending_;  // written since the last match
  std::uint64_t pending_offset_ = 0;
  std::uint64_t tx_written_ = 0;  // bytes the client wrote
  std::size_t exchanges_served_ = 0;
  std::optional<ReplayTime> last_match_time_;
  std::uint64_t last_match_t_ns_ = 0;
};

}  // namespace wiretape::detail
