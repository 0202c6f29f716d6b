// Where records come from: a .wtape file, a merged pair of flexiport logs, or
// (in tests) a list in memory. The session reader and the replay engine both
// read through this one interface.
#pragma once

#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <string_view>
#include <utility>
#include <vector>

#include "wiretape/errors.hpp"
#include "wiretape/session.hpp"

namespace wiretape::detail {

// Payload bytes in a read buffer; `owner` keeps that buffer alive and
// unchanged (the reader continues in a fresh buffer while a view is held).
struct PayloadView {
  std::shared_ptr<const void> owner;
  std::string_view bytes;
  explicit operator bool() const { return owner != nullptr; }
};

// Payloads from this size up are handed out as views; smaller ones are
// copied (cheap, and a view of a few bytes would pin a whole buffer).
inline constexpr std::size_t min_view_payload = 512;

class RecordSource {
 public:
  virtual ~RecordSource() = default;
  // The next record in recorded order; false at the end or at damage (then
  // damage() says where).
  virtual bool next(Record& record) = 0;
  // next(), but a large payload may come as `view` instead of in
  // record.data (then left empty); `view` is empty otherwise. The replay
  // engine reads this way to copy each payload once, into the client's
  // buffer.
  virtual bool next(Record& record, PayloadView& view) {
    view = PayloadView{};
    return next(record);
  }
  // Back to the first record.
  virtual void rewind() = 0;
  // Why the records ended early, if they did.
  virtual const std::optional<SessionError>& damage() const = 0;
  // Set when the records ended at the unfinished end of a file its writer
  // is still writing (not damage: every record before it was read).
  virtual const std::optional<SessionError>& unfinished() const {
    static const std::optional<SessionError> none;
    return none;
  }
};

// The replay engine opens several independent sources over one session (one
// per direction), so it takes a factory rather than a single source.
using RecordSourceFactory = std::function<std::unique_ptr<RecordSource>()>;

// Records held in memory (shared by every source the factory makes).
class VectorRecordSource final : public RecordSource {
 public:
  explicit VectorRecordSource(std::shared_ptr<const std::vector<Record>> records)
      : records_(std::move(records)) {}
  bool next(Record& record) override {
    if (position_ >= records_->size()) return false;
    record = (*records_)[position_++];
    return true;
  }
  // Every payload as a view: the records are held, unchanged, as long as
  // any source of the factory is, so a view pins nothing more and spares
  // the copy of each payload (a fuzzer opens a replay per run).
  bool next(Record& record, PayloadView& view) override {
    view = PayloadView{};
    if (position_ >= records_->size()) return false;
    const Record& held = (*records_)[position_++];
    record.t_ns = held.t_ns;
    record.kind = held.kind;
    record.channel = held.channel;
    record.data.clear();
    view = PayloadView{records_, held.data};
    return true;
  }
  void rewind() override { position_ = 0; }
  const std::optional<SessionError>& damage() const override { return no_damage_; }

 private:
  std::shared_ptr<const std::vector<Record>> records_;
  std::size_t position_ = 0;
  std::optional<SessionError> no_damage_;
};

inline RecordSourceFactory vector_source_factory(std::vector<Record> records) {
  auto shared = std::make_shared<const std::vector<Record>>(std::move(records));
  return [shared] { return std::make_unique<VectorRecordSource>(shared); };
}

}  // namespace wiretape::detail
