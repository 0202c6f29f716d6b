#include <chrono>
#include <string>

#include <gtest/gtest.h>

#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"

using wiretape::OptionError;
using wiretape::Options;

TEST(OptionsParse, KeyValuePairsSeparatedByCommasAndSpace) {
  auto options = Options::parse("type=serial, device=/dev/ttyS0\tbaud=115200\ntimeout=1");
  ASSERT_EQ(options.entries().size(), 4u);
  EXPECT_EQ(options.peek("device").value(), "/dev/ttyS0");
  EXPECT_EQ(options.peek("baud").value(), "115200");
}

TEST(OptionsParse, BareKeyMeansOne) {
  auto options = Options::parse("type=serial,readonly");
  EXPECT_EQ(options.peek("readonly").value(), "1");
}

TEST(OptionsParse, QuotedValueKeepsSeparatorsAndEscapes) {
  auto options = Options::parse(R"(log="/home/me/My Runs/a,b.wtape",meta_note="say \"hi\"")");
  EXPECT_EQ(options.peek("log").value(), "/home/me/My Runs/a,b.wtape");
  EXPECT_EQ(options.peek("meta_note").value(), "say \"hi\"");
}

TEST(OptionsParse, RoundTripsThroughToString) {
  auto options = Options::parse(R"(type=tcp,log="a b",x="q\"\\")");
  auto again = Options::parse(options.to_string());
  ASSERT_EQ(again.entries().size(), options.entries().size());
  for (std::size_t i = 0; i < again.entries().size(); ++i) {
    EXPECT_EQ(again.entries()[i].key, options.entries()[i].key);
    EXPECT_EQ(again.entries()[i].value, options.entries()[i].value);
  }
}

TEST(OptionsParse, SyntaxErrorsNamePosition) {
  EXPECT_THROW(Options::parse("log=\"unterminated"), OptionError);
  EXPECT_THROW(Options::parse("=value"), OptionError);
  EXPECT_THROW(Options::parse("baud=1,baud=2"), OptionError);
  try {
    Options::parse("type=serial,log=\"abc");
    FAIL();
  } catch (const OptionError& e) {
    EXPECT_EQ(e.key(), "log");
    EXPECT_NE(std::string(e.what()).find("position 16"), std::string::npos) << e.what();
  }
}

TEST(OptionsTake, TypedValuesAndErrors) {
  auto options = Options::parse("a=yes,b=off,n=42,f=2.5,t=none,c=even");
  EXPECT_TRUE(options.take_bool("a", false));
  EXPECT_FALSE(options.take_bool("b", true));
  EXPECT_EQ(options.take_int("n", 0, 0, 100), 42);
  EXPECT_DOUBLE_EQ(options.take_double("f", 0, 0, 10), 2.5);
  EXPECT_EQ(options.take_timeout("t", std::chrono::seconds(1)), wiretape::forever);
  EXPECT_EQ(options.take_choice("c", "none", {"none", "even", "odd"}), "even");
  EXPECT_NO_THROW(options.finish("serial"));
}

TEST(OptionsTake, BadValueNamesKeyAndValid) {
  auto options = Options::parse("parity=sometimes");
  try {
    options.take_choice("parity", "none", {"none", "even", "odd"});
    FAIL();
  } catch (const OptionError& e) {
    EXPECT_EQ(e.key(), "parity");
    EXPECT_NE(std::string(e.what()).find("none, even, odd"), std::string::npos);
  }
}

TEST(OptionsFinish, UnknownAndInapplicableKeysAreErrors) {
  auto unknown = Options::parse("bod=9600");
  unknown.take("device");
  try {
    unknown.finish("serial");
    FAIL();
  } catch (const OptionError& e) {
    EXPECT_EQ(e.key(), "bod");
    EXPECT_NE(std::string(e.what()).find("unknown option"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("device"), std::string::npos);
  }
  auto inapplicable = Options::parse("baud=9600");
  inapplicable.take("host");
  try {
    inapplicable.finish("tcp");
    FAIL();
  } catch (const OptionError& e) {
    EXPECT_NE(std::string(e.what()).find("does not apply to type=tcp"), std::string::npos);
  }
}

TEST(OptionsAlias, OldNameMapsAndBothIsError) {
  auto options = Options::parse("ip=10.0.0.1");
  options.alias("ip", "host");
  EXPECT_EQ(options.take_string("host", ""), "10.0.0.1");
  auto both = Options::parse("ip=1,host=2");
  EXPECT_THROW(both.alias("ip", "host"), OptionError);
}

TEST(OptionsTake, TimeoutSpellings) {
  auto options = Options::parse("a=-1,b=none,c=forever,d=0,e=1.5,f=NONE");
  EXPECT_EQ(options.take_timeout("a", std::chrono::seconds(1)), wiretape::forever);
  EXPECT_EQ(options.take_timeout("b", std::chrono::seconds(1)), wiretape::forever);
  EXPECT_EQ(options.take_timeout("c", std::chrono::seconds(1)), wiretape::forever);
  EXPECT_EQ(options.take_timeout("d", wiretape::forever), std::chrono::nanoseconds(0));
  EXPECT_EQ(options.take_timeout("e", wiretape::forever),
            std::chrono::nanoseconds(1'500'000'000));
  EXPECT_EQ(options.take_timeout("f", std::chrono::seconds(1)), wiretape::forever);
  EXPECT_EQ(options.take_timeout("absent", std::chrono::seconds(2)),
            std::chrono::nanoseconds(std::chrono::seconds(2)));
  for (const char* bad : {"-0.5", "soon", "", "1s", "inf", "nan"}) {
    auto one = Options::parse(std::string("timeout=\"") + bad + "\"");
    try {
      one.take_timeout("timeout", wiretape::forever);
      ADD_FAILURE() << "accepted timeout=" << bad;
    } catch (const OptionError& e) {
      EXPECT_EQ(e.key(), "timeout");
    }
  }
}

TEST(OptionsTake, BooleansAcceptEverySpellingInAnyCase) {
  auto options = Options::parse("a=TRUE,b=No,c=ON,d=0,e=Yes,f=off,g");
  EXPECT_TRUE(options.take_bool("a", false));
  EXPECT_FALSE(options.take_bool("b", true));
  EXPECT_TRUE(options.take_bool("c", false));
  EXPECT_FALSE(options.take_bool("d", true));
  EXPECT_TRUE(options.take_bool("e", false));
  EXPECT_FALSE(options.take_bool("f", true));
  EXPECT_TRUE(options.take_bool("g", false)) << "a bare key means 1";
  auto bad = Options::parse("listen=2");
  EXPECT_THROW(bad.take_bool("listen", false), OptionError);
}

TEST(OptionsTake, IntegersRejectTrailingTextAndRange) {
  for (const char* bad : {"12abc", "", "1.5", "99999999999999999999", "-1"}) {
    auto options = Options::parse(std::string("n=\"") + bad + "\"");
    try {
      options.take_int("n", 0, 0, 100);
      ADD_FAILURE() << "accepted n=" << bad;
    } catch (const OptionError& e) {
      EXPECT_EQ(e.key(), "n");
      EXPECT_NE(std::string(e.what()).find("0 to 100"), std::string::npos);
    }
  }
}

TEST(OptionsTake, PrefixedKeysAreCollected) {
  auto options = Options::parse("meta_robot=r2,meta_site=\"lab 3\",other=1");
  const auto meta = options.take_prefixed("meta_");
  ASSERT_EQ(meta.size(), 2u);
  EXPECT_EQ(meta.at("robot"), "r2");
  EXPECT_EQ(meta.at("site"), "lab 3");
  EXPECT_THROW(options.finish("loopback"), OptionError) << "'other' is left";
}

TEST(OptionsQuote, QuotesOnlyWhatNeedsIt) {
  EXPECT_EQ(wiretape::quote_option_value("plain"), "plain");
  EXPECT_EQ(wiretape::quote_option_value("/dev/ttyUSB0"), "/dev/ttyUSB0");
  EXPECT_EQ(wiretape::quote_option_value("a b"), "\"a b\"");
  EXPECT_EQ(wiretape::quote_option_value("a,b"), "\"a,b\"");
  EXPECT_EQ(wiretape::quote_option_value("a\tb\r\n"), "\"a\tb\r\n\"");
  EXPECT_EQ(wiretape::quote_option_value("k=v"), "\"k=v\"");
  EXPECT_EQ(wiretape::quote_option_value(""), "\"\"");
  EXPECT_EQ(wiretape::quote_option_value("say \"x\""), "\"say \\\"x\\\"\"");
  EXPECT_EQ(wiretape::quote_option_value("C:\\x"), "\"C:\\\\x\"");
}

TEST(OptionsQuote, ParseGivesTheQuotedValueBack) {
  for (const std::string value :
       {"plain", "/home/me/My Runs/a.wtape", "a,b=c", "", "say \"x\"", "back\\slash",
        "tab\tand\nnewline", "\"\\\""}) {
    const auto options = Options::parse("log=" + wiretape::quote_option_value(value));
    EXPECT_EQ(options.peek("log"), value) << value;
  }
}

TEST(DeviceOptions, ABarePathMeansASerialDevice) {
  EXPECT_EQ(wiretape::device_options("/dev/ttyUSB0"),
            "type=serial,device=/dev/ttyUSB0");
  EXPECT_EQ(wiretape::device_options("  /dev/My Port\n"),
            "type=serial,device=\"/dev/My Port\"");
  EXPECT_EQ(wiretape::device_options("type=tcp,port=5000"), "type=tcp,port=5000");
  EXPECT_EQ(wiretape::device_options(" type=loopback "), "type=loopback");
}

TEST(DeviceOptions, AnEmptySettingNamesTheProblem) {
  try {
    wiretape::device_options(" \t");
    FAIL() << "no OptionError";
  } catch (const OptionError& error) {
    EXPECT_EQ(error.key(), "device");
    EXPECT_NE(std::string(error.what()).find("empty"), std::string::npos);
  }
}

TEST(OptionsAlias, AliasIsListedAmongValidKeys) {
  auto options = Options::parse("colour=1");
  options.alias("ip", "host");
  options.take("host");
  try {
    options.finish("tcp");
    FAIL();
  } catch (const OptionError& e) {
    EXPECT_NE(std::string(e.what()).find("ip"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("host"), std::string::npos);
  }
}

// Parsing must stay linear in the number of pairs: a long generated option
// string (100k meta_ keys) once took seconds because every key was looked up
// by scanning all the keys before it.
TEST(OptionsParse, ManyPairsParseInLinearTime) {
  constexpr int pairs = 200'000;
  std::string text = "type=loopback";
  for (int i = 0; i < pairs; ++i) {
    text += ",meta_k" + std::to_string(i) + "=v" + std::to_string(i);
  }
  const auto start = std::chrono::steady_clock::now();
  auto options = Options::parse(text);
  options.take("type");
  const auto metadata = options.take_prefixed("meta_");
  options.finish("loopback");
  const auto again = Options::parse(options.to_string());
  const auto elapsed = std::chrono::steady_clock::now() - start;
  EXPECT_EQ(metadata.size(), static_cast<std::size_t>(pairs));
  EXPECT_EQ(again.entries().size(), static_cast<std::size_t>(pairs + 1));
  EXPECT_EQ(again.peek("meta_k199999").value_or(""), "v199999");
  // A generous bound for a loaded CI machine: linear parsing takes about a
  // tenth of a second here, the old quadratic lookup over ten seconds for
  // half as many pairs.
  EXPECT_LT(elapsed, std::chrono::seconds(5))
      << std::chrono::duration_cast<std::chrono::milliseconds>(elapsed).count() << " ms";
}

// A NUL byte would silently cut a path where it reaches the OS (log=a\0b
// opens "a"): no value or key may hold one.
TEST(OptionsParse, NulByteIsRejectedNamingTheKey) {
  using namespace std::string_literals;
  for (const std::string& text :
       {"type=loopback,log=a\0b.wtape"s, "type=loopback,log=\"a\0b\""s}) {
    try {
      Options::parse(text);
      FAIL() << "accepted a NUL byte";
    } catch (const OptionError& e) {
      EXPECT_EQ(e.key(), "log");
      EXPECT_NE(std::string(e.what()).find("NUL"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("'log'"), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(Options::parse("type=loopback,lo\0g=x"s), OptionError);
  Options options;
  EXPECT_THROW(options.set("log", "a\0b"s), OptionError);
}
