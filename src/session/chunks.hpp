// Compressed chunks (format 2.0, DESIGN §29; docs/session-format.md "The
// chunk record"): records grouped into chunks of up to about 1 MiB, each
// chunk one zstd frame, written as one or more chunk records ("parts"): each
// flush of the file ends a part (ZSTD_e_flush), so that what was written
// decodes up to it, and the last part of a chunk (flag 0x01) ends the frame
// and carries the decoded length and CRC32C. Inside, each record is an
// entry: kind (u8), channel, time since the previous entry (zigzag) and
// length as varints, then the payload.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "wiretape/session.hpp"

namespace wiretape::detail {

inline constexpr std::uint8_t chunk_record_code = 0x21;
inline constexpr std::uint8_t chunk_last_part = 0x01;  // the record's flags
// A chunk ends once its decoded entries reach this much.
inline constexpr std::size_t chunk_target_bytes = 1u << 20;
// A reader refuses a chunk that decodes to more (a decompression bomb).
inline constexpr std::size_t max_chunk_decoded = 4u << 20;
// A record larger than this is written as an ordinary record between chunks.
inline constexpr std::size_t max_chunked_payload = 1u << 19;
// The last part's payload ends with the decoded length and CRC32C (u32 each).
inline constexpr std::size_t chunk_trailer_size = 8;
// A compressed file's version: older readers refuse it by its major version.
inline constexpr std::uint16_t compressed_version_major = 2;
inline constexpr std::uint16_t compressed_version_minor = 0;

// Where a whole chunk lies in the file, from its first part's record header
// to past its last part's CRC, and how many records of each channel it
// holds ((channel, records), in channel order, only the channels it
// holds): what the index of a compressed file lists.
struct ChunkPlace {
  std::uint64_t begin = 0;
  std::uint64_t end = 0;
  std::vector<std::pair<std::uint16_t, std::uint64_t>> records;
};

// Records counted by channel, chunk after chunk: the counts of one are
// taken in the time of the channels it held, not of every id up to the
// largest (a chunk may name any of 65536).
class ChannelCounts {
 public:
  void add(std::uint16_t channel) {
    if (channel >= counts_.size()) counts_.resize(channel + std::size_t{1});
    if (counts_[channel]++ == 0) touched_.push_back(channel);
  }
  // The counts so far, in channel order; back to none.
  std::vector<std::pair<std::uint16_t, std::uint64_t>> take();
  void clear();

 private:
  std::vector<std::uint64_t> counts_;
  std::vector<std::uint16_t> touched_;
};

// The writer's side: entries in, whole chunk records (header, payload, CRC)
// out. Not thread-safe (the writer's flush holds its io mutex).
class ChunkEncoder {
 public:
  ChunkEncoder();
  ~ChunkEncoder();
  ChunkEncoder(const ChunkEncoder&) = delete;
  ChunkEncoder& operator=(const ChunkEncoder&) = delete;

  // Whether a record of `size` payload bytes goes into a chunk (else it is
  // written as it is, after end_chunk()).
  static bool fits(std::size_t size) { return size <= max_chunked_payload; }
  // Adds a record; ends the chunk first (into `out`) when it would pass the
  // target size.
  void add(std::uint8_t kind, std::uint16_t channel, std::uint64_t t_ns,
           std::string_view payload, std::string& out);
  // Appends a part of what was added since the last part: the file is
  // flushed. Nothing when nothing was added.
  void flush_part(std::string& out);
  // Appends the chunk's last part (if a chunk is open).
  void end_chunk(std::string& out);
  bool chunk_open() const { return open_; }
  // The file offset where the `out` of the calls that follow begins (so
  // that the places of the chunks they end are known).
  void set_file_offset(std::uint64_t offset) { file_offset_ = offset; }
  // The chunks ended since the last call.
  std::vector<ChunkPlace> take_ended() { return std::exchange(ended_, {}); }

 private:
  void emit(std::string& out, bool last);

  struct Zstd;
  std::unique_ptr<Zstd> zstd_;
  std::string pending_;  // entries not compressed yet
  bool open_ = false;
  std::uint64_t previous_t_ = 0;
  std::uint64_t decoded_ = 0;  // bytes of the chunk's entries
  std::uint32_t crc_ = 0;      // CRC32C of them
  std::uint64_t file_offset_ = 0;
  ChunkPlace place_;  // of the open chunk, once its first part is out
  ChannelCounts counts_;  // of the open chunk
  bool placed_ = false;
  std::vector<ChunkPlace> ended_;
};

// The reader's side: parts in (their payloads, CRC-checked by the reader),
// records out.
class ChunkDecoder {
 public:
  ChunkDecoder();
  ~ChunkDecoder();
  ChunkDecoder(const ChunkDecoder&) = delete;
  ChunkDecoder& operator=(const ChunkDecoder&) = delete;

  // Decodes a part found at `offset`; std::nullopt, or why the chunk is
  // damaged (not zstd, larger than max_chunk_decoded, a last part whose
  // length or CRC does not match, an entry that does not parse).
  // `end`: past the part's CRC.
  std::optional<std::string> feed(std::uint64_t offset, std::uint64_t end,
                                  std::string_view payload, bool last);
  // The next whole record decoded, or false until more is fed. With `only`,
  // entries of other channels are passed over without copying their
  // payloads.
  bool next(Record& record, std::string* problem,
            std::optional<std::uint16_t> only = std::nullopt);
  // Once every entry of a chunk was handed out or passed over: where the
  // chunk lay and its records by channel (once per chunk).
  std::optional<ChunkPlace> take_finished();
  // Inside a chunk whose last part has not come.
  bool open() const { return open_; }
  // Where the open chunk began.
  std::uint64_t chunk_offset() const { return chunk_offset_; }
  void reset();

 private:
  struct Zstd;
  std::unique_ptr<Zstd> zstd_;
  // Decoded bytes, written by zstd in place (a std::string would be filled
  // with zeros before each write into it).
  class Bytes {
   public:
    std::size_t size() const { return size_; }
    std::string_view view() const { return {data_.get(), size_}; }
    void clear() { size_ = 0; }
    void discard_front(std::size_t count);
    // At least `more` writable bytes past the end; grow() then counts them.
    char* room(std::size_t more);
    void grow(std::size_t count) { size_ += count; }

   private:
    std::unique_ptr<char[]> data_;
    std::size_t size_ = 0;
    std::size_t capacity_ = 0;
  };
  Bytes decoded_;  // decoded bytes not yet handed out, from at_
  std::size_t at_ = 0;
  bool open_ = false;
  std::uint64_t chunk_offset_ = 0;
  std::uint64_t total_ = 0;  // decoded bytes of the chunk so far
  std::uint32_t crc_ = 0;
  std::uint64_t previous_t_ = 0;
  ChunkPlace place_;  // of the chunk being decoded
  ChannelCounts counts_;  // of its entries read so far
  bool finished_ = false;  // its last part came and every entry was read
};

}  // namespace wiretape::detail
