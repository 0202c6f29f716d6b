// Reading sessions: .wtape files (specified in docs/session-format.md) and,
// through session/flexiport.cpp, flexiport's two-file logs.
#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>
#include <utility>

#include "posix/file_checks.hpp"
#include "posix/syscalls.hpp"
#include "session/buffered_file.hpp"
#include "session/chunks.hpp"
#include "session/flexiport.hpp"
#include "session/format.hpp"
#include "session/header.hpp"
#include "session/reader.hpp"
#include "session/record_kinds.hpp"
#include "session/session_index.hpp"
#include "util/json.hpp"
#include "wiretape/session.hpp"

namespace wiretape {

namespace detail {

std::optional<std::string> record_content_problem(RecordKind kind, std::uint64_t t_ns,
                                          std::string_view payload) {
  if (t_ns > max_record_t_ns) {
    return "its time t_ns " + std::to_string(t_ns) + " is beyond the format's bound of " +
           std::to_string(max_record_t_ns) + " ns (about 136 years)";
  }
  const RecordKindSpec* spec = find_record_kind(kind);
  if (spec == nullptr || !spec->is_event || payload.empty()) return std::nullopt;
  json::Value root;
  try {
    root = json::parse(payload);
  } catch (const json::ParseError& e) {
    return "its " + std::string(spec->name) + " event payload is not valid JSON (" +
           e.what() + " of the payload)";
  }
  if (!root.is_object()) {
    return "its " + std::string(spec->name) + " event payload is not a JSON object";
  }
  return std::nullopt;
}

namespace {

std::string hex32(std::uint32_t value) {
  char text[16];
  std::snprintf(text, sizeof text, "0x%08x", value);
  return text;
}

class WtapeSource final : public RecordSource {
 public:
  WtapeSource(const std::string& path, SessionHeader& header, Streams streams,
              std::optional<std::uint16_t> channel, UnlistedRecordSink on_unlisted,
              RecordPlaceSink on_place)
      : file_(path, streams), channel_(channel), on_unlisted_(std::move(on_unlisted)),
        on_place_(std::move(on_place)) {
    read_header(header);
    channel_count_ = header.channels.empty() ? 1 : header.channels.size();
    first_record_ = file_.position();
    // One channel of several: its spans, if the file's index describes it;
    // every record otherwise (a file still being written has none yet).
    if (channel_ && channel_count_ > 1 && !file_.is_stream()) {
      spans_ = find_channel_spans(file_.fd(), file_.size(), first_record_, channel_count_,
                                  *channel_, nullptr);
    }
  }

  bool next(Record& record) override { return next_record(record, nullptr); }
  bool next(Record& record, PayloadView& view) override {
    if (next_record(record, &view)) return true;
    view = PayloadView{};  // no bytes of a damaged record handed out
    return false;
  }

  void rewind() override {
    file_.seek(first_record_);
    damage_.reset();
    unfinished_.reset();
    records_ = 0;
    if (chunk_) chunk_->reset();
    if (spans_) {
      spans_->rewind();
      span_ = IndexSpan{};
      file_.limit_read_ahead(0);
    }
  }

  const std::optional<SessionError>& damage() const override { return damage_; }
  const std::optional<SessionError>& unfinished() const override { return unfinished_; }

 private:
  // With `view`, large payloads come as views into the read buffer.
  bool next_record(Record& record, PayloadView* view) {
    for (;;) {
      if (view) *view = PayloadView{};
      if (damage_ || unfinished_) return false;
      if (chunk_) {
        std::string problem;
        // A reader of one channel passes over the others' entries; verify
        // (which is told of unlisted channels) sees every entry.
        const std::optional<std::uint16_t> only =
            on_unlisted_ ? std::nullopt : channel_;
        if (chunk_->next(record, &problem, only)) {
          if (!wanted(record.channel, static_cast<std::uint8_t>(record.kind),
                      chunk_->chunk_offset())) {
            continue;
          }
          if (const auto unusable = record_content_problem(record.kind, record.t_ns, record.data)) {
            return stop(chunk_->chunk_offset(), "a record of the chunk at byte " +
                                                    std::to_string(chunk_->chunk_offset()) +
                                                    " is unusable: " + *unusable);
          }
          ++records_;
          return true;
        }
        if (!problem.empty()) {
          return stop(chunk_->chunk_offset(), "the chunk at byte " +
                                                  std::to_string(chunk_->chunk_offset()) +
                                                  " is damaged: " + problem);
        }
        if (on_place_) {
          if (const auto place = chunk_->take_finished()) {
            for (const auto& [channel, records] : place->records) {
              on_place_(
                  RecordPlace{place->begin, place->end, channel, chunk_record_code, records});
            }
          }
        }
      }
      if (spans_ && !enter_span()) return false;
      const std::uint64_t offset = file_.position();
      char head[record_header_size];
      if (file_.remaining() == 0) {
        if (chunk_ && chunk_->open()) {
          if (writer_holds_file()) return stop_unfinished(offset);
          // What a recorder killed inside a chunk leaves: its flushed parts
          // were read; the records after its last flush are lost.
          return stop(chunk_->chunk_offset(),
                      "the chunk at byte " + std::to_string(chunk_->chunk_offset()) +
                          " has no last part (the recording stopped inside it)");
        }
        return false;
      }
      if (!file_.read(head, sizeof head)) {
        if (!file_.is_stream() && writer_holds_file()) return stop_unfinished(offset);
        // What is left now: a stream's bytes are known only once they came.
        return stop(offset, "truncated record at byte " + std::to_string(offset) +
                                ": a record header needs 16 bytes, the file ends " +
                                std::to_string(file_.remaining()) + " bytes later");
      }
      const std::uint32_t length = get_u32le(head);
      const auto claims_too_much = [&](std::uint64_t held) {
        return stop(offset, "record at byte " + std::to_string(offset) +
                                " claims a payload of " + std::to_string(length) +
                                " bytes, but the file holds only " + std::to_string(held) +
                                " more bytes (truncated, or a corrupt length)");
      };
      // A stream's length is checked as its bytes arrive (read_into).
      if (!file_.is_stream() &&
          static_cast<std::uint64_t>(length) + crc_size > file_.remaining()) {
        if (writer_holds_file()) return stop_unfinished(offset);
        return claims_too_much(file_.remaining());
      }
      std::uint32_t crc = crc32c(head, sizeof head);
      const char* payload = nullptr;
      if (view && views_pin_own_records() && length >= min_view_payload &&
          length <= BufferedFile::max_view_size()) {
        if (!file_.read_view(length, *view)) {
          return stop(offset, "truncated record at byte " + std::to_string(offset));
        }
        record.data.clear();
        payload = view->bytes.data();
      } else {
        if (!file_.read_into(record.data, length)) {
          if (file_.is_stream()) return claims_too_much(record.data.size());
          return stop(offset, "truncated record at byte " + std::to_string(offset));
        }
        payload = record.data.data();
      }
      crc = crc32c(payload, length, crc);
      char stored_bytes[crc_size];
      if (!file_.read(stored_bytes, crc_size)) {
        return stop(offset, "truncated record at byte " + std::to_string(offset));
      }
      const std::uint32_t stored = get_u32le(stored_bytes);
      if (stored != crc) {
        return stop(offset, "record at byte " + std::to_string(offset) +
                                " is corrupt: CRC32C " + hex32(crc) +
                                " does not match the stored " + hex32(stored));
      }
      // A channel the header does not list (a newer writer's), a kind not
      // known or a channel not asked for: skipped.
      const std::uint16_t channel = get_u16le(head + 6);
      const auto kind_byte = static_cast<std::uint8_t>(head[4]);
      if (on_place_) on_place_(RecordPlace{offset, file_.position(), channel, kind_byte});
      if (kind_byte == chunk_record_code) {
        if (!chunk_) chunk_ = std::make_unique<ChunkDecoder>();
        const bool last = (static_cast<std::uint8_t>(head[5]) & chunk_last_part) != 0;
        if (const auto problem = chunk_->feed(offset, file_.position(),
                                                  std::string_view(payload, length), last)) {
          return stop(offset, "the chunk at byte " + std::to_string(chunk_->chunk_offset()) +
                                  " is damaged in its part at byte " + std::to_string(offset) +
                                  ": " + *problem);
        }
        continue;
      }
      if (chunk_ && chunk_->open()) {
        return stop(offset, "record at byte " + std::to_string(offset) +
                                " lies inside the unfinished chunk at byte " +
                                std::to_string(chunk_->chunk_offset()));
      }
      if (!wanted(channel, kind_byte, offset)) continue;
      record.channel = channel;
      record.kind = static_cast<RecordKind>(kind_byte);
      record.t_ns = get_u64le(head + 8);
      if (const auto problem =
              record_content_problem(record.kind, record.t_ns,
                                     std::string_view(payload, length))) {
        if (view) *view = PayloadView{};
        return stop(offset, "record at byte " + std::to_string(offset) +
                                " is intact (its CRC matches) but unusable: " + *problem);
      }
      ++records_;
      return true;
    }
  }

  // A channel the header does not list (a newer writer's, reported), a kind
  // not known or a channel not asked for: skipped.
  bool wanted(std::uint16_t channel, std::uint8_t kind_byte, std::uint64_t offset) {
    if (channel >= channel_count_) {
      if (on_unlisted_) on_unlisted_(UnlistedRecord{offset, channel});
      return false;
    }
    if (find_record_kind(static_cast<RecordKind>(kind_byte)) == nullptr) return false;
    return !channel_ || channel == *channel_;
  }

  // A view pins its read buffer. Reading one channel of several without an
  // index, a buffer holds mostly other channels' records: a view would pin
  // a whole buffer for the few bytes of this channel's, so the look-ahead's
  // memory would grow with the number of channels, and a copy costs less.
  // Through the index, the reads hold this channel's spans.
  bool views_pin_own_records() const {
    if (file_.is_stream()) return false;
    return !channel_ || channel_count_ == 1 || spans_.has_value();
  }

  // Moves to the next span of the channel when the reader is past the
  // current one; false after the last.
  bool enter_span() {
    while (file_.position() >= span_.end) {
      if (!spans_->next(span_)) return false;
      if (span_.begin > file_.position() && !file_.skip(span_.begin - file_.position())) {
        return false;  // the file is shorter than its index says: not a span of it
      }
      file_.limit_read_ahead(span_.end);
    }
    return true;
  }

  // Whether a writer holds the file (SessionWriter locks it, flock, until
  // it closes): the end of the file is then where the writer is, not
  // damage. A writer that was killed holds nothing, and what it left is
  // read as damage.
  bool writer_holds_file() const {
    if (file_.is_stream()) return false;
    if (sys::flock(file_.fd(), LOCK_SH | LOCK_NB) == 0) {
      (void)sys::flock(file_.fd(), LOCK_UN);
      return false;
    }
    return errno == EWOULDBLOCK;
  }

  // The end of a file still being written, at `offset` (a record not whole
  // yet), or inside the open chunk.
  bool stop_unfinished(std::uint64_t offset) {
    const bool in_chunk = chunk_ && chunk_->open();
    const std::uint64_t at = in_chunk ? chunk_->chunk_offset() : offset;
    unfinished_.emplace(file_.path() + ": the file is still being written: it ends in an "
                            "unfinished " + (in_chunk ? "chunk" : "record") + " at byte " +
                            std::to_string(at) + "; the " + std::to_string(records_) +
                            " records before it were read",
                        at);
    return false;
  }

  bool stop(std::uint64_t offset, const std::string& what) {
    damage_.emplace(file_.path() + ": " + what + "; reading stopped there, the " +
                        std::to_string(records_) + " records before it are intact",
                    offset);
    return false;
  }

  [[noreturn]] void fail(std::uint64_t offset, const std::string& what) {
    throw SessionError(file_.path() + ": " + what, offset);
  }

  void read_header(SessionHeader& header) {
    const std::uint64_t size = file_.remaining();
    if (size == 0) fail(0, "empty file (0 bytes): not a wiretape session");
    char fixed[file_header_fixed_size];
    const bool complete = file_.read(fixed, sizeof fixed);
    // Counted after the read: a stream's bytes are known once they came.
    const std::size_t have =
        complete ? sizeof fixed : static_cast<std::size_t>(file_.remaining());
    if (!complete) file_.read(fixed, have);
    const std::size_t magic_bytes = std::min(have, sizeof session_magic);
    if (std::memcmp(fixed, session_magic, magic_bytes) != 0) {
      fail(0, "not a wiretape session file (wrong magic number at byte 0)");
    }
    if (!complete) {
      fail(have, "truncated header: the file ends at byte " +
                     std::to_string(have) + ", inside the 16-byte file header");
    }
    header.version_major = get_u16le(fixed + 8);
    header.version_minor = get_u16le(fixed + 10);
    if (header.version_major > compressed_version_major) {
      fail(8, "written in session format " + std::to_string(header.version_major) +
                  "." + std::to_string(header.version_minor) +
                  ", newer than this reader's " +
                  std::to_string(compressed_version_major) + "." +
                  std::to_string(compressed_version_minor) +
                  ": upgrade wiretape to read it");
    }
    if (header.version_major == 0) fail(8, "invalid format version 0");
    const std::uint32_t json_length = get_u32le(fixed + 12);
    // A stream's length is checked as its bytes arrive (read_into), within
    // max_header_json.
    if (json_length > max_header_json ||
        (!file_.is_stream() &&
         static_cast<std::uint64_t>(json_length) + crc_size > file_.remaining())) {
      fail(12, "truncated or corrupt header: its metadata claims " +
                   std::to_string(json_length) + " bytes, the file holds " +
                   std::to_string(file_.remaining()) + " after byte 16");
    }
    std::string json;
    char stored_bytes[crc_size];
    if (!file_.read_into(json, json_length) || !file_.read(stored_bytes, crc_size)) {
      fail(16, "truncated header");
    }
    std::uint32_t crc = crc32c(fixed, sizeof fixed);
    crc = crc32c(json.data(), json.size(), crc);
    if (crc != get_u32le(stored_bytes)) {
      fail(0, "the file header (bytes 0.." +
                  std::to_string(file_header_fixed_size + json_length + crc_size) +
                  ") is corrupt: CRC32C " + hex32(crc) + " does not match the stored " +
                  hex32(get_u32le(stored_bytes)));
    }
    parse_header_json(json, file_.path(), file_header_fixed_size, header);
  }

  BufferedFile file_;
  std::optional<std::uint16_t> channel_;  // std::nullopt: every channel
  UnlistedRecordSink on_unlisted_;
  RecordPlaceSink on_place_;
  std::size_t channel_count_ = 1;
  std::uint64_t first_record_ = 0;
  std::optional<ChannelSpans> spans_;  // the channel's, from the file's index
  std::unique_ptr<ChunkDecoder> chunk_;  // once a file shows it has chunks (2.0)
  IndexSpan span_;                     // the one being read
  std::uint64_t records_ = 0;
  std::optional<SessionError> damage_;
  std::optional<SessionError> unfinished_;
};

// False also when `path` cannot be opened: opening it as a .wtape file then
// reports why. A stream is not looked into (what is read from it is gone, and
// closing it could cost its writer its reader): it is read as a .wtape file.
bool starts_with_magic(const std::string& path, Streams streams) {
  if (streams == Streams::read && is_stream(path)) return true;
  try {
    const InputFile file(path);
    char head[sizeof session_magic] = {};
    ssize_t n = 0;
    do {
      n = sys::read(file.fd(), head, sizeof head);
    } while (n < 0 && errno == EINTR);
    return n == static_cast<ssize_t>(sizeof head) &&
           std::memcmp(head, session_magic, sizeof head) == 0;
  } catch (const PortError&) {
    return false;
  }
}

}  // namespace

std::unique_ptr<RecordSource> open_session_source(const std::string& path,
                                                  SessionHeader& header, Streams streams,
                                                  std::optional<std::uint16_t> channel,
                                                  UnlistedRecordSink on_unlisted,
                                                  RecordPlaceSink on_place) {
  if (!starts_with_magic(path, streams)) {
    // A flexiport log is one port: channel 0.
    if (auto prefix = flexiport_prefix(path)) {
      if (channel.value_or(0) != 0) {
        throw SessionError(path + ": a flexiport log has one channel (0), not " +
                               std::to_string(*channel),
                           0);
      }
      return open_flexiport(*prefix, header);
    }
  }
  return std::make_unique<WtapeSource>(path, header, streams, channel,
                                       std::move(on_unlisted), std::move(on_place));
}

}  // namespace detail

struct SessionReader::Impl {
  std::string path;
  SessionHeader header;
  std::unique_ptr<detail::RecordSource> source;
};

SessionReader::SessionReader(const std::string& path, std::optional<std::uint16_t> channel)
    : impl_(std::make_unique<Impl>()) {
  impl_->path = path;
  // The commands that read sessions read pipes and FIFOs too (DESIGN §6).
  impl_->source =
      detail::open_session_source(path, impl_->header, detail::Streams::read, channel);
}

SessionReader::~SessionReader() = default;
SessionReader::SessionReader(SessionReader&&) noexcept = default;
SessionReader& SessionReader::operator=(SessionReader&&) noexcept = default;

const SessionHeader& SessionReader::header() const { return impl_->header; }
bool SessionReader::next(Record& record) { return impl_->source->next(record); }
const std::optional<SessionError>& SessionReader::damage() const {
  return impl_->source->damage();
}
const std::optional<SessionError>& SessionReader::unfinished() const {
  return impl_->source->unfinished();
}
void SessionReader::rewind() { impl_->source->rewind(); }
const std::string& SessionReader::path() const { return impl_->path; }

}  // namespace wiretape
