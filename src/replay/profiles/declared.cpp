// Profiles declared in options, for a protocol of one's own (DESIGN.md
// section 13): framing=, ignore=, echo=, checksum=. Each spec is parsed
// here once; a bad one is an OptionError naming the key and showing its
// grammar.
#include "replay/profiles/declared.hpp"

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string>
#include <vector>

#include "replay/profiles/checksums.hpp"
#include "util/hex.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

namespace {

constexpr const char* framing_grammar =
    "framing=delimiter:HEX | length:OFFSET:SIZE:ADJUST[:be|le] | fixed:N | gap:MS "
    "(MS: a frame ends after that many milliseconds without a byte, or where the other "
    "direction speaks; HEX: the delimiter's bytes in hex, such as 0d0a; length: the frame is "
    "ADJUST + the SIZE-byte (1, 2 or 4) unsigned field at OFFSET bytes long)";
constexpr const char* fields_grammar =
    "OFFSET:LEN[;OFFSET:LEN...] (a negative OFFSET counts from the frame's end)";
constexpr const char* checksum_grammar =
    "checksum=ALG@OFFSET, ALG one of crc16-modbus, crc16-ccitt, crc32, sum8, xor8, nmea "
    "(over the frame's bytes before OFFSET; a negative OFFSET counts from the end)";

[[noreturn]] void bad_spec(const std::string& key, const std::string& value,
                           const std::string& why, const char* grammar) {
  throw OptionError(key, "option '" + key + "': bad spec '" + value + "': " + why +
                             "; the grammar is " + grammar);
}

std::vector<std::string> split(const std::string& text, char separator) {
  std::vector<std::string> parts;
  std::size_t start = 0;
  for (;;) {
    const std::size_t end = text.find(separator, start);
    parts.push_back(text.substr(start, end == std::string::npos ? std::string::npos : end - start));
    if (end == std::string::npos) return parts;
    start = end + 1;
  }
}

// A decimal integer within [min, max], or nullopt.
std::optional<long long> integer(const std::string& text, long long min, long long max) {
  if (text.empty() || text.size() > 19) return std::nullopt;
  char* end = nullptr;
  errno = 0;
  const long long value = std::strtoll(text.c_str(), &end, 10);
  if (errno != 0 || end != text.c_str() + text.size() || value < min || value > max) {
    return std::nullopt;
  }
  return value;
}

std::optional<std::string> hex_bytes(const std::string& text) {
  if (text.empty() || text.size() % 2 != 0 || text.size() > 64) return std::nullopt;
  std::string bytes;
  for (std::size_t i = 0; i < text.size(); i += 2) {
    unsigned value = 0;
    for (std::size_t k = i; k < i + 2; ++k) {
      const char c = text[k];
      unsigned digit = 0;
      if (c >= '0' && c <= '9') digit = static_cast<unsigned>(c - '0');
      else if (c >= 'a' && c <= 'f') digit = static_cast<unsigned>(c - 'a' + 10);
      else if (c >= 'A' && c <= 'F') digit = static_cast<unsigned>(c - 'A' + 10);
      else return std::nullopt;
      value = value * 16 + digit;
    }
    bytes += static_cast<char>(value);
  }
  return bytes;
}

constexpr long long max_offset = 1 << 20;

// Where a field declared at `offset` (negative: from the end) begins in a
// frame of `size` bytes; nullopt if outside it.
std::optional<std::size_t> resolve(long long offset, std::size_t size) {
  const long long at = offset < 0 ? static_cast<long long>(size) + offset : offset;
  if (at < 0 || at > static_cast<long long>(size)) return std::nullopt;
  return static_cast<std::size_t>(at);
}

}  // namespace

DeclaredFraming parse_framing(const std::string& value) {
  const std::string key = "framing";
  const std::vector<std::string> parts = split(value, ':');
  DeclaredFraming framing;
  if (parts[0] == "delimiter") {
    if (parts.size() != 2) bad_spec(key, value, "delimiter takes one HEX argument", framing_grammar);
    const auto bytes = hex_bytes(parts[1]);
    if (!bytes) bad_spec(key, value, "'" + parts[1] + "' is not 1 to 32 bytes in hex", framing_grammar);
    framing.kind = DeclaredFraming::Kind::delimiter;
    framing.delimiter = *bytes;
    return framing;
  }
  if (parts[0] == "fixed") {
    if (parts.size() != 2) bad_spec(key, value, "fixed takes one size N", framing_grammar);
    const auto size = integer(parts[1], 1, max_frame_bytes);
    if (!size) bad_spec(key, value, "'" + parts[1] + "' is not a size from 1 to 1048576", framing_grammar);
    framing.kind = DeclaredFraming::Kind::fixed;
    framing.fixed = static_cast<std::size_t>(*size);
    return framing;
  }
  if (parts[0] == "length") {
    if (parts.size() != 4 && parts.size() != 5) {
      bad_spec(key, value, "length takes OFFSET:SIZE:ADJUST and an optional be or le",
               framing_grammar);
    }
    const auto offset = integer(parts[1], 0, 4096);
    const auto size = integer(parts[2], 1, 4);
    const auto adjust = integer(parts[3], -65536, 65536);
    if (!offset) bad_spec(key, value, "OFFSET '" + parts[1] + "' is not from 0 to 4096", framing_grammar);
    if (!size || *size == 3) bad_spec(key, value, "SIZE '" + parts[2] + "' is not 1, 2 or 4", framing_grammar);
    if (!adjust) bad_spec(key, value, "ADJUST '" + parts[3] + "' is not from -65536 to 65536", framing_grammar);
    if (parts.size() == 5 && parts[4] != "be" && parts[4] != "le") {
      bad_spec(key, value, "the byte order '" + parts[4] + "' is neither be nor le", framing_grammar);
    }
    framing.kind = DeclaredFraming::Kind::length;
    framing.length_offset = static_cast<std::size_t>(*offset);
    framing.length_size = static_cast<std::size_t>(*size);
    framing.length_adjust = *adjust;
    framing.little_endian = parts.size() == 5 && parts[4] == "le";
    return framing;
  }
  if (parts[0] == "gap") {
    if (parts.size() != 2) bad_spec(key, value, "gap takes one time MS", framing_grammar);
    const auto ms = integer(parts[1], 1, 60'000);
    if (!ms) bad_spec(key, value, "'" + parts[1] + "' is not from 1 to 60000 ms", framing_grammar);
    framing.kind = DeclaredFraming::Kind::gap;
    framing.gap_ns = static_cast<std::uint64_t>(*ms) * 1'000'000;
    return framing;
  }
  bad_spec(key, value, "'" + parts[0] + "' is not a framing (delimiter, length, fixed or gap)",
           framing_grammar);
}

std::vector<DeclaredField> parse_fields(const std::string& key, const std::string& value) {
  std::vector<DeclaredField> fields;
  for (const std::string& part : split(value, ';')) {
    const std::vector<std::string> numbers = split(part, ':');
    if (numbers.size() != 2) bad_spec(key, value, "'" + part + "' is not OFFSET:LEN", fields_grammar);
    const auto offset = integer(numbers[0], -max_offset, max_offset);
    const auto length = integer(numbers[1], 1, max_offset);
    if (!offset) bad_spec(key, value, "OFFSET '" + numbers[0] + "' is not a whole number", fields_grammar);
    if (!length) bad_spec(key, value, "LEN '" + numbers[1] + "' is not a positive whole number", fields_grammar);
    fields.push_back({*offset, static_cast<std::size_t>(*length)});
    if (fields.size() > 64) bad_spec(key, value, "more than 64 fields", fields_grammar);
  }
  return fields;
}

DeclaredChecksum parse_checksum(const std::string& value) {
  const std::string key = "checksum";
  const std::size_t at = value.find('@');
  if (at == std::string::npos) bad_spec(key, value, "no '@OFFSET'", checksum_grammar);
  const std::string algorithm = value.substr(0, at);
  const auto offset = integer(value.substr(at + 1), -max_offset, max_offset);
  if (!offset) bad_spec(key, value, "OFFSET '" + value.substr(at + 1) + "' is not a whole number", checksum_grammar);
  DeclaredChecksum checksum;
  checksum.offset = *offset;
  if (algorithm == "crc16-modbus") checksum.algorithm = DeclaredChecksum::Algorithm::crc16_modbus;
  else if (algorithm == "crc16-ccitt") checksum.algorithm = DeclaredChecksum::Algorithm::crc16_ccitt;
  else if (algorithm == "crc32") checksum.algorithm = DeclaredChecksum::Algorithm::crc32;
  else if (algorithm == "sum8") checksum.algorithm = DeclaredChecksum::Algorithm::sum8;
  else if (algorithm == "xor8") checksum.algorithm = DeclaredChecksum::Algorithm::xor8;
  else if (algorithm == "nmea") checksum.algorithm = DeclaredChecksum::Algorithm::nmea;
  else bad_spec(key, value, "'" + algorithm + "' is not a checksum this knows", checksum_grammar);
  return checksum;
}

namespace {

// The checksum's bytes for `covered`, as the frame carries them.
std::string checksum_bytes(DeclaredChecksum::Algorithm algorithm, std::string_view covered) {
  using Algorithm = DeclaredChecksum::Algorithm;
  switch (algorithm) {
    case Algorithm::crc16_modbus: {
      const std::uint16_t crc = crc16_modbus(covered);
      return {static_cast<char>(crc & 0xFF), static_cast<char>(crc >> 8)};
    }
    case Algorithm::crc16_ccitt: {
      const std::uint16_t crc = crc16_ccitt(covered);
      return {static_cast<char>(crc >> 8), static_cast<char>(crc & 0xFF)};
    }
    case Algorithm::crc32: {
      const std::uint32_t crc = crc32_zlib(covered);
      return {static_cast<char>(crc & 0xFF), static_cast<char>((crc >> 8) & 0xFF),
              static_cast<char>((crc >> 16) & 0xFF), static_cast<char>(crc >> 24)};
    }
    case Algorithm::sum8: return std::string(1, static_cast<char>(sum8(covered)));
    case Algorithm::xor8: return std::string(1, static_cast<char>(xor8(covered)));
    case Algorithm::nmea: {
      // Over what lies between the leading '$' or '!' and the '*'.
      std::string_view body = covered;
      if (!body.empty() && (body[0] == '$' || body[0] == '!')) body.remove_prefix(1);
      if (!body.empty() && body.back() == '*') body.remove_suffix(1);
      char text[3];
      std::snprintf(text, sizeof text, "%02X", xor8(body));
      return text;
    }
  }
  return {};
}

class DeclaredFramer final : public BufferingFramer {
 public:
  DeclaredFramer(const DeclaredFraming& framing, std::optional<DeclaredChecksum> checksum)
      : framing_(framing), checksum_(checksum) {}

  std::optional<std::chrono::nanoseconds> quiet_gap() const override {
    if (framing_.kind != DeclaredFraming::Kind::gap) return std::nullopt;
    return std::chrono::nanoseconds(framing_.gap_ns);
  }

  void feed_at(std::uint64_t t_ns, std::string_view bytes, std::vector<Frame>& frames) override {
    if (framing_.kind == DeclaredFraming::Kind::gap && !buffer_.empty() &&
        t_ns >= last_t_ns_ + framing_.gap_ns) {
      complete(frames);
    }
    last_t_ns_ = t_ns;
    feed(bytes, frames);
  }

  void feed(std::string_view bytes, std::vector<Frame>& frames) override {
    for (char byte : bytes) {
      buffer_ += byte;
      switch (framing_.kind) {
        case DeclaredFraming::Kind::gap:
          break;  // silence ends the frame (feed_at, finish)
        case DeclaredFraming::Kind::delimiter:
          if (buffer_.size() >= framing_.delimiter.size() &&
              buffer_.compare(buffer_.size() - framing_.delimiter.size(),
                              framing_.delimiter.size(), framing_.delimiter) == 0) {
            complete(frames);
          }
          break;
        case DeclaredFraming::Kind::fixed:
          if (buffer_.size() == framing_.fixed) complete(frames);
          break;
        case DeclaredFraming::Kind::length:
          if (buffer_.size() == framing_.length_offset + framing_.length_size) {
            long long value = 0;
            for (std::size_t i = 0; i < framing_.length_size; ++i) {
              const std::size_t at = framing_.little_endian
                                         ? framing_.length_offset + framing_.length_size - 1 - i
                                         : framing_.length_offset + i;
              value = value * 256 + static_cast<unsigned char>(buffer_[at]);
            }
            const long long total = value + framing_.length_adjust;
            if (total < static_cast<long long>(buffer_.size()) ||
                total > static_cast<long long>(max_frame_bytes)) {
              cut(FrameEnd::broken, frames,
                  "bad length: the length field says " + std::to_string(value) +
                      ", a frame of " + std::to_string(total) + " bytes");
              break;
            }
            expected_ = static_cast<std::size_t>(total);
          }
          if (expected_ != 0 && buffer_.size() == expected_) complete(frames);
          break;
      }
      if (!buffer_.empty() && buffer_.size() >= max_frame_bytes) {
        cut(FrameEnd::size_limit, frames, "no frame end in 1 MiB");
      }
    }
  }

 private:
  void complete(std::vector<Frame>& frames) {
    if (checksum_) {
      const auto at = resolve(checksum_->offset, buffer_.size());
      if (!at) {
        cut(FrameEnd::broken, frames, "too short for its checksum");
        return;
      }
      const std::string computed = checksum_bytes(checksum_->algorithm, std::string_view(buffer_).substr(0, *at));
      const std::string_view stored = std::string_view(buffer_).substr(*at, computed.size());
      if (stored != computed) {
        cut(FrameEnd::broken, frames,
            "bad checksum " + hex_ascii(stored) + ", computed " + hex_ascii(computed));
        return;
      }
    }
    cut(FrameEnd::delimited, frames);
  }
  void forget_frame() override { expected_ = 0; }
  // Silence ends a frame: what is kept is whole when the stream ends.
  FrameEnd tail_end() const override {
    return framing_.kind == DeclaredFraming::Kind::gap ? FrameEnd::delimited
                                                       : FrameEnd::stream_end;
  }

  DeclaredFraming framing_;
  std::uint64_t last_t_ns_ = 0;
  std::optional<DeclaredChecksum> checksum_;
  std::size_t expected_ = 0;
};

class DeclaredProfile final : public Profile {
 public:
  explicit DeclaredProfile(DeclaredSpec spec) : spec_(std::move(spec)) {}

  std::string_view name() const override { return "declared"; }
  std::string_view summary() const override {
    return "a protocol declared in options (framing=, ignore=, echo=, checksum=)";
  }
  std::unique_ptr<Framer> make_framer(StreamDirection) const override {
    return std::make_unique<DeclaredFramer>(spec_.framing, spec_.checksum);
  }
  std::string match_key(std::string_view request) const override {
    std::vector<bool> left_out(request.size(), false);
    const auto leave_out = [&](long long offset, std::size_t length) {
      const auto at = resolve(offset, request.size());
      if (!at) return;
      for (std::size_t i = *at; i < request.size() && i < *at + length; ++i) left_out[i] = true;
    };
    for (const DeclaredField& field : spec_.ignore) leave_out(field.offset, field.length);
    for (const DeclaredField& field : spec_.echo) leave_out(field.offset, field.length);
    if (spec_.checksum) {
      leave_out(spec_.checksum->offset,
                checksum_bytes(spec_.checksum->algorithm, {}).size());
    }
    std::string key;
    for (std::size_t i = 0; i < request.size(); ++i) {
      if (!left_out[i]) key += request[i];
    }
    return key;
  }
  bool fixes_responses() const override { return !spec_.echo.empty(); }
  std::string fix_response(std::string_view, std::string_view actual,
                           std::string_view response) const override {
    std::string fixed(response);
    for (const DeclaredField& field : spec_.echo) {
      const auto from = resolve(field.offset, actual.size());
      const auto to = resolve(field.offset, fixed.size());
      if (!from || !to) continue;
      for (std::size_t i = 0; i < field.length && *from + i < actual.size() &&
                              *to + i < fixed.size();
           ++i) {
        fixed[*to + i] = actual[*from + i];
      }
    }
    return recompute_checksums(StreamDirection::rx, fixed);
  }
  std::string recompute_checksums(StreamDirection, std::string_view frame) const override {
    std::string fixed(frame);
    if (spec_.checksum) {
      if (const auto at = resolve(spec_.checksum->offset, fixed.size())) {
        const std::string sum =
            checksum_bytes(spec_.checksum->algorithm, std::string_view(fixed).substr(0, *at));
        fixed.replace(*at, std::min(sum.size(), fixed.size() - *at), sum);
      }
    }
    return fixed;
  }
  std::string frame_name(StreamDirection, std::string_view frame) const override {
    return escape_bytes(frame, 24);
  }
  std::string describe(StreamDirection, std::string_view frame) const override {
    return escape_bytes(frame, 64);
  }
  std::string field_name(StreamDirection, std::string_view frame,
                         std::size_t offset) const override {
    const auto in = [&](long long start, std::size_t length) {
      const auto at = resolve(start, frame.size());
      return at && offset >= *at && offset < *at + length;
    };
    for (const DeclaredField& field : spec_.echo) {
      if (in(field.offset, field.length)) return "echo field";
    }
    for (const DeclaredField& field : spec_.ignore) {
      if (in(field.offset, field.length)) return "ignored field";
    }
    if (spec_.checksum && in(spec_.checksum->offset, 4)) return "checksum";
    return "byte " + std::to_string(offset);
  }

 private:
  DeclaredSpec spec_;
};

}  // namespace

std::shared_ptr<const Profile> take_declared_profile(Options& options) {
  const auto framing = options.peek("framing");
  for (const char* key : {"ignore", "echo", "checksum"}) {
    if (!framing && options.has(key)) {
      throw OptionError(key, std::string("option '") + key +
                                 "' belongs to a declared profile and needs framing=; "
                                 "the grammar is " + framing_grammar);
    }
  }
  if (!framing) return nullptr;
  DeclaredSpec spec;
  spec.framing = parse_framing(options.take_string("framing"));
  if (options.has("ignore")) spec.ignore = parse_fields("ignore", options.take_string("ignore"));
  if (options.has("echo")) spec.echo = parse_fields("echo", options.take_string("echo"));
  if (options.has("checksum")) spec.checksum = parse_checksum(options.take_string("checksum"));
  return std::make_shared<DeclaredProfile>(std::move(spec));
}

}  // namespace wiretape::detail
