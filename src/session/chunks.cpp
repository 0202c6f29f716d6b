#include "session/chunks.hpp"

#include <zstd.h>

#include <algorithm>
#include <cstring>
#include <stdexcept>

#include "session/format.hpp"

namespace wiretape::detail {

namespace {

// Level 3, zstd's default: the recorder keeps up with the traffic it
// records (docs/benchmarks.md) and sensor streams shrink well at it.
constexpr int compression_level = 3;

std::uint64_t zigzag(std::int64_t v) {
  return (static_cast<std::uint64_t>(v) << 1) ^ static_cast<std::uint64_t>(v >> 63);
}
std::int64_t unzigzag(std::uint64_t v) {
  return static_cast<std::int64_t>(v >> 1) ^ -static_cast<std::int64_t>(v & 1);
}

}  // namespace

struct ChunkEncoder::Zstd {
  ZSTD_CCtx* context = ZSTD_createCCtx();
  ~Zstd() { ZSTD_freeCCtx(context); }
};

ChunkEncoder::ChunkEncoder() : zstd_(std::make_unique<Zstd>()) {
  if (zstd_->context == nullptr) throw std::bad_alloc();
  ZSTD_CCtx_setParameter(zstd_->context, ZSTD_c_compressionLevel, compression_level);
}

ChunkEncoder::~ChunkEncoder() = default;

void ChunkEncoder::add(std::uint8_t kind, std::uint16_t channel, std::uint64_t t_ns,
                       std::string_view payload, std::string& out) {
  // kind, then at most 3 + 10 + 10 bytes of varints
  constexpr std::size_t max_entry_head = 24;
  if (open_ && decoded_ + max_entry_head + payload.size() > chunk_target_bytes) end_chunk(out);
  open_ = true;
  counts_.add(channel);
  std::string entry;
  entry.push_back(static_cast<char>(kind));
  put_varint(entry, channel);
  // A chunk's first entry counts its time from 0 (previous_t_ is reset).
  put_varint(entry, zigzag(static_cast<std::int64_t>(t_ns - previous_t_)));
  put_varint(entry, payload.size());
  previous_t_ = t_ns;
  crc_ = crc32c(entry.data(), entry.size(), crc_);
  crc_ = crc32c(payload.data(), payload.size(), crc_);
  decoded_ += entry.size() + payload.size();
  pending_ += entry;
  pending_.append(payload.data(), payload.size());
}

void ChunkEncoder::flush_part(std::string& out) {
  if (!pending_.empty()) emit(out, false);
}

void ChunkEncoder::end_chunk(std::string& out) {
  if (open_) emit(out, true);
}

void ChunkEncoder::emit(std::string& out, bool last) {
  const std::size_t start = out.size();
  if (!placed_) {
    place_.begin = file_offset_ + start;
    placed_ = true;
  }
  out.append(record_header_size, '\0');
  ZSTD_inBuffer in{pending_.data(), pending_.size(), 0};
  const ZSTD_EndDirective mode = last ? ZSTD_e_end : ZSTD_e_flush;
  std::size_t left = 0;
  do {
    const std::size_t room = ZSTD_compressBound(in.size - in.pos) + 64;
    const std::size_t at = out.size();
    out.resize(at + room);
    ZSTD_outBuffer buffer{&out[at], room, 0};
    left = ZSTD_compressStream2(zstd_->context, &buffer, &in, mode);
    if (ZSTD_isError(left)) {
      throw std::runtime_error(std::string("zstd: ") + ZSTD_getErrorName(left));
    }
    out.resize(at + buffer.pos);
  } while (left != 0 || in.pos < in.size);
  pending_.clear();
  if (last) {
    char trailer[chunk_trailer_size];
    put_u32le(trailer, static_cast<std::uint32_t>(decoded_));
    put_u32le(trailer + 4, crc_);
    out.append(trailer, sizeof trailer);
    open_ = false;
    decoded_ = 0;
    crc_ = 0;
    previous_t_ = 0;
  }
  char* head = &out[start];
  put_u32le(head, static_cast<std::uint32_t>(out.size() - start - record_header_size));
  head[4] = static_cast<char>(chunk_record_code);
  head[5] = static_cast<char>(last ? chunk_last_part : 0);
  char crc[crc_size];
  put_u32le(crc, crc32c(&out[start], out.size() - start));
  out.append(crc, sizeof crc);
  if (last) {
    place_.end = file_offset_ + out.size();
    place_.records = counts_.take();
    ended_.push_back(std::move(place_));
    place_ = ChunkPlace{};
    placed_ = false;
  }
}

std::vector<std::pair<std::uint16_t, std::uint64_t>> ChannelCounts::take() {
  std::sort(touched_.begin(), touched_.end());
  std::vector<std::pair<std::uint16_t, std::uint64_t>> counted;
  counted.reserve(touched_.size());
  for (const std::uint16_t channel : touched_) {
    counted.emplace_back(channel, counts_[channel]);
    counts_[channel] = 0;
  }
  touched_.clear();
  return counted;
}

void ChannelCounts::clear() {
  for (const std::uint16_t channel : touched_) counts_[channel] = 0;
  touched_.clear();
}

void ChunkDecoder::Bytes::discard_front(std::size_t count) {
  if (count == 0) return;
  std::memmove(data_.get(), data_.get() + count, size_ - count);
  size_ -= count;
}

char* ChunkDecoder::Bytes::room(std::size_t more) {
  if (capacity_ - size_ < more) {
    const std::size_t capacity = std::max(capacity_ * 2, size_ + more);
    std::unique_ptr<char[]> bigger(new char[capacity]);
    if (size_ != 0) std::memcpy(bigger.get(), data_.get(), size_);
    data_ = std::move(bigger);
    capacity_ = capacity;
  }
  return data_.get() + size_;
}

struct ChunkDecoder::Zstd {
  ZSTD_DCtx* context = ZSTD_createDCtx();
  ~Zstd() { ZSTD_freeDCtx(context); }
};

ChunkDecoder::ChunkDecoder() : zstd_(std::make_unique<Zstd>()) {
  if (zstd_->context == nullptr) throw std::bad_alloc();
}

ChunkDecoder::~ChunkDecoder() = default;

void ChunkDecoder::reset() {
  ZSTD_DCtx_reset(zstd_->context, ZSTD_reset_session_only);
  decoded_.clear();
  at_ = 0;
  open_ = false;
  total_ = 0;
  crc_ = 0;
  previous_t_ = 0;
  place_ = ChunkPlace{};
  counts_.clear();
  finished_ = false;
}

std::optional<std::string> ChunkDecoder::feed(std::uint64_t offset, std::uint64_t end,
                                              std::string_view payload, bool last) {
  if (!open_) {
    open_ = true;
    // A chunk's first entry counts its time from 0, however the one before
    // ended: its last part may have held no entry (a flush sent the others
    // ahead), so next() never saw the chunk's end.
    previous_t_ = 0;
    chunk_offset_ = offset;
    place_ = ChunkPlace{offset, 0, {}};
    counts_.clear();
    finished_ = false;
  }
  if (last && payload.size() < chunk_trailer_size) {
    return "its last part is shorter than its trailer";
  }
  const std::string_view frame =
      last ? payload.substr(0, payload.size() - chunk_trailer_size) : payload;
  // What was handed out goes: the buffer holds at most a chunk.
  decoded_.discard_front(at_);
  at_ = 0;
  ZSTD_inBuffer in{frame.data(), frame.size(), 0};
  constexpr std::size_t block = 1 << 16;
  while (in.pos < in.size || last) {
    // zstd decodes into the buffer itself: one copy of the bytes fewer.
    ZSTD_outBuffer out{decoded_.room(block), block, 0};
    const std::size_t left = ZSTD_decompressStream(zstd_->context, &out, &in);
    if (ZSTD_isError(left)) return std::string("its zstd data is corrupt (") +
                                   ZSTD_getErrorName(left) + ")";
    total_ += out.pos;
    if (total_ > max_chunk_decoded) {
      return "it decodes to more than the " + std::to_string(max_chunk_decoded >> 20) +
             " MiB a chunk may hold";
    }
    crc_ = crc32c(static_cast<const char*>(out.dst), out.pos, crc_);
    decoded_.grow(out.pos);
    if (left == 0) {  // the frame ended
      if (!last || in.pos < in.size) return "its zstd frame ends before its last part";
      break;
    }
    if (out.pos < block && in.pos == in.size) {
      if (last) return "its zstd frame does not end with its last part";
      break;
    }
  }
  if (last) {
    const std::uint32_t length = get_u32le(payload.data() + frame.size());
    const std::uint32_t crc = get_u32le(payload.data() + frame.size() + 4);
    if (length != total_) {
      return "it decodes to " + std::to_string(total_) + " bytes, its trailer says " +
             std::to_string(length);
    }
    if (crc != crc_) return "the CRC32C of its decoded bytes does not match its trailer";
    ZSTD_DCtx_reset(zstd_->context, ZSTD_reset_session_only);
    open_ = false;
    total_ = 0;
    crc_ = 0;
    place_.end = end;
    finished_ = true;
  }
  return std::nullopt;
}

std::optional<ChunkPlace> ChunkDecoder::take_finished() {
  if (!finished_ || at_ < decoded_.size()) return std::nullopt;
  finished_ = false;
  place_.records = counts_.take();
  return std::exchange(place_, ChunkPlace{});
}

bool ChunkDecoder::next(Record& record, std::string* problem,
                        std::optional<std::uint16_t> only) {
  const std::string_view bytes = decoded_.view();
  for (;;) {
    std::size_t at = at_;
    if (at >= bytes.size()) return false;
    const auto kind = static_cast<std::uint8_t>(bytes[at++]);
    std::uint64_t channel = 0;
    std::uint64_t delta = 0;
    std::uint64_t length = 0;
    if (!get_varint(bytes, at, channel) || !get_varint(bytes, at, delta) ||
        !get_varint(bytes, at, length) || bytes.size() - at < length) {
      // An entry not whole yet is whole once its chunk's next part came.
      if (!open_ && problem) *problem = "an entry is cut short at its chunk's end";
      return false;
    }
    if (channel > 0xFFFF) {
      if (problem) *problem = "an entry names channel " + std::to_string(channel);
      return false;
    }
    // The first entry of a chunk counts from 0 (previous_t_ reset below).
    const std::uint64_t t = previous_t_ + static_cast<std::uint64_t>(unzigzag(delta));
    at_ = at + static_cast<std::size_t>(length);
    previous_t_ = t;
    if (!open_ && at_ >= decoded_.size()) previous_t_ = 0;  // the chunk is done
    counts_.add(static_cast<std::uint16_t>(channel));
    if (only && channel != *only) continue;
    record.kind = static_cast<RecordKind>(kind);
    record.channel = static_cast<std::uint16_t>(channel);
    record.t_ns = t;
    record.data.assign(bytes.data() + at, static_cast<std::size_t>(length));
    return true;
  }
}

}  // namespace wiretape::detail
