// The `nmea` profile: NMEA 0183 sentences ("$GPGGA,...*hh\r\n", "!AIVDM,..."),
// both directions. A sentence is a line ending with LF; one that does not
// begin with '$' or '!', or whose checksum is wrong, is a broken frame. The
// key is the sentence without its checksum and line end.
#include <cctype>
#include <cstdio>
#include <string>

#include "replay/profiles/builtin.hpp"
#include "replay/profiles/checksums.hpp"
#include "util/hex.hpp"

namespace wiretape::detail {

namespace {

std::string_view without_line_end(std::string_view line) {
  while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.remove_suffix(1);
  return line;
}

// What is wrong with a sentence; empty if nothing.
std::string sentence_problem(std::string_view frame) {
  const std::string_view line = without_line_end(frame);
  if (line.empty() || (line[0] != '$' && line[0] != '!')) {
    return "garbage: not an NMEA sentence (no '$' or '!' at its start)";
  }
  const std::size_t star = line.rfind('*');
  if (star == std::string_view::npos) return {};  // the checksum is optional
  if (line.size() != star + 3) return "bad checksum field '" + std::string(line.substr(star)) + "'";
  unsigned stored = 0;
  if (std::sscanf(std::string(line.substr(star + 1)).c_str(), "%2x", &stored) != 1) {
    return "bad checksum field '" + std::string(line.substr(star)) + "'";
  }
  const unsigned computed = xor8(line.substr(1, star - 1));
  if (stored != computed) {
    char problem[64];
    std::snprintf(problem, sizeof problem, "bad checksum %02X, computed %02X", stored, computed);
    return problem;
  }
  return {};
}

class SentenceFramer final : public BufferingFramer {
 public:
  void feed(std::string_view bytes, std::vector<Frame>& frames) override {
    for (char byte : bytes) {
      buffer_ += byte;
      if (byte == '\n') {
        std::string problem = sentence_problem(buffer_);
        const FrameEnd end = problem.empty() ? FrameEnd::delimited : FrameEnd::broken;
        cut(end, frames, std::move(problem));
      } else if (buffer_.size() >= 1024) {
        cut(FrameEnd::size_limit, frames, "no line end in 1024 bytes");
      }
    }
  }
};

class NmeaProfile final : public Profile {
 public:
  std::string_view name() const override { return "nmea"; }
  std::string_view summary() const override {
    return "NMEA 0183 sentences; checksums checked and left out of the key";
  }
  std::unique_ptr<Framer> make_framer(StreamDirection) const override {
    return std::make_unique<SentenceFramer>();
  }
  std::string match_key(std::string_view request) const override {
    std::string_view line = without_line_end(request);
    const std::size_t star = line.rfind('*');
    if (star != std::string_view::npos) line = line.substr(0, star);
    return std::string(line);
  }
  // The two hex digits after the '*' (in the case the sentence used), where
  // there are two; a sentence without a checksum keeps none.
  std::string recompute_checksums(StreamDirection, std::string_view frame) const override {
    std::string fixed(frame);
    const std::string_view line = without_line_end(frame);
    if (line.empty() || (line[0] != '$' && line[0] != '!')) return fixed;
    const std::size_t star = line.rfind('*');
    if (star == std::string_view::npos || line.size() != star + 3) return fixed;
    const bool lower = std::islower(static_cast<unsigned char>(line[star + 1])) ||
                       std::islower(static_cast<unsigned char>(line[star + 2]));
    char digits[3];
    std::snprintf(digits, sizeof digits, lower ? "%02x" : "%02X",
                  static_cast<unsigned>(xor8(line.substr(1, star - 1))));
    fixed[star + 1] = digits[0];
    fixed[star + 2] = digits[1];
    return fixed;
  }
  std::string frame_name(StreamDirection, std::string_view frame) const override {
    const std::string_view line = without_line_end(frame);
    const std::size_t comma = line.find_first_of(",*");
    return escape_bytes(line.substr(0, comma == std::string_view::npos ? line.size() : comma), 16);
  }
  std::string describe(StreamDirection, std::string_view frame) const override {
    return escape_bytes(without_line_end(frame), 80);
  }
  std::string field_name(StreamDirection, std::string_view frame,
                         std::size_t offset) const override {
    const std::string_view line = without_line_end(frame);
    if (offset >= line.size()) return "line end";
    const std::size_t star = line.rfind('*');
    if (star != std::string_view::npos && offset >= star) return "checksum";
    std::size_t field = 0;
    for (std::size_t i = 0; i < offset; ++i) field += line[i] == ',';
    return field == 0 ? "sentence type" : "field " + std::to_string(field);
  }
};

}  // namespace

std::shared_ptr<const Profile> make_nmea_profile() { return std::make_shared<NmeaProfile>(); }

}  // namespace wiretape::detail
