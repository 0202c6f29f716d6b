// Where a test's cassette lives, what it is called and how a recording
// becomes it: the one set of rules for the GoogleTest helper
// (wiretape/testing.hpp) and, bound, the pytest plugin (wiretape.testing).
// Header-only and without GoogleTest, so that the Python extension can bind
// it. docs/testing.md, "Cassette names".
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "wiretape/options.hpp"
#include "wiretape/session.hpp"

namespace wiretape::testing {

// The longest file name a cassette gets, without ".wtape".
inline constexpr std::size_t max_cassette_name_length = 100;
// The hex digits of the name's hash that a changed name ends with.
inline constexpr std::size_t cassette_hash_digits = 12;

namespace detail {

// SHA-1 of `data` as 40 hex digits. Not for security: a name's fingerprint,
// the same one Python's hashlib.sha1 gives (cassettes named by the earlier
// pytest plugin keep their names).
inline std::string sha1_hex(std::string_view data) {
  std::uint32_t h[5] = {0x67452301u, 0xEFCDAB89u, 0x98BADCFEu, 0x10325476u, 0xC3D2E1F0u};
  const auto rotl = [](std::uint32_t x, int n) { return (x << n) | (x >> (32 - n)); };
  std::string message(data);
  const std::uint64_t bit_length = static_cast<std::uint64_t>(data.size()) * 8u;
  message += static_cast<char>(0x80);
  while (message.size() % 64 != 56) message += '\0';
  for (int shift = 56; shift >= 0; shift -= 8) {
    message += static_cast<char>((bit_length >> shift) & 0xffu);
  }
  for (std::size_t block = 0; block < message.size(); block += 64) {
    std::array<std::uint32_t, 80> w{};
    for (int i = 0; i < 16; ++i) {
      for (int b = 0; b < 4; ++b) {
        w[i] = (w[i] << 8) | static_cast<unsigned char>(message[block + 4 * i + b]);
      }
    }
    for (int i = 16; i < 80; ++i) w[i] = rotl(w[i - 3] ^ w[i - 8] ^ w[i - 14] ^ w[i - 16], 1);
    std::uint32_t a = h[0], b = h[1], c = h[2], d = h[3], e = h[4];
    for (int i = 0; i < 80; ++i) {
      std::uint32_t f = 0, k = 0;
      if (i < 20) {
        f = (b & c) | (~b & d), k = 0x5A827999u;
      } else if (i < 40) {
        f = b ^ c ^ d, k = 0x6ED9EBA1u;
      } else if (i < 60) {
        f = (b & c) | (b & d) | (c & d), k = 0x8F1BBCDCu;
      } else {
        f = b ^ c ^ d, k = 0xCA62C1D6u;
      }
      const std::uint32_t next = rotl(a, 5) + f + e + k + w[i];
      e = d, d = c, c = rotl(b, 30), b = a, a = next;
    }
    h[0] += a, h[1] += b, h[2] += c, h[3] += d, h[4] += e;
  }
  std::string hex;
  char digits[9];
  for (std::uint32_t word : h) {
    std::snprintf(digits, sizeof digits, "%08x", static_cast<unsigned>(word));
    hex += digits;
  }
  return hex;
}

inline bool is_safe_name_char(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
         c == '.' || c == '_' || c == '-' || c == '=' || c == '+';
}

}  // namespace detail

// `name` (UTF-8) as a file name: every run of characters but ASCII letters,
// digits and `._-=+` becomes one `_`, and `_` and `.` are trimmed from both
// ends ("test" if nothing is left). A name that had to change, or that is
// longer than max_cassette_name_length, is cut to fit and ends with `-` and
// the first 12 hex digits of the SHA-1 of the whole name: two tests whose
// names differ never share a cassette (`t[a b]` and `t[a_b]` both read
// `t_a_b`, but their hashes differ), and a name that needed no change keeps
// it exactly.
inline std::string safe_file_name(std::string_view name) {
  std::string safe;
  safe.reserve(name.size());
  bool in_run = false;
  for (char c : name) {
    if (detail::is_safe_name_char(c)) {
      safe += c;
      in_run = false;
    } else if (!in_run) {
      safe += '_';
      in_run = true;
    }
  }
  const auto trim_end = [](std::string& text) {
    while (!text.empty() && (text.back() == '_' || text.back() == '.')) text.pop_back();
  };
  trim_end(safe);
  std::size_t first = 0;
  while (first < safe.size() && (safe[first] == '_' || safe[first] == '.')) ++first;
  safe.erase(0, first);
  if (safe.empty()) safe = "test";
  if (safe == name && safe.size() <= max_cassette_name_length) return safe;
  const std::size_t keep = max_cassette_name_length - cassette_hash_digits - 1;
  if (safe.size() > keep) safe.resize(keep);
  trim_end(safe);
  return safe + "-" + detail::sha1_hex(name).substr(0, cassette_hash_digits);
}

// A test's cassette file name from the parts of its name, outermost first
// (GoogleTest: suite, test; pytest: class(es), function with its parameters):
// the parts joined by "." and made safe as a whole, plus ".wtape".
inline std::string cassette_file_name(const std::vector<std::string>& test_name_parts) {
  std::string joined;
  for (const std::string& part : test_name_parts) {
    if (!joined.empty()) joined += '.';
    joined += part;
  }
  return safe_file_name(joined) + ".wtape";
}

// The folder of a test source's cassettes: <dir of source>/recordings/<stem
// of source>, or <directory>/<stem of source> when a directory is given.
inline std::string cassette_directory(std::string_view source_file,
                                      std::string_view directory = {}) {
  const std::filesystem::path source{std::string(source_file)};
  const std::filesystem::path base = directory.empty()
                                         ? source.parent_path() / "recordings"
                                         : std::filesystem::path(std::string(directory));
  return (base / source.stem()).string();
}

// <cassette_directory>/<cassette_file_name({suite, test})>.
inline std::string default_cassette_path(std::string_view source_file, std::string_view suite,
                                         std::string_view test,
                                         const std::string& directory = {}) {
  return (std::filesystem::path(cassette_directory(source_file, directory)) /
          cassette_file_name({std::string(suite), std::string(test)}))
      .string();
}

// The file a cassette path stands for: the path itself, or through a
// symbolic link (a chain of them, a dangling one too) the file the last
// link names, so that a cassette kept behind a link is written where the
// link points and the link stays, as the exports write through links.
inline std::filesystem::path cassette_target(const std::filesystem::path& cassette) {
  std::filesystem::path target = cassette;
  std::error_code error;
  for (int hops = 0; hops < 40; ++hops) {  // 40: the kernel's own bound on a chain
    if (!std::filesystem::is_symlink(std::filesystem::symlink_status(target, error))) break;
    const std::filesystem::path next = std::filesystem::read_symlink(target, error);
    if (error) break;
    target = next.is_absolute() ? next : target.parent_path() / next;
  }
  return target;
}

namespace detail {

// Renames `from` to `to`; where they are on different file systems (a link
// to a cassette store elsewhere), copies to a file beside `to` and renames
// that, so that `to` is never half written.
inline void move_recording(const std::filesystem::path& from, const std::filesystem::path& to) {
  std::error_code error;
  std::filesystem::rename(from, to, error);
  if (!error) return;
  if (error != std::errc::cross_device_link) {
    throw std::filesystem::filesystem_error("cannot move the recording to its cassette", from,
                                            to, error);
  }
  const std::filesystem::path beside = to.string() + ".partial";
  std::error_code ignored;
  try {
    std::filesystem::copy_file(from, beside, std::filesystem::copy_options::overwrite_existing);
    std::filesystem::rename(beside, to);
  } catch (...) {
    std::filesystem::remove(beside, ignored);
    throw;
  }
  std::filesystem::remove(from, ignored);
}

}  // namespace detail

// `text` as one word of a POSIX shell, for the commands that messages print:
// in single quotes, each `'` in it spelled `'\''`.
inline std::string shell_quoted(std::string_view text) {
  std::string quoted = "'";
  for (char c : text) {
    if (c == '\'') {
      quoted += "'\\''";
    } else {
      quoted += c;
    }
  }
  return quoted + "'";
}

// The device setting a cassette was recorded from, for the command that
// records it again: the port options its header keeps (a channel's, for a
// cassette of several ports) without what the recording added to the
// device's own: log= (the cassette), name= (a Recorder's channel) and the
// test helpers' metadata (meta_gtest, meta_pytest_node). "" when the header
// keeps none (an imported session) or they do not parse.
inline std::string recorded_device(std::string_view port_options) {
  Options options;
  try {
    options = Options::parse(port_options);
  } catch (const std::exception&) {
    return {};
  }
  for (const char* added : {"log", "name", "meta_gtest", "meta_pytest_node"}) options.erase(added);
  return options.entries().empty() ? std::string() : options.to_string();
}

// Moves a finished recording (recorded to the temporary file `recording`,
// e.g. "<cassette>.recording-4242") to `cassette`, so that the cassette says
// nothing of the machine or the run that recorded it: the port option
// string, which names the file recorded to (log=/tmp/.../x.recording-4242),
// names the cassette's own file name instead (log=x.wtape), and so does any
// other field of the header that named the temporary file. Everything else
// (records, times, host, metadata) is kept. A recording that is damaged (a
// failed write) or names no temporary file is moved as it is, so that
// nothing it holds is lost. Throws PortError/SessionError when the files
// cannot be read or written. A cassette that is a symbolic link is
// written through it (cassette_target), its header naming the link's name.
inline void publish_recording(const std::string& recording, const std::string& cassette) {
  const std::string cassette_name = std::filesystem::path(cassette).filename().string();
  const std::filesystem::path target = cassette_target(cassette);
  const std::string quoted_recording = quote_option_value(recording);
  const auto replace_all = [](std::string text, const std::string& from, const std::string& to) {
    for (std::size_t at = text.find(from); at != std::string::npos;
         at = text.find(from, at + to.size())) {
      text.replace(at, from.size(), to);
    }
    return text;
  };
  const auto stable = [&](const std::string& text) {
    return replace_all(replace_all(text, "log=" + quoted_recording,
                                   "log=" + quote_option_value(cassette_name)),
                       recording, cassette_name);
  };
  {
    SessionReader reader(recording);
    SessionHeader header = reader.header();
    const bool names_recording = header.metadata_json.find(recording) != std::string::npos ||
                                 header.metadata_json.find(quoted_recording) != std::string::npos;
    if (names_recording) {
      header.port_options = stable(header.port_options);
      header.device_address = stable(header.device_address);
      for (auto& [key, value] : header.user_metadata) value = stable(value);
      header.metadata_json.clear();
      const std::string rewritten = recording + ".header";
      bool whole = false;
      std::error_code ignored;
      try {
        SessionWriter writer(rewritten, header);
        Record record;
        while (reader.next(record)) writer.write(record);
        whole = !reader.damage();
        writer.close();
      } catch (...) {
        // The recording stays where it was; no half-written copy is left.
        std::filesystem::remove(rewritten, ignored);
        throw;
      }
      if (whole) {
        detail::move_recording(rewritten, target);
        std::filesystem::remove(recording, ignored);
        return;
      }
      std::filesystem::remove(rewritten, ignored);
    }
  }
  detail::move_recording(recording, target);
}

}  // namespace wiretape::testing
