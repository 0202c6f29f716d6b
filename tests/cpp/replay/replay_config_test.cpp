// src/replay/replay_config.cpp: the keys of type=replay parsed once into a
// ReplayConfig: defaults, every key, flexiport's spellings, and the errors
// that name the key at fault.
#include <gtest/gtest.h>

#include <chrono>
#include <string>

#include "replay/replay_config.hpp"
#include "support/replay_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"
#include "wiretape/port.hpp"

using namespace wiretape;
using namespace std::chrono_literals;
using namespace wiretape::test::replay_support;
using wiretape::detail::ReplayConfig;

namespace {

// The OptionError `keys` raise; fails the test when they are accepted.
OptionError refusal_of(const std::string& keys) {
  try {
    config_from(keys);
  } catch (const OptionError& error) {
    return error;
  }
  ADD_FAILURE() << keys << " was accepted";
  return OptionError("", "");
}

bool says(const OptionError& error, const std::string& words) {
  return std::string(error.what()).find(words) != std::string::npos;
}

}  // namespace

// --- parsing -------------------------------------------------------------------------------

TEST(ReplayOptions, DefaultsFollowTheDesign) {
  const ReplayConfig config = config_from("");
  EXPECT_EQ(config.timing, detail::ReplayTiming::causal);
  EXPECT_EQ(config.check, detail::ReplayCheck::data);
  EXPECT_EQ(config.match, detail::ReplayMatch::sequence);
  EXPECT_EQ(config.unmatched, detail::ReplayUnmatched::error);
  EXPECT_EQ(config.repeat, detail::ReplayRepeat::none);
  EXPECT_EQ(config.unused, detail::ReplayUnused::warn);
  EXPECT_EQ(config.at_end, detail::ReplayAtEnd::silent);
  EXPECT_EQ(config.tolerance, 100ms);
  EXPECT_DOUBLE_EQ(config.speed, 1.0);
}

TEST(ReplayOptions, EveryKeyIsParsed) {
  const ReplayConfig config = config_from(
      "timing=session,speed=2.5,check=timing,tolerance=20,match=request,"
      "unmatched=silent,repeat=cycle,unused=error,at_end=closed");
  EXPECT_EQ(config.timing, detail::ReplayTiming::session);
  EXPECT_DOUBLE_EQ(config.speed, 2.5);
  EXPECT_EQ(config.check, detail::ReplayCheck::timing);
  EXPECT_EQ(config.tolerance, 20ms);
  EXPECT_EQ(config.match, detail::ReplayMatch::request);
  EXPECT_EQ(config.unmatched, detail::ReplayUnmatched::silent);
  EXPECT_EQ(config.repeat, detail::ReplayRepeat::cycle);
  EXPECT_EQ(config.unused, detail::ReplayUnused::error);
  EXPECT_EQ(config.at_end, detail::ReplayAtEnd::closed);
  EXPECT_EQ(config_from("repeat=last").repeat, detail::ReplayRepeat::last);
  EXPECT_EQ(config_from("unused=ignore").unused, detail::ReplayUnused::ignore);
}

TEST(ReplayOptions, FlexiportSpellingsMapToTheNewKeys) {
  EXPECT_EQ(config_from("strictness=0").check, detail::ReplayCheck::off);
  EXPECT_EQ(config_from("strictness=1").check, detail::ReplayCheck::data);
  EXPECT_EQ(config_from("strictness=2").check, detail::ReplayCheck::timing);
  EXPECT_EQ(config_from("ignoretimes").timing, detail::ReplayTiming::none);
}

// flexiport documented jitter in ms but applied it in µs; µs it is.
TEST(ReplayOptions, JitterIsInMicroseconds) {
  EXPECT_EQ(config_from("jitter=1500").tolerance, 1500us);
  EXPECT_EQ(config_from("tolerance=1500").tolerance, 1500ms);
}

TEST(ReplayOptions, BadValuesNameTheKey) {
  for (const std::string keys :
       {"timing=fast", "speed=0", "speed=abc", "check=strict", "tolerance=-1",
        "match=any", "unmatched=ignore", "repeat=always", "unused=maybe",
        "at_end=open", "strictness=3", "jitter=-5"}) {
    const std::string key = keys.substr(0, keys.find('='));
    try {
      config_from(keys);
      ADD_FAILURE() << keys << " was accepted";
    } catch (const OptionError& error) {
      EXPECT_EQ(error.key(), key) << keys << ": " << error.what();
      EXPECT_NE(std::string(error.what()).find(key), std::string::npos);
    }
  }
}

TEST(ReplayOptions, CheckTimingWithoutAClockIsAnOptionError) {
  for (const std::string keys :
       {"check=timing,timing=none", "strictness=2,ignoretimes"}) {
    try {
      config_from(keys);
      ADD_FAILURE() << keys << " was accepted";
    } catch (const OptionError& error) {
      EXPECT_EQ(error.key(), "check") << error.what();
    }
  }
}

TEST(ReplayOptions, ContradictoryFlexiportSpellingsAreErrors) {
  EXPECT_THROW(config_from("check=data,strictness=1"), OptionError);
  EXPECT_THROW(config_from("tolerance=5,jitter=5"), OptionError);
  EXPECT_THROW(config_from("timing=causal,ignoretimes"), OptionError);
}

TEST(ReplayOptions, FileIsRequiredAndMustExist) {
  try {
    open_port("type=replay");
    ADD_FAILURE() << "replay without file was accepted";
  } catch (const OptionError& error) {
    EXPECT_EQ(error.key(), "file");
  }
  EXPECT_ANY_THROW(open_port("type=replay,file=/nonexistent/none.wtape"));
}

// --- errors the parser itself raises, by key ---------------------------------------------

// An empty file= is no file: refused as a missing one, saying what it takes.
TEST(ReplayOptions, AnEmptyFileNamesWhatItNeeds) {
  Options options = Options::parse("file=");
  try {
    detail::take_replay_config(options);
    FAIL() << "file= was accepted";
  } catch (const OptionError& error) {
    EXPECT_EQ(error.key(), "file");
    EXPECT_TRUE(says(error, "missing option 'file'")) << error.what();
    EXPECT_TRUE(says(error, ".wtape")) << error.what();
  }
}

TEST(ReplayOptions, EachContradictionNamesTheKeyAndTheOtherOne) {
  const OptionError times = refusal_of("timing=session,ignoretimes");
  EXPECT_EQ(times.key(), "ignoretimes");
  EXPECT_TRUE(says(times, "'timing=session'")) << times.what();
  // ignoretimes with timing=none says the same twice, and is no contradiction.
  EXPECT_EQ(config_from("timing=none,ignoretimes").timing, detail::ReplayTiming::none);
  const OptionError strictness = refusal_of("check=off,strictness=0");
  EXPECT_EQ(strictness.key(), "strictness");
  EXPECT_TRUE(says(strictness, "check=off|data|timing")) << strictness.what();
  const OptionError jitter = refusal_of("tolerance=1,jitter=1000");
  EXPECT_EQ(jitter.key(), "jitter");
  EXPECT_TRUE(says(jitter, "microseconds")) << jitter.what();
}

TEST(ReplayOptions, CheckTimingWithoutAClockSaysWhichTimingsHaveOne) {
  const OptionError error = refusal_of("check=timing,timing=none");
  EXPECT_TRUE(says(error, "timing=causal or timing=session")) << error.what();
  // strictness=2 is check=timing: it has a clock under either timing.
  EXPECT_EQ(config_from("strictness=2,timing=session").check, detail::ReplayCheck::timing);
}

TEST(ReplayOptions, AProfileAndADeclaredFramingTogetherAreRefused) {
  const OptionError error = refusal_of("profile=lines,framing=fixed:4");
  EXPECT_EQ(error.key(), "framing");
  EXPECT_TRUE(says(error, "not both")) << error.what();
}

TEST(ReplayOptions, FramingBySilenceNeedsMatchRequest) {
  const OptionError error = refusal_of("framing=gap:20");
  EXPECT_EQ(error.key(), "framing");
  EXPECT_TRUE(says(error, "match=request")) << error.what();
  EXPECT_NE(config_from("framing=gap:20,match=request").profile, nullptr);
}

TEST(ReplayOptions, AnUnknownProfileIsRefusedAtParse) {
  EXPECT_THROW(config_from("profile=no-such-profile"), OptionError);
  EXPECT_NE(config_from("profile=lines").profile, nullptr);
  EXPECT_EQ(config_from("").profile, nullptr);
}

// A bad fault plan fails when the replay is configured, before a session is
// opened.
TEST(ReplayOptions, ABadFaultPlanIsRefusedAtParseNamingFaults) {
  const OptionError error = refusal_of("faults=nonsense@nowhere");
  EXPECT_EQ(error.key(), "faults");
  EXPECT_TRUE(says(error, "nonsense@nowhere")) << error.what();
  EXPECT_TRUE(config_from("").faults.empty());
  EXPECT_FALSE(config_from("faults=drop@exchange:1,seed=7").faults.empty());
}

TEST(ReplayOptions, AKeyThatIsNoReplayKeyIsRefusedWithTheNearestOne) {
  Options options = Options::parse("file=x.wtape,timming=none");
  try {
    detail::take_replay_config(options);
    FAIL() << "timming= was accepted";
  } catch (const OptionError& error) {
    EXPECT_EQ(error.key(), "timming");
    EXPECT_TRUE(says(error, "timing")) << error.what();
  }
}

TEST(ReplayOptions, MillisecondKeysTakeFractionsToTheNanosecond) {
  EXPECT_EQ(config_from("tolerance=0.25").tolerance, 250us);
  EXPECT_EQ(config_from("match=request,gap=7.5").gap, 7500us);
  EXPECT_EQ(config_from("flush_wait=12").flush_wait, 12ms);
  EXPECT_EQ(config_from("").flush_wait, 200ms);
  EXPECT_EQ(config_from("channel=gps").channel, "gps");
  EXPECT_EQ(config_from("").channel, "");
}

// Empty records are datagrams only where nothing frames them.
TEST(ReplayOptions, EmptyRecordsAreDatagramsInASequenceReplayWithoutAProfile) {
  ReplayConfig config = config_from("");
  EXPECT_FALSE(detail::replays_empty_datagrams(config));
  config.datagrams = true;
  EXPECT_TRUE(detail::replays_empty_datagrams(config));
  ReplayConfig request = config_from("match=request");
  request.datagrams = true;
  EXPECT_FALSE(detail::replays_empty_datagrams(request));
  ReplayConfig profiled = config_from("profile=lines");
  profiled.datagrams = true;
  EXPECT_FALSE(detail::replays_empty_datagrams(profiled));
}

TEST(ReplayOptions, OnlyAReplayThatNothingTimesIsUntimed) {
  EXPECT_TRUE(detail::untimed_replay(config_from("timing=none"), /*recorded_flushes=*/false));
  // A recorded client flush gates rx for flush_wait: that wait is timed.
  EXPECT_FALSE(detail::untimed_replay(config_from("timing=none"), /*recorded_flushes=*/true));
  EXPECT_FALSE(detail::untimed_replay(config_from(""), false));
  EXPECT_FALSE(detail::untimed_replay(config_from("timing=session"), false));
  // match=request waits `gap` for a longer request.
  EXPECT_FALSE(detail::untimed_replay(config_from("timing=none,match=request"), false));
  ReplayConfig checked = config_from("timing=none");  // refused as keys, defended anyway
  checked.check = detail::ReplayCheck::timing;
  EXPECT_FALSE(detail::untimed_replay(checked, false));
  ReplayConfig faulted = config_from("timing=none");
  faulted.faults.faults.emplace_back();
  EXPECT_FALSE(detail::untimed_replay(faulted, false));
}
