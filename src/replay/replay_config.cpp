#include "replay/replay_config.hpp"

#include <cmath>

#include "replay/profile.hpp"
#include "replay/faults.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

namespace {

template <typename Enum>
Enum pick(const std::string& value,
          std::initializer_list<std::pair<const char*, Enum>> choices) {
  for (const auto& [name, choice] : choices) {
    if (value == name) return choice;
  }
  return choices.begin()->second;  // take_choice already rejected the rest
}

}  // namespace

ReplayConfig take_replay_config(Options& options) {
  ReplayConfig config;
  options.set_port_type("replay");
  config.file = options.take_required("file");
  if (config.file.empty()) {
    throw OptionError("file",
                      "option 'file' needs a session file (a .wtape, or a "
                      "flexiport name.log for name.logr + name.logw)");
  }

  // timing, and flexiport's ignoretimes (= timing=none).
  const bool timing_given = options.has("timing");
  const std::string timing = options.take_choice("timing");
  const bool ignore_times = options.take_bool("ignoretimes");
  if (ignore_times && timing_given && timing != "none") {
    throw OptionError("ignoretimes",
                      "options 'ignoretimes' and 'timing=" + timing +
                          "' contradict each other: ignoretimes means "
                          "timing=none; give one of them");
  }
  config.timing = ignore_times ? ReplayTiming::none
                               : pick<ReplayTiming>(timing, {{"causal", ReplayTiming::causal},
                                                             {"none", ReplayTiming::none},
                                                             {"session", ReplayTiming::session}});
  config.speed = options.take_double("speed");

  // check, and flexiport's strictness=0|1|2.
  const bool check_given = options.has("check");
  const bool strictness_given = options.has("strictness");
  if (check_given && strictness_given) {
    throw OptionError("strictness",
                      "options 'check' and 'strictness' say the same thing "
                      "(strictness=0|1|2 is check=off|data|timing); give one");
  }
  const std::string check = options.take_choice("check");
  config.check = pick<ReplayCheck>(check, {{"data", ReplayCheck::data},
                                           {"off", ReplayCheck::off},
                                           {"timing", ReplayCheck::timing}});
  if (strictness_given) {
    const auto strictness = options.take_int("strictness");
    config.check = strictness == 0   ? ReplayCheck::off
                   : strictness == 1 ? ReplayCheck::data
                                     : ReplayCheck::timing;
  }

  // tolerance in milliseconds, and flexiport's jitter in microseconds (what
  // flexiport really applied, whatever its documentation said).
  const bool tolerance_given = options.has("tolerance");
  const bool jitter_given = options.has("jitter");
  if (tolerance_given && jitter_given) {
    throw OptionError("jitter",
                      "options 'tolerance' (milliseconds) and 'jitter' "
                      "(flexiport's, microseconds) say the same thing; give one");
  }
  const double tolerance_ms = options.take_double("tolerance");
  config.tolerance =
      jitter_given ? std::chrono::nanoseconds(options.take_int("jitter") * 1000)
                   : std::chrono::nanoseconds(
                         static_cast<std::int64_t>(std::llround(tolerance_ms * 1e6)));

  config.match = pick<ReplayMatch>(
      options.take_choice("match"),
      {{"sequence", ReplayMatch::sequence}, {"request", ReplayMatch::request}});
  config.unmatched = pick<ReplayUnmatched>(
      options.take_choice("unmatched"),
      {{"error", ReplayUnmatched::error}, {"silent", ReplayUnmatched::silent}});
  config.repeat = pick<ReplayRepeat>(
      options.take_choice("repeat"),
      {{"none", ReplayRepeat::none},
       {"last", ReplayRepeat::last},
       {"cycle", ReplayRepeat::cycle}});
  const double gap_ms = options.take_double("gap");
  config.gap = std::chrono::nanoseconds(static_cast<std::int64_t>(std::llround(gap_ms * 1e6)));
  const double flush_wait_ms = options.take_double("flush_wait");
  config.flush_wait =
      std::chrono::nanoseconds(static_cast<std::int64_t>(std::llround(flush_wait_ms * 1e6)));
  config.profile = take_profile(options);
  if (config.profile && config.match == ReplayMatch::sequence &&
      config.profile->make_framer(StreamDirection::tx)->quiet_gap()) {
    throw OptionError("framing",
                      "framing by silence (gap:MS) works with match=request only: in "
                      "match=sequence the client's last frame would never end");
  }
  config.unused = pick<ReplayUnused>(
      options.take_choice("unused"),
      {{"warn", ReplayUnused::warn},
       {"ignore", ReplayUnused::ignore},
       {"error", ReplayUnused::error}});
  config.at_end = pick<ReplayAtEnd>(
      options.take_choice("at_end"),
      {{"silent", ReplayAtEnd::silent}, {"closed", ReplayAtEnd::closed}});

  // Fault injection: parsed once, here, so that a bad plan fails at open.
  config.channel = options.take_string("channel");
  const std::string faults = options.take_string("faults");
  const auto seed = static_cast<std::uint64_t>(options.take_int("seed"));
  config.faults = parse_faults(faults, seed);

  if (config.check == ReplayCheck::timing &&
      config.timing == ReplayTiming::none) {
    throw OptionError(
        "check",
        "option 'check=timing' needs a clock to check against, but "
        "timing=none (or ignoretimes) replays without one; use "
        "timing=causal or timing=session, or check=data");
  }
  // Every other key was taken before (open_port takes the common ones
  // first): what is left is refused now, before the session is opened and a
  // replay exists whose closing would report unused data.
  options.finish("replay");
  return config;
}

}  // namespace wiretape::detail
