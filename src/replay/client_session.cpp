#include "replay/client_session.hpp"

#include <string>
#include <utility>

#include "session/record_kinds.hpp"
#include "util/json.hpp"

namespace wiretape::detail {

namespace {

// A member of an event payload, or nothing (a payload that is not JSON: an
// old or hand-made recording, read as a controlling client's).
std::optional<std::string> event_member(std::string_view payload, const char* key) {
  try {
    const json::Value value = json::parse(payload.empty() ? std::string_view("{}") : payload);
    if (const json::Value* member = value.find(key)) return member->text;
  } catch (const json::ParseError&) {
  }
  return std::nullopt;
}

}  // namespace

ClientSessionTracker::Change ClientSessionTracker::feed(RecordKind kind,
                                                        std::string_view payload) {
  if (kind == RecordKind::client_connect) {
    if (peer_ || event_member(payload, event_field::role) == std::optional<std::string>("monitor")) {
      return Change::none;
    }
    peer_ = event_member(payload, event_field::peer).value_or(std::string());
    return Change::began;
  }
  if (kind == RecordKind::client_disconnect && peer_) {
    const std::optional<std::string> peer = event_member(payload, event_field::peer);
    // A disconnect that names no peer is the session's (hand-made recordings).
    if (peer && !peer_->empty() && *peer != *peer_) return Change::none;
    peer_.reset();
    return Change::ended;
  }
  return Change::none;
}

namespace {

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
    tracker_ = ClientSessionTracker();
  }
  const std::optional<SessionError>& damage() const override { return inner_->damage(); }

 private:
  bool next_record(Record& record, PayloadView* view) {
    if (!started_) {
      int seen = 0;
      Record skipped;
      while (seen < k_) {
        if (!inner_->next(skipped)) return false;
        if (tracker_.feed(skipped.kind, skipped.data) == ClientSessionTracker::Change::began) {
          ++seen;
        }
      }
      started_ = true;
    }
    if (ended_) return false;
    const bool got = view ? inner_->next(record, *view) : inner_->next(record);
    if (!got) return false;
    // What follows the client's recorded disconnect was said to nobody, or
    // belongs to the next client's session.
    if (tracker_.feed(record.kind, record.data) == ClientSessionTracker::Change::ended) {
      ended_ = true;
      return false;
    }
    return true;
  }

  std::unique_ptr<RecordSource> inner_;
  const int k_;
  bool started_ = false;
  bool ended_ = false;
  ClientSessionTracker tracker_;
};

}  // namespace

std::optional<std::uint64_t> find_client_connect(RecordSource& source, int k) {
  Record record;
  ClientSessionTracker tracker;
  int seen = 0;
  while (source.next(record)) {
    if (tracker.feed(record.kind, record.data) == ClientSessionTracker::Change::began &&
        ++seen == k) {
      return record.t_ns;
    }
  }
  return std::nullopt;
}

namespace {

class SessionsFirstSource final : public RecordSource {
 public:
  SessionsFirstSource(RecordSourceFactory sources, int k) : sources_(std::move(sources)), k_(k) {}

  bool next(Record& record) override { return next_record(record, nullptr); }
  bool next(Record& record, PayloadView& view) override { return next_record(record, &view); }
  void rewind() override {
    source_.reset();
    others_ = false;
  }
  const std::optional<SessionError>& damage() const override {
    static const std::optional<SessionError> none;
    return source_ ? source_->damage() : none;
  }

 private:
  // Two passes over the recording: session k's records, then the other
  // sessions'; each session from the client_connect that began it to the
  // client_disconnect that ended it.
  bool next_record(Record& record, PayloadView* view) {
    for (;;) {
      if (!source_) {
        source_ = sources_();
        tracker_ = ClientSessionTracker();
        session_ = 0;
      }
      if (!(view ? source_->next(record, *view) : source_->next(record))) {
        if (others_) return false;
        others_ = true;
        source_.reset();
        continue;
      }
      const std::string_view payload =
          view && *view ? view->bytes : std::string_view(record.data);
      const ClientSessionTracker::Change change = tracker_.feed(record.kind, payload);
      if (change == ClientSessionTracker::Change::began) ++session_;
      const bool in_session = tracker_.open() || change == ClientSessionTracker::Change::ended;
      if (in_session && (session_ == k_) != others_) return true;
    }
  }

  const RecordSourceFactory sources_;
  const int k_;
  std::unique_ptr<RecordSource> source_;
  bool others_ = false;  // the second pass
  ClientSessionTracker tracker_;
  int session_ = 0;
};

}  // namespace

int count_client_sessions(RecordSource& source) {
  Record record;
  ClientSessionTracker tracker;
  int seen = 0;
  while (source.next(record)) {
    if (tracker.feed(record.kind, record.data) == ClientSessionTracker::Change::began) ++seen;
  }
  return seen;
}

RecordSourceFactory sessions_first_sources(RecordSourceFactory sources, int k) {
  return [sources = std::move(sources), k] {
    return std::make_unique<SessionsFirstSource>(sources, k);
  };
}

RecordSourceFactory client_session_sources(RecordSourceFactory sources, int k) {
  return [sources = std::move(sources), k] {
    return std::make_unique<ClientSessionSource>(sources(), k);
  };
}

}  // namespace wiretape::detail
