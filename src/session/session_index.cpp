#include "session/session_index.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "posix/file_checks.hpp"
#include "posix/syscalls.hpp"
#include "session/chunks.hpp"
#include "wiretape/errors.hpp"
#include "session/format.hpp"
#include "wiretape/session.hpp"

namespace wiretape::detail {

namespace {

// channel count (u16), reserved (u16)
constexpr std::size_t index_head_size = 4;
// per channel: records (u64), spans (u64), bytes of its encoded spans (u32)
constexpr std::size_t index_directory_entry = 20;
// An index larger than this is not read (a corrupt trailer could claim any
// length): the reader scans instead.
constexpr std::uint64_t max_index_payload = 1ull << 30;

bool read_at(int fd, std::uint64_t offset, void* out, std::size_t size) {
  auto* dst = static_cast<char*>(out);
  std::size_t done = 0;
  while (done < size) {
    const ssize_t n = sys::pread(fd, dst + done, size - done, static_cast<off_t>(offset + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    done += static_cast<std::size_t>(n);
  }
  return true;
}

std::optional<IndexFound> none(std::string* why_not, std::string why) {
  if (why_not) *why_not = std::move(why);
  return std::nullopt;
}

}  // namespace

bool ChannelSpans::refill() {
  constexpr std::size_t block = 4096;
  buffer_.erase(0, at_);
  base_ += at_;
  at_ = 0;
  const std::uint64_t read = base_ + buffer_.size();
  const auto want = static_cast<std::size_t>(std::min<std::uint64_t>(block, size_ - read));
  if (want == 0) return false;
  const std::size_t kept = buffer_.size();
  buffer_.resize(kept + want);
  if (!read_at(fd_, offset_ + read, &buffer_[kept], want)) {
    buffer_.resize(kept);
    return false;
  }
  return true;
}

bool ChannelSpans::next(IndexSpan& span) {
  // Two varints take at most 20 bytes: have that many at hand, or the rest.
  constexpr std::size_t most = 20;
  if (fd_ >= 0 && buffer_.size() - at_ < most && base_ + buffer_.size() < size_) refill();
  if (at_ >= buffer_.size()) return false;
  std::uint64_t gap = 0;
  std::uint64_t length = 0;
  if (!get_varint(buffer_, at_, gap) || !get_varint(buffer_, at_, length)) {
    at_ = buffer_.size();
    return false;
  }
  span.begin = previous_end_ + gap;
  span.end = span.begin + length;
  previous_end_ = span.end;
  return true;
}

void ChannelSpans::rewind() {
  previous_end_ = 0;
  at_ = 0;
  if (fd_ >= 0) {
    buffer_.clear();
    base_ = 0;
  }
}

void SessionIndexBuilder::add(std::uint64_t offset, std::uint64_t end, std::uint16_t channel,
                              std::uint64_t records) {
  if (channel >= channels_.size()) channels_.resize(static_cast<std::size_t>(channel) + 1);
  Channel& state = channels_[channel];
  state.records += records;
  if (state.open && offset >= state.open->end &&
      offset - state.open->end <= index_span_merge_gap) {
    state.open->end = end;
    return;
  }
  close_span(state);
  state.open = IndexSpan{offset, end};
}

void SessionIndexBuilder::close_span(Channel& channel) {
  if (!channel.open) return;
  put_varint(channel.encoded, channel.open->begin - channel.previous_end);
  put_varint(channel.encoded, channel.open->end - channel.open->begin);
  channel.previous_end = channel.open->end;
  ++channel.spans;
  channel.open.reset();
}

std::string SessionIndexBuilder::record_bytes(std::uint64_t at,
                                              std::size_t channel_count) const {
  std::vector<Channel> channels = channels_;
  channels.resize(channel_count);  // records of unlisted channels are not indexed
  std::string payload(index_head_size, '\0');
  put_u16le(&payload[0], static_cast<std::uint16_t>(channel_count));
  for (Channel& channel : channels) {
    close_span(channel);
    char entry[index_directory_entry];
    put_u64le(entry, channel.records);
    put_u64le(entry + 8, channel.spans);
    put_u32le(entry + 16, static_cast<std::uint32_t>(channel.encoded.size()));
    payload.append(entry, sizeof entry);
  }
  for (const Channel& channel : channels) payload += channel.encoded;
  char trailer[index_trailer_size];
  put_u64le(trailer, at);
  std::memcpy(trailer + 8, index_trailer_mark, sizeof index_trailer_mark);
  payload.append(trailer, sizeof trailer);

  std::string record(record_header_size, '\0');
  put_u32le(&record[0], static_cast<std::uint32_t>(payload.size()));
  record[4] = static_cast<char>(index_record_code);
  record += payload;
  char crc[crc_size];
  put_u32le(crc, crc32c(record.data(), record.size()));
  record.append(crc, sizeof crc);
  return record;
}

namespace {

// Whether `spans` holds `count` spans, in order, between `first_record` and
// the index at `offset`.
bool spans_lie_within(ChannelSpans& spans, std::uint64_t count, std::uint64_t first_record,
                      std::uint64_t offset) {
  IndexSpan span;
  std::uint64_t previous_end = 0;
  std::uint64_t seen = 0;
  while (spans.next(span)) {
    if (span.begin < previous_end || span.begin < first_record || span.end <= span.begin ||
        span.begin > offset || span.end > offset) {
      return false;
    }
    previous_end = span.end;
    ++seen;
  }
  return seen == count;
}

// The index at the end of the file, checked; of its spans, those of
// `channel` are kept (in `spans`), or with std::nullopt the whole payload
// (in `payload`). Memory: the directory and what is kept; the rest is read
// through a small buffer for its CRC.
std::optional<IndexFound> read_index(int fd, std::uint64_t file_size, std::uint64_t first_record,
                                     std::size_t channel_count,
                                     std::optional<std::uint16_t> channel, std::string* why_not) {
  const std::uint64_t smallest =
      record_header_size + index_head_size + index_trailer_size + crc_size;
  if (file_size < first_record + smallest) return none(why_not, "no index");
  char tail[index_trailer_size + crc_size];
  if (!read_at(fd, file_size - sizeof tail, tail, sizeof tail) ||
      std::memcmp(tail + 8, index_trailer_mark, sizeof index_trailer_mark) != 0) {
    return none(why_not, "no index");
  }
  const std::uint64_t offset = get_u64le(tail);
  const std::string at_offset = "the index at byte " + std::to_string(offset);
  if (offset < first_record || offset > file_size - smallest) {
    return none(why_not, "the index at the end of the file names offset " +
                             std::to_string(offset) + ", outside the file's records");
  }
  const std::uint64_t length = file_size - offset - record_header_size - crc_size;
  char head[record_header_size];
  if (!read_at(fd, offset, head, sizeof head) ||
      static_cast<std::uint8_t>(head[4]) != index_record_code || get_u32le(head) != length) {
    return none(why_not, "the index the end of the file names at byte " +
                             std::to_string(offset) + " is not an index record ending there");
  }
  if (length > max_index_payload) {
    return none(why_not, at_offset + " claims " + std::to_string(length) +
                             " bytes, more than a reader takes");
  }
  const std::uint64_t directory_size = index_head_size + channel_count * index_directory_entry;
  if (directory_size + index_trailer_size > length) {
    return none(why_not, at_offset + " is too short for the header's " +
                             std::to_string(channel_count) + " channels");
  }
  std::string directory(static_cast<std::size_t>(directory_size), '\0');
  if (!read_at(fd, offset + record_header_size, &directory[0], directory.size())) {
    return none(why_not, at_offset + " cannot be read");
  }
  std::uint32_t crc = crc32c(head, sizeof head);
  crc = crc32c(directory.data(), directory.size(), crc);
  IndexFound found;
  found.offset = offset;
  found.channel_count = get_u16le(directory.data());
  if (found.channel_count != channel_count) {
    return none(why_not, at_offset + " lists " + std::to_string(found.channel_count) +
                             " channels, the header " + std::to_string(channel_count));
  }
  // Where each channel's spans are in the payload.
  std::vector<std::uint64_t> starts;
  std::uint64_t spans_end = directory_size;
  for (std::size_t id = 0; id < channel_count; ++id) {
    starts.push_back(spans_end);
    spans_end += get_u32le(directory.data() + index_head_size + id * index_directory_entry + 16);
  }
  if (spans_end != length - index_trailer_size) {
    return none(why_not, at_offset + " holds bytes its directory does not account for");
  }
  const bool one = channel && *channel < channel_count;
  const std::uint64_t keep_begin = one ? starts[*channel] : directory_size;
  const std::uint64_t keep_end =
      one ? (*channel + 1u < channel_count ? starts[*channel + 1u] : spans_end) : length;
  std::string kept;
  // A reader of one channel reads its spans from the file as it goes.
  const bool keep_bytes = !one;
  char block[1 << 16];
  for (std::uint64_t position = directory_size; position < length;) {
    const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(sizeof block, length - position));
    if (!read_at(fd, offset + record_header_size + position, block, n)) {
      return none(why_not, at_offset + " cannot be read");
    }
    crc = crc32c(block, n, crc);
    const std::uint64_t from = std::max(position, keep_begin);
    const std::uint64_t to = std::min<std::uint64_t>(position + n, keep_end);
    if (keep_bytes && from < to) {
      kept.append(block + (from - position), static_cast<std::size_t>(to - from));
    }
    position += n;
  }
  if (crc != get_u32le(tail + index_trailer_size)) {
    return none(why_not, at_offset + " is corrupt (CRC32C)");
  }
  const auto stale = [&](std::size_t id) {
    return none(why_not, at_offset + " does not describe the file: channel " +
                             std::to_string(id) + "'s spans lie outside its records");
  };
  const auto entry = [&](std::size_t id) {
    return directory.data() + index_head_size + id * index_directory_entry;
  };
  if (channel) {
    if (!one) return found;  // a channel the file lacks: none of its records
    ChannelSpans spans(fd, offset + record_header_size + keep_begin, keep_end - keep_begin,
                       get_u64le(entry(*channel)));
    if (!spans_lie_within(spans, get_u64le(entry(*channel) + 8), first_record, offset)) {
      return stale(*channel);
    }
    spans.rewind();
    found.spans = std::move(spans);
    return found;
  }
  found.payload = directory + kept;
  for (std::size_t id = 0; id < channel_count; ++id) {
    ChannelSpans spans(found.payload.substr(
                           static_cast<std::size_t>(starts[id]),
                           static_cast<std::size_t>(
                               (id + 1 < channel_count ? starts[id + 1] : spans_end) - starts[id])),
                       0);
    if (!spans_lie_within(spans, get_u64le(entry(id) + 8), first_record, offset)) {
      return stale(id);
    }
  }
  return found;
}

}  // namespace

std::optional<IndexFound> find_session_index(int fd, std::uint64_t file_size,
                                             std::uint64_t first_record,
                                             std::size_t channel_count, std::string* why_not) {
  return read_index(fd, file_size, first_record, channel_count, std::nullopt, why_not);
}

std::optional<ChannelSpans> find_channel_spans(int fd, std::uint64_t file_size,
                                               std::uint64_t first_record,
                                               std::size_t channel_count, std::uint16_t channel,
                                               std::string* why_not) {
  auto found = read_index(fd, file_size, first_record, channel_count, channel, why_not);
  if (!found) return std::nullopt;
  return std::move(found->spans);
}

ChannelSpans channel_spans(const IndexFound& index, std::uint16_t channel) {
  if (channel >= index.channel_count) return ChannelSpans();  // none of its records
  const std::string_view payload = index.payload;
  std::size_t at = index_head_size + index.channel_count * index_directory_entry;
  for (std::uint16_t id = 0; id < channel; ++id) {
    at += get_u32le(payload.data() + index_head_size + id * index_directory_entry + 16);
  }
  const char* entry = payload.data() + index_head_size + channel * index_directory_entry;
  return ChannelSpans(std::string(payload.substr(at, get_u32le(entry + 16))), get_u64le(entry));
}

std::string_view to_string(IndexState state) {
  switch (state) {
    case IndexState::not_needed: return "not needed";
    case IndexState::current: return "current";
    case IndexState::absent: return "absent";
    case IndexState::stale: return "stale";
    case IndexState::unchecked: return "unchecked";
  }
  return "unchecked";
}

RecordPlaceSink IndexCheck::sink() {
  return [this](const RecordPlace& place) {
    // Indexes are the file's structure, not records it indexes; a chunk is
    // indexed as a whole, once its records are known, not by its parts.
    if (place.kind_code == index_record_code) return;
    if (place.kind_code == chunk_record_code) {
      if (place.records != 0) {
        scanned_.add(place.offset, place.end, place.channel, place.records);
      }
      return;
    }
    scanned_.add(place.offset, place.end, place.channel);
  };
}

IndexStatus IndexCheck::status(const std::string& path, std::size_t channel_count,
                               bool damaged) const {
  if (channel_count < 2) return {IndexState::not_needed, ""};
  if (damaged) return {IndexState::unchecked, "the file is damaged"};
  const InputFile file(path);
  struct stat info {};
  if (sys::fstat(file.fd(), &info) != 0) return {IndexState::unchecked, "cannot stat the file"};
  std::string why;
  const auto found = find_session_index(file.fd(), static_cast<std::uint64_t>(info.st_size),
                                        file_header_fixed_size, channel_count, &why);
  if (!found) {
    return {why == "no index" ? IndexState::absent : IndexState::stale, why};
  }
  const std::string expected = scanned_.record_bytes(found->offset, channel_count);
  const std::string_view payload = std::string_view(expected).substr(
      record_header_size, expected.size() - record_header_size - crc_size);
  if (payload != found->payload) {
    return {IndexState::stale, "the index at byte " + std::to_string(found->offset) +
                                   " does not match the records before it"};
  }
  return {IndexState::current, "at byte " + std::to_string(found->offset)};
}

IndexStatus repair_session_index(const std::string& path) {
  SessionHeader header;
  IndexCheck check;
  const auto source =
      open_session_source(path, header, Streams::refused, std::nullopt, {}, check.sink());
  Record record;
  while (source->next(record)) {
  }
  if (source->unfinished()) {
    throw SessionError(std::string(source->unfinished()->what()) +
                           "; no index appended (its writer appends it when it closes)",
                       source->unfinished()->offset());
  }
  if (source->damage()) {
    throw SessionError(std::string(source->damage()->what()) +
                           "; no index appended (convert the file to keep what is intact)",
                       source->damage()->offset());
  }
  const std::size_t channels = header.channels.size();
  const IndexStatus status = check.status(path, channels, false);
  if (status.state != IndexState::absent && status.state != IndexState::stale) return status;
  const int fd = sys::open(path.c_str(), O_WRONLY | O_APPEND | O_CLOEXEC);
  if (fd < 0) throw PortError(errno, path + ": cannot open the session to append its index");
  struct stat info {};
  int error = sys::fstat(fd, &info) == 0 ? 0 : errno;
  const std::uint64_t at = static_cast<std::uint64_t>(info.st_size);
  const std::string bytes = check.record_bytes(at, channels);
  std::size_t written = 0;
  while (error == 0 && written < bytes.size()) {
    const ssize_t n = sys::write(fd, bytes.data() + written, bytes.size() - written);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      error = n < 0 ? errno : ENOSPC;
      break;
    }
    written += static_cast<std::size_t>(n);
  }
  if (error == 0 && sys::fsync(fd) != 0 && errno != EINVAL) error = errno;
  if (error != 0) {
    // A part of an index is no record: cut it off again.
    (void)sys::ftruncate(fd, static_cast<off_t>(at));
    sys::close(fd);
    throw PortError(error, path + ": cannot append the session's index");
  }
  sys::close(fd);
  return {IndexState::current, "appended at byte " + std::to_string(at)};
}

}  // namespace wiretape::detail
