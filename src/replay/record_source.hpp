// Where the replay engine gets its records from: a session file in
// production, a list of records in tests. The engine opens several
// independent cursors over the same session (one per direction), so it takes a
// factory rather than a single source.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "session/cursor.hpp"
#include "wiretape/session.hpp"

namespace wiretape::detail {

class RecordSource {
 public:
  virtual ~RecordSource() = default;
  // The next record in recorded order; false at the end.
  virtual bool next(Record& record) = 0;
  // next(), but a large payload may come as `view` instead of in
  // record.data (then left empty); `view` is empty otherwise.
  virtual bool next_view(Record& record, PayloadView& view) {
    view = PayloadView{};
    return next(record);
  }
};

using RecordSourceFactory = std::function<std::unique_ptr<RecordSource>()>;

// Records held in memory (shared by every cursor).
class VectorRecordSource final : public RecordSource {
 public:
  explicit VectorRecordSource(std::shared_ptr<const std::vector<Record>> records)
      : records_(std::move(records)) {}
  bool next(Record& record) override {
    if (position_ >= records_->size()) return false;
    record = (*records_)[position_++];
    return true;
  }

 private:
  std::shared_ptr<const std::vector<Record>> records_;
  std::size_t position_ = 0;
};

inline RecordSourceFactory vector_source_factory(std::vector<Record> records) {
  auto shared = std::make_shared<const std::vector<Record>>(std::move(records));
  return [shared] { return std::make_unique<VectorRecordSource>(shared); };
}

// A session file (.wtape or flexiport log), streamed. A damaged file replays
// up to the damage, with one warning on stderr.
RecordSourceFactory session_source_factory(const std::string& path);

}  // namespace wiretape::detail
