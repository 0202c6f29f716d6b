#include "session/format.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <ctime>

#if defined(__x86_64__)
#include <nmmintrin.h>
#elif defined(__aarch64__) && defined(__ARM_FEATURE_CRC32)
#include <arm_acle.h>
#endif

#include "util/json.hpp"
#include "wiretape/version.hpp"

namespace wiretape {

namespace {

// Slicing-by-8 tables of the reflected Castagnoli polynomial.
using CrcTables = std::array<std::array<std::uint32_t, 256>, 8>;

CrcTables make_crc_tables() {
  CrcTables tables{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t crc = i;
    for (int bit = 0; bit < 8; ++bit) crc = (crc >> 1) ^ (0x82F63B78u & (0u - (crc & 1u)));
    tables[0][i] = crc;
  }
  for (std::size_t i = 0; i < 256; ++i) {
    for (std::size_t slice = 1; slice < 8; ++slice) {
      const std::uint32_t previous = tables[slice - 1][i];
      tables[slice][i] = (previous >> 8) ^ tables[0][previous & 0xFF];
    }
  }
  return tables;
}

const CrcTables& crc_tables() {
  static const CrcTables tables = make_crc_tables();
  return tables;
}

}  // namespace

namespace {

// The hardware paths run three independent streams over consecutive blocks
// (the crc32 instruction's latency is three times its issue interval) and
// join them by advancing a stream's register over the blocks that follow it.
constexpr std::size_t crc_long_block = 8192;
constexpr std::size_t crc_short_block = 256;
static_assert(crc_long_block % 8 == 0 && crc_short_block % 8 == 0,
              "the streams advance eight bytes a step");

// Advancing a raw CRC register over n zero bytes is linear over GF(2): one
// table per byte of the register.
using CrcShiftTable = std::array<std::array<std::uint32_t, 256>, 4>;

CrcShiftTable make_crc_shift_table(std::size_t zero_bytes) {
  // zero_bytes is a multiple of 8: eight zero bytes at a time by the
  // slicing tables (the data bytes' lookups are all t[k][0] == 0).
  const CrcTables& t = crc_tables();
  std::array<std::uint32_t, 32> basis{};
  for (std::size_t bit = 0; bit < 32; ++bit) {
    std::uint32_t crc = 1u << bit;
    for (std::size_t i = 0; i < zero_bytes; i += 8) {
      crc = t[7][crc & 0xFF] ^ t[6][(crc >> 8) & 0xFF] ^ t[5][(crc >> 16) & 0xFF] ^
            t[4][crc >> 24];
    }
    basis[bit] = crc;
  }
  CrcShiftTable table{};
  for (std::size_t byte = 0; byte < 4; ++byte) {
    for (std::uint32_t value = 0; value < 256; ++value) {
      std::uint32_t shifted = 0;
      for (std::size_t bit = 0; bit < 8; ++bit) {
        if ((value >> bit) & 1u) shifted ^= basis[byte * 8 + bit];
      }
      table[byte][value] = shifted;
    }
  }
  return table;
}

inline std::uint32_t crc_shift(const CrcShiftTable& table, std::uint32_t crc) {
  return table[0][crc & 0xFF] ^ table[1][(crc >> 8) & 0xFF] ^ table[2][(crc >> 16) & 0xFF] ^
         table[3][crc >> 24];
}

const CrcShiftTable& crc_long_shift() {
  static const CrcShiftTable table = make_crc_shift_table(crc_long_block);
  return table;
}
const CrcShiftTable& crc_short_shift() {
  static const CrcShiftTable table = make_crc_shift_table(crc_short_block);
  return table;
}

inline std::uint64_t load_u64(const unsigned char* p) {
  std::uint64_t value;
  std::memcpy(&value, p, sizeof value);
  return value;
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define WIRETAPE_CRC32C_HARDWARE 1

__attribute__((target("sse4.2"))) inline std::uint32_t crc_step(std::uint32_t crc,
                                                                  const unsigned char* p) {
  return static_cast<std::uint32_t>(_mm_crc32_u64(crc, load_u64(p)));
}
__attribute__((target("sse4.2"))) inline std::uint32_t crc_step_byte(std::uint32_t crc,
                                                                       unsigned char byte) {
  return _mm_crc32_u8(crc, byte);
}
#define WIRETAPE_CRC32C_TARGET __attribute__((target("sse4.2")))

bool cpu_has_crc32c() { return __builtin_cpu_supports("sse4.2"); }

#elif defined(__aarch64__) && defined(__ARM_FEATURE_CRC32)
#define WIRETAPE_CRC32C_HARDWARE 1

inline std::uint32_t crc_step(std::uint32_t crc, const unsigned char* p) {
  return __crc32cd(crc, load_u64(p));
}
inline std::uint32_t crc_step_byte(std::uint32_t crc, unsigned char byte) {
  return __crc32cb(crc, byte);
}
#define WIRETAPE_CRC32C_TARGET

bool cpu_has_crc32c() { return true; }
#endif

#ifdef WIRETAPE_CRC32C_HARDWARE
// Three streams over [p, p + 3 * block), joined into `crc`.
template <std::size_t block>
WIRETAPE_CRC32C_TARGET inline std::uint32_t crc_three_blocks(std::uint32_t crc,
                                                             const unsigned char* p,
                                                             const CrcShiftTable& shift) {
  std::uint32_t crc1 = 0;
  std::uint32_t crc2 = 0;
  for (std::size_t i = 0; i < block; i += 8) {
    crc = crc_step(crc, p + i);
    crc1 = crc_step(crc1, p + block + i);
    crc2 = crc_step(crc2, p + 2 * block + i);
  }
  crc = crc_shift(shift, crc) ^ crc1;
  return crc_shift(shift, crc) ^ crc2;
}

WIRETAPE_CRC32C_TARGET std::uint32_t crc32c_instructions(const void* data, std::size_t size,
                                                         std::uint32_t crc) {
  const auto* p = static_cast<const unsigned char*>(data);
  crc = ~crc;
  while (size >= 3 * crc_long_block) {
    crc = crc_three_blocks<crc_long_block>(crc, p, crc_long_shift());
    p += 3 * crc_long_block;
    size -= 3 * crc_long_block;
  }
  while (size >= 3 * crc_short_block) {
    crc = crc_three_blocks<crc_short_block>(crc, p, crc_short_shift());
    p += 3 * crc_short_block;
    size -= 3 * crc_short_block;
  }
  while (size >= 8) {
    crc = crc_step(crc, p);
    p += 8;
    size -= 8;
  }
  while (size-- > 0) crc = crc_step_byte(crc, *p++);
  return ~crc;
}
#endif

using Crc32cFunction = std::uint32_t (*)(const void*, std::size_t, std::uint32_t);

Crc32cFunction pick_crc32c() {
#ifdef WIRETAPE_CRC32C_HARDWARE
  if (cpu_has_crc32c()) {
    // Built now so that the first checksum on a recording thread does not.
    crc_long_shift();
    crc_short_shift();
    return crc32c_instructions;
  }
#endif
  return detail::crc32c_table;
}

}  // namespace

namespace detail {

std::uint32_t crc32c_table(const void* data, std::size_t size, std::uint32_t crc) {
  const CrcTables& t = crc_tables();
  const auto* p = static_cast<const unsigned char*>(data);
  crc = ~crc;
  while (size >= 8) {
    const std::uint32_t low = crc ^ (static_cast<std::uint32_t>(p[0]) |
                                     (static_cast<std::uint32_t>(p[1]) << 8) |
                                     (static_cast<std::uint32_t>(p[2]) << 16) |
                                     (static_cast<std::uint32_t>(p[3]) << 24));
    crc = t[7][low & 0xFF] ^ t[6][(low >> 8) & 0xFF] ^ t[5][(low >> 16) & 0xFF] ^
          t[4][low >> 24] ^ t[3][p[4]] ^ t[2][p[5]] ^ t[1][p[6]] ^ t[0][p[7]];
    p += 8;
    size -= 8;
  }
  while (size-- > 0) crc = (crc >> 8) ^ t[0][(crc ^ *p++) & 0xFF];
  return ~crc;
}

bool crc32c_hardware_available() {
#ifdef WIRETAPE_CRC32C_HARDWARE
  return cpu_has_crc32c();
#else
  return false;
#endif
}

std::uint32_t crc32c_hardware(const void* data, std::size_t size, std::uint32_t crc) {
#ifdef WIRETAPE_CRC32C_HARDWARE
  if (cpu_has_crc32c()) return crc32c_instructions(data, size, crc);
#endif
  return crc32c_table(data, size, crc);
}

}  // namespace detail

std::uint32_t crc32c(const void* data, std::size_t size, std::uint32_t crc) {
  static const Crc32cFunction implementation = pick_crc32c();
  return implementation(data, size, crc);
}

std::string_view to_string(RecordKind kind) {
  switch (kind) {
    case RecordKind::rx: return "rx";
    case RecordKind::tx: return "tx";
    case RecordKind::open: return "open";
    case RecordKind::close: return "close";
    case RecordKind::flush_input: return "flush_input";
    case RecordKind::flush_output: return "flush_output";
    case RecordKind::drain: return "drain";
    case RecordKind::settings: return "settings";
    case RecordKind::modem_lines: return "modem_lines";
    case RecordKind::line_break: return "break";
    case RecordKind::client_connect: return "client_connect";
    case RecordKind::client_disconnect: return "client_disconnect";
    case RecordKind::device_lost: return "device_lost";
  }
  return "unknown";
}

std::optional<RecordKind> record_kind_from_string(std::string_view name) {
  for (RecordKind kind :
       {RecordKind::rx, RecordKind::tx, RecordKind::open, RecordKind::close,
        RecordKind::flush_input, RecordKind::flush_output, RecordKind::drain,
        RecordKind::settings, RecordKind::modem_lines, RecordKind::line_break,
        RecordKind::client_connect, RecordKind::client_disconnect,
        RecordKind::device_lost}) {
    if (to_string(kind) == name) return kind;
  }
  if (name == "line_break") return RecordKind::line_break;
  return std::nullopt;
}

namespace detail {

std::string utc_now_iso8601() {
  const auto now = std::chrono::system_clock::now();
  const auto since_epoch = now.time_since_epoch();
  const auto seconds = std::chrono::duration_cast<std::chrono::seconds>(since_epoch);
  const auto micros =
      std::chrono::duration_cast<std::chrono::microseconds>(since_epoch - seconds);
  const std::time_t t = static_cast<std::time_t>(seconds.count());
  std::tm parts{};
  gmtime_r(&t, &parts);
  char text[64];
  std::snprintf(text, sizeof text, "%04d-%02d-%02dT%02d:%02d:%02d.%06lldZ",
                parts.tm_year + 1900, parts.tm_mon + 1, parts.tm_mday,
                parts.tm_hour, parts.tm_min, parts.tm_sec,
                static_cast<long long>(micros.count()));
  return text;
}

namespace {

std::string host_name() {
  char name[256] = {};
  if (gethostname(name, sizeof name - 1) != 0) return "";
  return name;
}

const char* capture_name(Capture capture) {
  return capture == Capture::wire ? "wire" : "client";
}

}  // namespace

std::string header_json(const SessionWriterOptions& options) {
  json::ObjectWriter object;
  object.add("port_options", options.port_options)
      .add("port_type", options.port_type)
      .add("start_utc",
           options.start_utc.empty() ? utc_now_iso8601() : options.start_utc)
      .add("wiretape_version", options.wiretape_version.empty()
                                   ? std::string(wiretape::version)
                                   : options.wiretape_version)
      .add("host", options.host.empty() ? host_name() : options.host)
      .add("capture", capture_name(options.capture))
      .add("metadata", options.metadata);
  return object.str();
}

void parse_header_json(const std::string& text, const std::string& path,
                       std::uint64_t offset, SessionHeader& header) {
  json::Value root;
  try {
    root = json::parse(text);
  } catch (const json::ParseError& e) {
    throw SessionError(path + ": the header's metadata is not valid JSON (" +
                           e.what() + " of the metadata, file byte " +
                           std::to_string(offset + e.offset()) + ")",
                       offset + e.offset());
  }
  if (!root.is_object()) {
    throw SessionError(path + ": the header's metadata at byte " +
                           std::to_string(offset) + " is not a JSON object",
                       offset);
  }
  header.metadata_json = text;
  header.port_options = root.string_member("port_options").value_or("");
  header.port_type = root.string_member("port_type").value_or("");
  header.start_utc = root.string_member("start_utc").value_or("");
  header.wiretape_version = root.string_member("wiretape_version").value_or("");
  header.host = root.string_member("host").value_or("");
  const std::string capture = root.string_member("capture").value_or("client");
  if (capture == "client") {
    header.capture = Capture::client;
  } else if (capture == "wire") {
    header.capture = Capture::wire;
  } else {
    throw SessionError(path + ": unknown capture \"" + capture +
                           "\" in the header at byte " + std::to_string(offset) +
                           " (expected client or wire)",
                       offset);
  }
  header.user_metadata.clear();
  if (const json::Value* metadata = root.find("metadata");
      metadata != nullptr && metadata->is_object()) {
    for (const auto& [key, value] : metadata->members) {
      header.user_metadata[key] =
          value.is_string() ? value.text : json::serialize(value);
    }
  }
}

// --- BufferedFile ----------------------------------------------------------

namespace {
constexpr std::size_t buffer_size = 128 * 1024;
}  // namespace

BufferedFile::BufferedFile(const std::string& path)
    : path_(path), buffer_(new char[buffer_size]) {
  do {
    fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  } while (fd_ < 0 && errno == EINTR);
  if (fd_ < 0) {
    throw SessionError(path + ": cannot open: " + std::strerror(errno), 0);
  }
  struct stat info {};
  if (::fstat(fd_, &info) == 0 && S_ISDIR(info.st_mode)) {
    ::close(fd_);
    fd_ = -1;
    throw SessionError(path + ": is a directory, not a session file", 0);
  }
  refresh_size();
}

BufferedFile::~BufferedFile() {
  if (fd_ >= 0) ::close(fd_);
}

void BufferedFile::refresh_size() {
  struct stat info {};
  if (::fstat(fd_, &info) == 0) size_ = static_cast<std::uint64_t>(info.st_size);
}

std::uint64_t BufferedFile::remaining() {
  // At the known end, look again: the file may still be being written.
  if (position_ >= size_) refresh_size();
  return size_ > position_ ? size_ - position_ : 0;
}

std::size_t BufferedFile::fill() {
  if (buffer_.use_count() > 1 && (begin_ > 0 || end_ == 0)) {
    // Views still point into this buffer: go on in a fresh one rather than
    // move or overwrite their bytes.
    std::shared_ptr<char[]> fresh;
    for (auto& retired : retired_) {
      if (retired.use_count() == 1) {  // its views are all gone: reuse it
        fresh = std::move(retired);
        retired = std::move(retired_.back());
        retired_.pop_back();
        break;
      }
    }
    // A fresh allocation costs page faults every time; reuse is what pays.
    if (!fresh) fresh.reset(new char[buffer_size]);
    std::memcpy(fresh.get(), buffer_.get() + begin_, end_ - begin_);
    end_ -= begin_;
    begin_ = 0;
    if (retired_.size() < max_retired_buffers) retired_.push_back(std::move(buffer_));
    buffer_ = std::move(fresh);
  } else if (begin_ > 0) {
    std::memmove(buffer_.get(), buffer_.get() + begin_, end_ - begin_);
    end_ -= begin_;
    begin_ = 0;
  }
  while (end_ < buffer_size) {
    const ssize_t n = ::read(fd_, buffer_.get() + end_, buffer_size - end_);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    end_ += static_cast<std::size_t>(n);
    break;
  }
  return end_ - begin_;
}

bool BufferedFile::read(void* out, std::size_t size) {
  auto* dst = static_cast<char*>(out);
  if (end_ - begin_ >= size) {
    std::memcpy(dst, buffer_.get() + begin_, size);
    begin_ += size;
    position_ += size;
    return true;
  }
  if (remaining() < size) refresh_size();
  if (remaining() < size) return false;
  // Large reads go straight to the destination.
  std::size_t done = end_ - begin_;
  std::memcpy(dst, buffer_.get() + begin_, done);
  begin_ = end_ = 0;
  if (size - done >= buffer_size) {
    while (done < size) {
      const ssize_t n = ::read(fd_, dst + done, size - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        seek(position_);
        return false;
      }
      done += static_cast<std::size_t>(n);
    }
    position_ += size;
    return true;
  }
  while (done < size) {
    if (fill() == 0) {
      seek(position_);
      return false;
    }
    const std::size_t take = std::min(size - done, end_ - begin_);
    std::memcpy(dst + done, buffer_.get() + begin_, take);
    begin_ += take;
    done += take;
  }
  position_ += size;
  return true;
}

bool BufferedFile::read_into(std::string& out, std::size_t size) {
  if (end_ - begin_ >= size) {
    // One copy, without the zero-fill a resize() would do first.
    out.assign(buffer_.get() + begin_, size);
    begin_ += size;
    position_ += size;
    return true;
  }
  out.resize(size);
  return size == 0 || read(&out[0], size);
}

std::size_t BufferedFile::max_view_size() { return buffer_size / 2; }

bool BufferedFile::read_view(std::size_t size, PayloadView& out) {
  if (size > max_view_size()) return false;
  if (end_ - begin_ < size) {
    if (remaining() < size) refresh_size();
    if (remaining() < size) return false;
    while (end_ - begin_ < size) {
      const std::size_t before = end_ - begin_;
      if (fill() == before) {
        seek(position_);
        return false;
      }
    }
  }
  out.owner = buffer_;
  out.bytes = std::string_view(buffer_.get() + begin_, size);
  begin_ += size;
  position_ += size;
  return true;
}

bool BufferedFile::skip(std::uint64_t size) {
  if (end_ - begin_ >= size) {
    begin_ += static_cast<std::size_t>(size);
    position_ += size;
    return true;
  }
  if (remaining() < size) refresh_size();
  if (remaining() < size) return false;
  seek(position_ + size);
  return true;
}

void BufferedFile::seek(std::uint64_t position) {
  ::lseek(fd_, static_cast<off_t>(position), SEEK_SET);
  position_ = position;
  begin_ = end_ = 0;
}

}  // namespace detail
}  // namespace wiretape
