// flexiport's two-file logs (GearBox flexiport, LogWriterPort/LogReaderPort):
// `name.logr` holds what each read call returned, `name.logw` what each write
// call sent, as chunks of
//   new format (from 2008-07): [u32 BE sec][u32 BE usec][u32 BE length][payload]
//   old format:                [i64 LE sec][i64 LE usec][u64 LE length][payload]
// with times counted from the port's open. The format of each file is
// detected from its first chunks; the two files are merged by time, a write
// before a read at equal times.
#include "session/flexiport.hpp"

#include "posix/file_checks.hpp"
#include "posix/syscalls.hpp"

#include <sys/stat.h>

#include <cerrno>
#include <cstdio>
#include <memory>
#include <string>

#include "session/buffered_file.hpp"
#include "session/format.hpp"
#include "session/header.hpp"
#include "util/json.hpp"
#include "wiretape/session.hpp"

namespace wiretape {
namespace detail {
namespace {

const char* format_name(FlexiportFormat format) {
  return format == FlexiportFormat::modern ? "new" : "old";
}

constexpr std::uint64_t usec_per_sec = 1'000'000;
// Later seconds would give a t_ns beyond what a .wtape reader accepts.
constexpr std::uint64_t max_legacy_seconds = max_record_t_ns / 1'000'000'000ull;

struct Chunk {
  std::uint64_t t_ns = 0;
  std::string data;
};

// One chunk header decoded, or the reason it is not valid.
struct ChunkHeader {
  std::uint64_t t_ns = 0;
  std::uint64_t length = 0;
  const char* problem = nullptr;
};

std::size_t header_size(FlexiportFormat format) {
  return format == FlexiportFormat::modern ? 12 : 24;
}

ChunkHeader decode_header(FlexiportFormat format, const char* bytes,
                          std::uint64_t remaining_after_header) {
  ChunkHeader header;
  std::uint64_t seconds = 0;
  std::uint64_t micros = 0;
  if (format == FlexiportFormat::modern) {
    seconds = get_u32be(bytes);
    micros = get_u32be(bytes + 4);
    header.length = get_u32be(bytes + 8);
  } else {
    seconds = get_u64le(bytes);
    micros = get_u64le(bytes + 8);
    header.length = get_u64le(bytes + 16);
    if (seconds > max_legacy_seconds) {
      header.problem = "a negative or absurd time in seconds";
      return header;
    }
  }
  if (micros >= usec_per_sec) {
    header.problem = "a microseconds field of 1,000,000 or more";
    return header;
  }
  if (header.length > remaining_after_header) {
    header.problem = "a length longer than the rest of the file (truncated, or a corrupt length)";
    return header;
  }
  header.t_ns = seconds * 1'000'000'000ull + micros * 1000ull;
  return header;
}

// How many leading chunks of `path` decode in `format` (up to `limit`), and
// whether the walk reached the end of the file cleanly.
struct Probe {
  int valid_chunks = 0;
  bool clean = false;
};

Probe probe(const std::string& path, FlexiportFormat format, int limit) {
  BufferedFile file(path);
  Probe result;
  char bytes[24];
  const std::size_t size = header_size(format);
  while (result.valid_chunks < limit) {
    if (file.remaining() == 0) {
      result.clean = true;
      return result;
    }
    if (!file.read(bytes, size)) return result;
    const ChunkHeader header = decode_header(format, bytes, file.remaining());
    if (header.problem != nullptr || !file.skip(header.length)) return result;
    ++result.valid_chunks;
  }
  result.clean = true;  // every probed chunk decoded
  return result;
}

FlexiportFormat detect_format(const std::string& path) {
  constexpr int limit = 64;
  const Probe modern = probe(path, FlexiportFormat::modern, limit);
  if (modern.clean) return FlexiportFormat::modern;
  const Probe legacy = probe(path, FlexiportFormat::legacy, limit);
  if (legacy.clean) return FlexiportFormat::legacy;
  // Neither decodes cleanly: read in the one that got further, so that the
  // damage is reported where that format breaks.
  return legacy.valid_chunks > modern.valid_chunks ? FlexiportFormat::legacy
                                                   : FlexiportFormat::modern;
}

class ChunkStream {
 public:
  ChunkStream(const std::string& path, const char* direction)
      : file_(path), direction_(direction), format_(detect_format(path)) {}

  FlexiportFormat format() const { return format_; }

  // The next chunk; false at the end or at damage (then damage() is set).
  bool next(Chunk& chunk) {
    if (damage_) return false;
    const std::uint64_t offset = file_.position();
    const std::uint64_t left = file_.remaining();
    if (left == 0) return false;
    char bytes[24];
    const std::size_t size = header_size(format_);
    if (!file_.read(bytes, size)) {
      return stop(offset, "truncated chunk at byte " + std::to_string(offset) +
                              ": its header needs " + std::to_string(size) +
                              " bytes, the file ends " + std::to_string(left) +
                              " bytes later");
    }
    const ChunkHeader header = decode_header(format_, bytes, file_.remaining());
    if (header.problem != nullptr) {
      return stop(offset, std::string("chunk at byte ") + std::to_string(offset) +
                              " is corrupt: " + header.problem);
    }
    if (!file_.read_into(chunk.data, static_cast<std::size_t>(header.length))) {
      return stop(offset, "truncated chunk at byte " + std::to_string(offset));
    }
    chunk.t_ns = header.t_ns;
    ++chunks_;
    return true;
  }

  void rewind() {
    file_.seek(0);
    damage_.reset();
    chunks_ = 0;
  }

  const std::optional<SessionError>& damage() const { return damage_; }

 private:
  bool stop(std::uint64_t offset, const std::string& what) {
    damage_.emplace(file_.path() + " (flexiport " + format_name(format_) + " format, " +
                        direction_ + "): " + what + "; reading stopped there, the " +
                        std::to_string(chunks_) + " chunks before it are intact",
                    offset);
    return false;
  }

  BufferedFile file_;
  const char* direction_;
  FlexiportFormat format_;
  std::uint64_t chunks_ = 0;
  std::optional<SessionError> damage_;
};

class FlexiportSource final : public RecordSource {
 public:
  FlexiportSource(const std::string& prefix)
      : reads_(prefix + "r", "reads"), writes_(prefix + "w", "writes") {
    rewind();
  }

  bool next(Record& record) override {
    if (damage_) return false;
    if (!has_read_ && !has_write_) return false;
    // Equal times: the write goes first (the device answers what it was sent).
    const bool take_write =
        has_write_ && (!has_read_ || write_.t_ns <= read_.t_ns);
    Chunk& chunk = take_write ? write_ : read_;
    record.kind = take_write ? RecordKind::tx : RecordKind::rx;
    record.t_ns = chunk.t_ns;
    record.data.swap(chunk.data);
    if (take_write) {
      has_write_ = advance(writes_, write_);
    } else {
      has_read_ = advance(reads_, read_);
    }
    return true;
  }

  void rewind() override {
    reads_.rewind();
    writes_.rewind();
    damage_.reset();
    has_read_ = advance(reads_, read_);
    has_write_ = advance(writes_, write_);
  }

  const std::optional<SessionError>& damage() const override { return damage_; }

  const ChunkStream& reads() const { return reads_; }
  const ChunkStream& writes() const { return writes_; }

 private:
  // Damage in either file ends the merged stream: what comes after it in the
  // other file cannot be placed in order against records that were lost.
  bool advance(ChunkStream& stream, Chunk& chunk) {
    if (stream.next(chunk)) return true;
    if (stream.damage() && !damage_) {
      damage_ = stream.damage();
      has_read_ = has_write_ = false;
    }
    return false;
  }

  ChunkStream reads_;
  ChunkStream writes_;
  Chunk read_;
  Chunk write_;
  bool has_read_ = false;
  bool has_write_ = false;
  std::optional<SessionError> damage_;
};

// Anything by that name counts: opening it then says what is wrong with a
// FIFO or a directory, rather than calling it missing.
bool exists(const std::string& path) {
  struct stat info {};
  return sys::stat(path.c_str(), &info) == 0;
}

bool ends_with(const std::string& text, const std::string& suffix) {
  return text.size() >= suffix.size() &&
         text.compare(text.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

std::optional<std::string> flexiport_prefix(const std::string& path) {
  if (ends_with(path, ".logr") || ends_with(path, ".logw")) {
    return path.substr(0, path.size() - 1);
  }
  if (exists(path + "r") || exists(path + "w")) return path;
  return std::nullopt;
}

std::unique_ptr<RecordSource> open_flexiport(const std::string& prefix,
                                             SessionHeader& header) {
  for (const char* suffix : {"r", "w"}) {
    if (!exists(prefix + suffix)) {
      throw SessionError(prefix + suffix + ": missing: a flexiport log " + prefix +
                             " is the pair " + prefix + "r (reads) and " + prefix +
                             "w (writes)",
                         0);
    }
  }
  auto source = std::make_unique<FlexiportSource>(prefix);
  // flexiport's logs hold no start time, host or port: the header says
  // "not known" rather than inventing them, and names the logs it came from.
  SessionHeader provenance;
  provenance.source_format = "flexiport";
  const auto base_name = [](const std::string& path) {
    const auto slash = path.rfind('/');
    return slash == std::string::npos ? path : path.substr(slash + 1);
  };
  provenance.source_files = {base_name(prefix + "r"), base_name(prefix + "w")};
  provenance.source_details = {{"read_format", format_name(source->reads().format())},
                               {"write_format", format_name(source->writes().format())}};
  header = SessionHeader{};
  parse_header_json(header_json(provenance), prefix, 0, header);
  header.version_major = 0;  // not a .wtape file: no format version
  header.version_minor = 0;
  header.wiretape_version.clear();  // nor written by wiretape
  return source;
}

}  // namespace detail

namespace {

// A file written through a buffer; every failure is a PortError naming it.
// An export: a FIFO or device at the path is written through (DESIGN §6).
class OutputFile {
 public:
  explicit OutputFile(std::string path)
      : path_(std::move(path)),
        fd_(detail::open_output_file(path_, detail::SpecialOutputs::written_through)) {}
  void write(const void* data, std::size_t size) {
    buffer_.append(static_cast<const char*>(data), size);
    if (buffer_.size() >= flush_size) flush();
  }
  void close() {
    flush();
    if (detail::sys::close(fd_.release()) != 0) {
      throw PortError(errno, path_ + ": write failed");
    }
  }

 private:
  static constexpr std::size_t flush_size = 64 * 1024;

  void flush() {
    std::size_t done = 0;
    while (done < buffer_.size()) {
      const ssize_t n =
          detail::sys::write(fd_.get(), buffer_.data() + done, buffer_.size() - done);
      if (n < 0 && errno == EINTR) {
        detail::check_interruption();  // a FIFO's reader may keep it waiting
        continue;
      }
      if (n <= 0) throw PortError(n < 0 ? errno : ENOSPC, path_ + ": write failed");
      done += static_cast<std::size_t>(n);
    }
    buffer_.clear();
  }

  std::string path_;
  detail::sys::UniqueFd fd_;
  std::string buffer_;
};

}  // namespace

std::uint64_t export_flexiport(const std::string& session_path, const std::string& prefix,
                               FlexiportFormat format) {
  SessionReader reader(session_path);
  // Both refused or both written: a refused .logw must not cost the .logr.
  for (const char* suffix : {"r", "w"}) {
    detail::check_output_file(prefix + suffix, detail::SpecialOutputs::written_through);
  }
  OutputFile reads(prefix + "r");
  OutputFile writes(prefix + "w");
  std::uint64_t written = 0;
  Record record;
  while (reader.next(record)) {
    if (record.kind != RecordKind::rx && record.kind != RecordKind::tx) continue;
    const std::uint64_t seconds = record.t_ns / 1'000'000'000ull;
    if (seconds > 0xFFFFFFFFull || record.data.size() > 0xFFFFFFFFull) {
      throw SessionError(session_path + ": a record at " + std::to_string(record.t_ns) +
                             " ns does not fit flexiport's 32-bit fields",
                         0);
    }
    const std::uint64_t micros = (record.t_ns % 1'000'000'000ull) / 1000;
    OutputFile& out = record.kind == RecordKind::rx ? reads : writes;
    if (format == FlexiportFormat::legacy) {
      char header[24];
      detail::put_u64le(header, seconds);
      detail::put_u64le(header + 8, micros);
      detail::put_u64le(header + 16, record.data.size());
      out.write(header, sizeof header);
    } else {
      char header[12];
      detail::put_u32be(header, static_cast<std::uint32_t>(seconds));
      detail::put_u32be(header + 4, static_cast<std::uint32_t>(micros));
      detail::put_u32be(header + 8, static_cast<std::uint32_t>(record.data.size()));
      out.write(header, sizeof header);
    }
    out.write(record.data.data(), record.data.size());
    ++written;
  }
  reads.close();
  writes.close();
  if (reader.damage()) throw *reader.damage();
  return written;
}

}  // namespace wiretape
