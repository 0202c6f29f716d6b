// A session reader for the replay engine that can hand out record payloads as
// views into its read buffers instead of copying them into Record::data: the
// replay then copies each payload once, into the client's buffer.
#pragma once

#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

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

// The same files, checks and damage reports as SessionReader.
class SessionCursor {
 public:
  explicit SessionCursor(const std::string& path);
  ~SessionCursor();
  SessionCursor(const SessionCursor&) = delete;
  SessionCursor& operator=(const SessionCursor&) = delete;

  bool next(Record& record);
  // Like next(), but a payload of at least min_view_payload bytes that fits
  // the read buffer comes as `view` (record.data is then left empty); `view`
  // is empty otherwise.
  bool next(Record& record, PayloadView& view);
  const std::optional<SessionError>& damage() const;
  const std::string& path() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace wiretape::detail
