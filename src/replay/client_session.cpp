#include "replay/client_session.hpp"

#include <string>
#include <utility>

namespace wiretape::detail {

namespace {

// The bridge records a monitor's connect with role "monitor"; only the
// controlling client's connections make sessions.
bool is_controlling_connect(const Record& record) {
  return record.kind == RecordKind::client_connect &&
         record.data.find("\"monitor\"") == std::string::npos;
}

class ClientSessionSource final : public RecordSource {
 public:
  ClientSessionSource(std::unique_ptr<RecordSource> inner, int k)
      : inner_(std::move(inner)), k_(k) {}

  bool next(Record& record) override {
    return next_record(record, nullptr);
  }
  bool next(Record& record, PayloadView& view) override {
    return next_record(record, &view);
  }
  void rewind() override {
    inner_->rewind();
    started_ = false;
    ended_ = false;
  }
  const std::optional<SessionError>& damage() const override { return inner_->damage(); }

 private:
  bool next_record(Record& record, PayloadView* view) {
    if (!started_) {
      int seen = 0;
      Record skipped;
      while (seen < k_) {
        if (!inner_->next(skipped)) return false;
        if (is_controlling_connect(skipped)) ++seen;
      }
      started_ = true;
    }
    if (ended_) return false;
    const bool got = view ? inner_->next(record, *view) : inner_->next(record);
    if (!got) return false;
    // What follows the client's recorded disconnect was said to nobody, or
    // belongs to the next client's session.
    if (record.kind == RecordKind::client_disconnect) {
      ended_ = true;
      return false;
    }
    return true;
  }

  std::unique_ptr<RecordSource> inner_;
  const int k_;
  bool started_ = false;
  bool ended_ = false;
};

}  // namespace

std::optional<std::uint64_t> find_client_connect(RecordSource& source, int k) {
  Record record;
  int seen = 0;
  while (source.next(record)) {
    if (is_controlling_connect(record) && ++seen == k) return record.t_ns;
  }
  return std::nullopt;
}

RecordSourceFactory client_session_sources(RecordSourceFactory sources, int k) {
  return [sources = std::move(sources), k] {
    return std::make_unique<ClientSessionSource>(sources(), k);
  };
}

}  // namespace wiretape::detail
