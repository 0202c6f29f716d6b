// Sequential reads of a session file (or a flexiport log) through a fixed
// buffer, for the session reader and the flexiport importer.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "posix/file_checks.hpp"
#include "session/record_source.hpp"

namespace wiretape::detail {

// Sequential reads from a file through a fixed buffer; memory independent of
// the file's size. Knows how many bytes a regular file still holds, so that
// length fields can be checked before anything is allocated. A stream (a
// pipe or FIFO, with Streams::read) has no size: reads wait for its bytes,
// and read_into() grows its string only as they arrive.
class BufferedFile {
 public:
  // Throws PortError naming `path` if it cannot be opened or is not a
  // regular file (nor, with Streams::read, a pipe or FIFO): InputFile.
  explicit BufferedFile(const std::string& path, Streams streams = Streams::refused);
  BufferedFile(const BufferedFile&) = delete;
  BufferedFile& operator=(const BufferedFile&) = delete;

  // Reads exactly `size` bytes; false (nothing consumed) if the file holds
  // fewer.
  bool read(void* out, std::size_t size);
  // Reads `size` bytes into `out`; the caller has checked remaining(). On a
  // stream, which cannot be checked first, `out` grows as bytes arrive, and
  // on false holds the bytes that did.
  bool read_into(std::string& out, std::size_t size);
  // Reads `size` bytes (at most max_view_size()) as a view into the buffer,
  // which is then never overwritten while the view lives; false (nothing
  // consumed) if the file holds fewer, or is a stream.
  bool read_view(std::size_t size, PayloadView& out);
  static std::size_t max_view_size();
  bool skip(std::uint64_t size);
  std::uint64_t position() const { return position_; }
  // Bytes after position(); re-reads the file's size so a file still being
  // written is followed. On a stream: the bytes already arrived, waiting for
  // some if none have, so 0 means the end.
  std::uint64_t remaining();
  std::uint64_t size() const { return size_; }
  // Throws PortError on a stream, which cannot go back.
  void seek(std::uint64_t position);
  bool is_stream() const { return file_.is_stream(); }
  int fd() const { return file_.fd(); }
  // Reads ahead no further than `end` (a file offset) while short of it, so
  // that a reader of some spans of a file does not read the bytes between
  // them; 0: as far as the buffer holds. Reads that need more still get it.
  void limit_read_ahead(std::uint64_t end) { read_ahead_end_ = end; }
  const std::string& path() const { return file_.path(); }

 private:
  std::size_t fill();
  // Up to `size` bytes at file offset `offset` (a stream: its next bytes).
  std::size_t read_some(char* out, std::size_t size, std::uint64_t offset);
  void refresh_size();
  bool read_stream(char* out, std::size_t size);

  InputFile file_;
  std::shared_ptr<char[]> buffer_;  // shared with the views handed out
  // Earlier buffers, reused once no view holds them any more.
  static constexpr std::size_t max_retired_buffers = 32;
  std::vector<std::shared_ptr<char[]>> retired_;
  std::size_t begin_ = 0;  // unread bytes are buffer_[begin_, end_)
  std::size_t end_ = 0;
  std::uint64_t position_ = 0;  // file offset of buffer_[begin_]
  std::uint64_t size_ = 0;
  std::uint64_t read_ahead_end_ = 0;
};

}  // namespace wiretape::detail
