// The .wtape byte layout (docs/session-format.md) and the pieces shared by
// the session reader, the writer and the flexiport importer.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "session/record_source.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/session.hpp"

namespace wiretape::detail {

// "\x89WTAPE\r\n": the high byte catches 7-bit transfers, CR LF catches
// newline translation.
inline constexpr char session_magic[8] = {'\x89', 'W', 'T', 'A', 'P', 'E', '\r', '\n'};
inline constexpr std::uint16_t session_version_major = 1;
inline constexpr std::uint16_t session_version_minor = 0;
// magic, major, minor, JSON length
inline constexpr std::size_t file_header_fixed_size = 16;
// A header larger than this is corrupt, whatever the file holds.
inline constexpr std::uint32_t max_header_json = 16u << 20;
// length, kind, flags, reserved, t_ns
inline constexpr std::size_t record_header_size = 16;
inline constexpr std::size_t crc_size = 4;

inline void put_u16le(char* out, std::uint16_t v) {
  out[0] = static_cast<char>(v & 0xFF);
  out[1] = static_cast<char>(v >> 8);
}
inline void put_u32le(char* out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out[i] = static_cast<char>((v >> (8 * i)) & 0xFF);
}
inline void put_u64le(char* out, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) out[i] = static_cast<char>((v >> (8 * i)) & 0xFF);
}
inline std::uint16_t get_u16le(const char* in) {
  const auto* b = reinterpret_cast<const unsigned char*>(in);
  return static_cast<std::uint16_t>(b[0] | (b[1] << 8));
}
inline std::uint32_t get_u32le(const char* in) {
  const auto* b = reinterpret_cast<const unsigned char*>(in);
  return static_cast<std::uint32_t>(b[0]) | (static_cast<std::uint32_t>(b[1]) << 8) |
         (static_cast<std::uint32_t>(b[2]) << 16) | (static_cast<std::uint32_t>(b[3]) << 24);
}
inline std::uint64_t get_u64le(const char* in) {
  return static_cast<std::uint64_t>(get_u32le(in)) |
         (static_cast<std::uint64_t>(get_u32le(in + 4)) << 32);
}
inline std::uint32_t get_u32be(const char* in) {
  const auto* b = reinterpret_cast<const unsigned char*>(in);
  return (static_cast<std::uint32_t>(b[0]) << 24) | (static_cast<std::uint32_t>(b[1]) << 16) |
         (static_cast<std::uint32_t>(b[2]) << 8) | static_cast<std::uint32_t>(b[3]);
}
inline void put_u32be(char* out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out[i] = static_cast<char>((v >> (24 - 8 * i)) & 0xFF);
}

// CRC32C by slicing-by-8 tables: the portable path, and the reference the
// hardware path must agree with.
std::uint32_t crc32c_table(const void* data, std::size_t size, std::uint32_t crc = 0);
// Whether this CPU has CRC32C instructions this build can use.
bool crc32c_hardware_available();
// CRC32C by the CPU's instructions (falls back to the tables when
// crc32c_hardware_available() is false). wiretape::crc32c picks this when it
// can.
std::uint32_t crc32c_hardware(const void* data, std::size_t size, std::uint32_t crc = 0);

// The header JSON of a session file.
std::string header_json(const SessionWriterOptions& options);
// Parses the header JSON into `header` (metadata_json included); throws
// SessionError(offset) naming `path` when it is not valid.
void parse_header_json(const std::string& json, const std::string& path,
                       std::uint64_t offset, SessionHeader& header);
// Now, as 2026-11-23T10:00:00.123456Z.
std::string utc_now_iso8601();

// Sequential reads from a file through a fixed buffer; memory independent of
// the file's size. Knows how many bytes the file still holds, so that length
// fields can be checked before anything is allocated.
class BufferedFile {
 public:
  // Throws SessionError naming `path` if it cannot be opened.
  explicit BufferedFile(const std::string& path);
  ~BufferedFile();
  BufferedFile(const BufferedFile&) = delete;
  BufferedFile& operator=(const BufferedFile&) = delete;

  // Reads exactly `size` bytes; false (nothing consumed) if the file holds
  // fewer.
  bool read(void* out, std::size_t size);
  // Reads `size` bytes into `out`; the caller has checked remaining().
  bool read_into(std::string& out, std::size_t size);
  // Reads `size` bytes (at most max_view_size()) as a view into the buffer,
  // which is then never overwritten while the view lives; false (nothing
  // consumed) if the file holds fewer.
  bool read_view(std::size_t size, PayloadView& out);
  static std::size_t max_view_size();
  bool skip(std::uint64_t size);
  std::uint64_t position() const { return position_; }
  // Bytes after position(); re-reads the file's size so a file still being
  // written is followed.
  std::uint64_t remaining();
  std::uint64_t size() const { return size_; }
  void seek(std::uint64_t position);
  const std::string& path() const { return path_; }

 private:
  std::size_t fill();
  void refresh_size();

  std::string path_;
  int fd_ = -1;
  std::shared_ptr<char[]> buffer_;  // shared with the views handed out
  // Earlier buffers, reused once no view holds them any more.
  static constexpr std::size_t max_retired_buffers = 32;
  std::vector<std::shared_ptr<char[]>> retired_;
  std::size_t begin_ = 0;  // unread bytes are buffer_[begin_, end_)
  std::size_t end_ = 0;
  std::uint64_t position_ = 0;  // file offset of buffer_[begin_]
  std::uint64_t size_ = 0;
};

// flexiport's logs: `prefix` is "name.log" for name.logr + name.logw. Throws
// SessionError when they cannot be used at all.
std::unique_ptr<RecordSource> open_flexiport(const std::string& prefix,
                                             SessionHeader& header);
// The "name.log" prefix `path` names when it is a flexiport log ("name.log",
// "name.logr" or "name.logw" with the pair on disk), else std::nullopt.
std::optional<std::string> flexiport_prefix(const std::string& path);

}  // namespace wiretape::detail
