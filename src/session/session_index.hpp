// The per-channel index of a session of several ports (format 1.3, DESIGN
// §29; docs/session-format.md, "The index record"): for each channel, the
// spans of the file that hold its records, so that a reader of one channel
// reads only its own pages. Written by the writer at close, appended by
// `verify --repair`; a reader that finds none, or one that does not describe
// the file, reads every record as before. Readers never write it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "session/reader.hpp"

namespace wiretape::detail {

// A record of the file's structure, not of the session (codes 0x20-0x2F,
// docs/session-format.md "Structure records"): readers of 1.2 skip it as a
// kind they do not know, readers of 1.3 never hand it out.
inline constexpr std::uint8_t index_record_code = 0x20;
// The last bytes of an index record's payload, so that a reader finds it
// from the end of the file: the record's own offset, then this mark.
inline constexpr char index_trailer_mark[8] = {'W', 'T', 'I', 'N', 'D', 'E', 'X', '1'};
inline constexpr std::size_t index_trailer_size = 16;
// Records of one channel closer than this to each other are one span: a
// reader reads the bytes between (other channels' records, skipped as they
// come) rather than seek for each page.
inline constexpr std::uint64_t index_span_merge_gap = 4096;

// One span: the bytes [begin, end) hold records of the channel, whole, and
// may hold other channels' records too.
struct IndexSpan {
  std::uint64_t begin = 0;
  std::uint64_t end = 0;
};

// A channel's spans in the index's compact form (varints: gap since the
// previous span's end, then length), read one at a time: from memory, or
// from the file through a small buffer (a reader's memory then does not
// grow with the index).
class ChannelSpans {
 public:
  ChannelSpans() = default;
  ChannelSpans(std::string encoded, std::uint64_t records)
      : size_(encoded.size()), buffer_(std::move(encoded)), records_(records) {}
  // The `size` bytes at `offset` of the open file `fd` (the caller's, which
  // outlives this).
  ChannelSpans(int fd, std::uint64_t offset, std::uint64_t size, std::uint64_t records)
      : fd_(fd), offset_(offset), size_(size), records_(records) {}
  // The next span, or false after the last (or if the file cannot be read
  // or its bytes do not decode).
  bool next(IndexSpan& span);
  void rewind();
  std::uint64_t records() const { return records_; }

 private:
  bool refill();

  int fd_ = -1;              // -1: buffer_ holds every byte
  std::uint64_t offset_ = 0;  // of the encoded bytes in the file
  std::uint64_t size_ = 0;    // of the encoded bytes
  std::uint64_t base_ = 0;    // where in the encoded bytes buffer_ begins
  std::string buffer_;
  std::size_t at_ = 0;
  std::uint64_t records_ = 0;
  std::uint64_t previous_end_ = 0;
};

// Builds an index from the records as they are written (or found by a scan):
// memory grows with the spans, at most a few bytes per 4 KiB of file.
class SessionIndexBuilder {
 public:
  // `records` records of `channel` at [offset, end): one record, or in a
  // compressed file the chunk that holds them.
  void add(std::uint64_t offset, std::uint64_t end, std::uint16_t channel,
           std::uint64_t records = 1);
  // The whole index record (header, payload, CRC) for a file whose records
  // end at `at`, where the record goes, listing `channel_count` channels.
  std::string record_bytes(std::uint64_t at, std::size_t channel_count) const;

 private:
  struct Channel {
    std::string encoded;
    std::uint64_t records = 0;
    std::uint64_t spans = 0;
    std::uint64_t previous_end = 0;  // of the last span encoded
    std::optional<IndexSpan> open;   // the span being extended
  };
  static void close_span(Channel& channel);
  std::vector<Channel> channels_;
};

// What the end of a file says of its index.
struct IndexFound {
  std::uint64_t offset = 0;  // where the index record begins
  std::string payload;       // checked: CRC, layout (find_session_index)
  std::size_t channel_count = 0;
  ChannelSpans spans;  // one channel's (find_channel_spans)
};

// The index at the end of the regular file `fd` of `file_size` bytes whose
// first record is at `first_record` (read with pread), or std::nullopt with the reason in `why_not`
// when there is none or it does not describe the file (`channel_count`:
// the header's).
std::optional<IndexFound> find_session_index(int fd, std::uint64_t file_size,
                                             std::uint64_t first_record,
                                             std::size_t channel_count, std::string* why_not);

// `channel`'s spans of a found index.
ChannelSpans channel_spans(const IndexFound& index, std::uint16_t channel);
// find_session_index() for a reader of one channel: only its spans are
// kept (the rest of the index is read through a small buffer for its CRC),
// so that its memory is that channel's share of the index. A channel the
// index does not list has no spans.
std::optional<ChannelSpans> find_channel_spans(int fd, std::uint64_t file_size,
                                               std::uint64_t first_record,
                                               std::size_t channel_count, std::uint16_t channel,
                                               std::string* why_not);

// What `wiretape verify` says of a file's index.
enum class IndexState {
  not_needed,  // one channel: a reader reads every record anyway
  current,     // it describes every record of the file
  absent,      // none (the writer did not close the file): readers scan
  stale,       // one that does not describe the file: readers scan
  unchecked,   // the file is damaged
};
std::string_view to_string(IndexState state);
struct IndexStatus {
  IndexState state = IndexState::not_needed;
  std::string detail;  // why absent or stale, or where it was appended
};

// The index a file's records call for, collected while a reader walks all
// of them (its RecordPlaceSink), and whether the file's own matches it.
class IndexCheck {
 public:
  RecordPlaceSink sink();
  IndexStatus status(const std::string& path, std::size_t channel_count, bool damaged) const;
  // The index record to append at `at`, the end of the file.
  std::string record_bytes(std::uint64_t at, std::size_t channel_count) const {
    return scanned_.record_bytes(at, channel_count);
  }

 private:
  SessionIndexBuilder scanned_;
};

// `wiretape verify --repair`: appends the index to a file of several
// channels whose index is absent or stale (the old one stays, skipped as
// every reader skips it), and says what it found or did (state current
// and where, when it appended). Throws SessionError when the file is
// damaged (the records an index would describe are not known), PortError
// when it cannot be written.
IndexStatus repair_session_index(const std::string& path);

}  // namespace wiretape::detail
