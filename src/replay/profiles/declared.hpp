// Profiles declared in options (framing=, ignore=, echo=, checksum=), for a
// protocol wiretape has no built-in profile for. The spec parsers are
// separate so that the fuzz target (fuzz/profile_spec_fuzz.cpp) can drive
// them; each throws OptionError naming its key and showing its grammar.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "wiretape/options.hpp"
#include "wiretape/profile.hpp"

namespace wiretape::detail {

struct DeclaredFraming {
  enum class Kind { delimiter, length, fixed, gap } kind = Kind::delimiter;
  std::uint64_t gap_ns = 0;
  std::string delimiter;
  std::size_t fixed = 0;
  std::size_t length_offset = 0;
  std::size_t length_size = 0;
  long long length_adjust = 0;
  bool little_endian = false;
};

struct DeclaredField {
  long long offset = 0;  // negative: from the frame's end
  std::size_t length = 0;
};

struct DeclaredChecksum {
  enum class Algorithm { crc16_modbus, crc16_ccitt, crc32, sum8, xor8, nmea };
  Algorithm algorithm = Algorithm::crc16_modbus;
  long long offset = 0;  // negative: from the frame's end
};

struct DeclaredSpec {
  DeclaredFraming framing;
  std::vector<DeclaredField> ignore;
  std::vector<DeclaredField> echo;
  std::optional<DeclaredChecksum> checksum;
};

DeclaredFraming parse_framing(const std::string& value);
std::vector<DeclaredField> parse_fields(const std::string& key, const std::string& value);
DeclaredChecksum parse_checksum(const std::string& value);

// The declared profile of `options`' framing=, ignore=, echo= and checksum=
// keys (taken), or nullptr when there is no framing=.
std::shared_ptr<const Profile> take_declared_profile(Options& options);

}  // namespace wiretape::detail
