// Fuzzes the declared-profile spec parsers (framing=, ignore=, echo=,
// checksum=) and the framer and key of what parses: any text either parses
// or raises an OptionError naming its key; a parsed profile frames any bytes
// without crashing, covers them exactly, and keys and fixes its frames.
// Input: the spec text, a NUL, then bytes to frame.
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "replay/profiles/declared.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  const std::size_t split = input.find('\0');
  const std::string_view spec = input.substr(0, split);
  const std::string_view stream =
      split == std::string_view::npos ? std::string_view() : input.substr(split + 1);
  for (const char* key : {"ignore", "echo"}) {
    try {
      wiretape::detail::parse_fields(key, std::string(spec));
    } catch (const wiretape::OptionError& error) {
      if (error.key() != key) std::abort();
    }
  }
  try {
    wiretape::detail::parse_checksum(std::string(spec));
  } catch (const wiretape::OptionError& error) {
    if (error.key() != "checksum") std::abort();
  }
  std::shared_ptr<const wiretape::Profile> profile;
  try {
    wiretape::Options options = wiretape::Options::parse(spec);
    profile = wiretape::detail::take_declared_profile(options);
  } catch (const wiretape::OptionError&) {
    return 0;
  }
  if (!profile) return 0;
  auto framer = profile->make_framer(wiretape::StreamDirection::tx);
  std::vector<wiretape::Frame> frames;
  // 7 bytes every 5 ms: a framer that cuts by silence sees some gaps too.
  for (std::size_t at = 0; at < stream.size(); at += 7) {
    framer->feed_at(at * 5'000'000 / 7, stream.substr(at, 7), frames);
  }
  if (auto tail = framer->finish()) frames.push_back(std::move(*tail));
  std::size_t covered = 0;
  for (const wiretape::Frame& frame : frames) {
    covered += frame.bytes.size();
    profile->match_key(frame.bytes);
    profile->fix_response(frame.bytes, frame.bytes, frame.bytes);
    profile->field_name(wiretape::StreamDirection::tx, frame.bytes, frame.bytes.size() / 2);
  }
  if (covered != stream.size()) std::abort();
  return 0;
}
