#include <chrono>
#include <cstdint>
#include <limits>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

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

// Two commas with nothing between them, or one at either end, are a slip
// of the keyboard: refused, naming where (issue 38).
TEST(OptionsParse, AnEmptyMemberIsRefusedNamingItsPosition) {
  const std::pair<const char*, const char*> cases[] = {
      {"type=serial,,device=X", "an empty option at position 12 (nothing between the "
                                "commas at positions 11 and 12)"},
      {"type=serial, ,device=X", "an empty option at position 13"},
      {",type=serial", "an empty option at position 0 (nothing before the first comma)"},
      {"type=serial,,", "an empty option at position 12"},
  };
  for (const auto& [text, message] : cases) {
    try {
      Options::parse(text);
      ADD_FAILURE() << text << " was accepted";
    } catch (const OptionError& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(Options::parse("type=serial, device=X").entries().size(), 2u)
      << "spaces beside a comma are no member";
  EXPECT_EQ(Options::parse("type=serial,device=X,").entries().size(), 2u)
      << "a comma at the end ends the last member";
}

// Options of one port type, as open_port() hands them to the type's
// constructor.
Options of_type(const std::string& type, const std::string& text) {
  auto options = Options::parse(text);
  options.set_port_type(type);
  return options;
}

TEST(OptionsTake, TypedValuesAndErrors) {
  auto options = of_type("serial", "exclusive=yes,fsync=off,baud=42,timeout=none,parity=even");
  EXPECT_TRUE(options.take_bool("exclusive"));
  EXPECT_FALSE(options.take_bool("fsync"));
  EXPECT_EQ(options.take_int("baud"), 42);
  EXPECT_EQ(options.take_timeout("timeout"), wiretape::forever);
  EXPECT_EQ(options.take_choice("parity"), "even");
  EXPECT_NO_THROW(options.finish("serial"));
  auto replay = of_type("replay", "speed=2.5");
  EXPECT_DOUBLE_EQ(replay.take_double("speed"), 2.5);
}

TEST(OptionsTake, BadValueNamesKeyAndValid) {
  auto options = of_type("serial", "parity=sometimes");
  try {
    options.take_choice("parity");
    FAIL();
  } catch (const OptionError& e) {
    EXPECT_EQ(e.key(), "parity");
    EXPECT_NE(std::string(e.what()).find("none, even, odd, mark, space"), std::string::npos)
        << e.what();
  }
}

TEST(OptionsFinish, UnknownAndInapplicableKeysAreErrors) {
  auto unknown = Options::parse("zzzz=9600");  // near no key: the valid ones are listed
  unknown.take("device");
  try {
    unknown.finish("serial");
    FAIL();
  } catch (const OptionError& e) {
    EXPECT_EQ(e.key(), "zzzz");
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

// A required key typed wrong is the mistake to name, not the key it left
// missing (issue 38).
TEST(OptionsTake, AMissingRequiredKeyNamesItsTypo) {
  const std::tuple<const char*, const char*, const char*, const char*> cases[] = {
      {"serial", "devcie=/dev/ttyUSB0", "device", "devcie"},
      {"tcp", "host=localhost,prot=5000", "port", "prot"},
  };
  for (const auto& [type, text, required, typo] : cases) {
    auto options = of_type(type, text);
    try {
      if (std::string(required) == "port") {
        options.take_int(required);
      } else {
        options.take_required(required);
      }
      ADD_FAILURE() << text << " was accepted";
    } catch (const OptionError& e) {
      EXPECT_EQ(e.key(), typo);
      EXPECT_EQ(std::string(e.what()), "unknown option '" + std::string(typo) + "' for type=" +
                                           type + "; did you mean '" + required + "'?");
    }
  }
  // no typo of it given: the key is missing, as before
  auto missing = of_type("serial", "baud=9600");
  try {
    missing.take_required("device");
    ADD_FAILURE();
  } catch (const OptionError& e) {
    EXPECT_NE(std::string(e.what()).find("missing option 'device' for type=serial"),
              std::string::npos) << e.what();
  }
}

TEST(OptionsAlias, OldNameMapsAndBothIsError) {
  auto options = of_type("tcp", "ip=10.0.0.1");
  options.alias("ip", "host");
  EXPECT_EQ(options.take_string("host"), "10.0.0.1");
  auto both = Options::parse("ip=1,host=2");
  EXPECT_THROW(both.alias("ip", "host"), OptionError);
}

TEST(OptionsTake, TimeoutSpellings) {
  for (const char* spelling : {"-1", "none", "forever", "NONE"}) {
    auto options = of_type("tcp", std::string("timeout=") + spelling);
    EXPECT_EQ(options.take_timeout("timeout"), wiretape::forever) << spelling;
  }
  EXPECT_EQ(of_type("tcp", "timeout=0").take_timeout("timeout"), std::chrono::nanoseconds(0));
  EXPECT_EQ(of_type("tcp", "timeout=1.5").take_timeout("timeout"),
            std::chrono::nanoseconds(1'500'000'000));
  EXPECT_EQ(of_type("tcp", "").take_timeout("timeout"), wiretape::forever)
      << "the table's default, -1";
  for (const char* bad : {"-0.5", "soon", "", "1s", "inf", "nan"}) {
    auto one = of_type("tcp", std::string("timeout=\"") + bad + "\"");
    try {
      one.take_timeout("timeout");
      ADD_FAILURE() << "accepted timeout=" << bad;
    } catch (const OptionError& e) {
      EXPECT_EQ(e.key(), "timeout");
    }
  }
}

TEST(OptionsTake, BooleansAcceptEverySpellingInAnyCase) {
  for (const char* spelling : {"TRUE", "Yes", "ON", "1", "true", "on"}) {
    EXPECT_EQ(wiretape::parse_bool(spelling), true) << spelling;
    EXPECT_TRUE(of_type("tcp", std::string("listen=") + spelling).take_bool("listen"));
  }
  for (const char* spelling : {"No", "0", "off", "FALSE", "false", "no"}) {
    EXPECT_EQ(wiretape::parse_bool(spelling), false) << spelling;
    EXPECT_FALSE(of_type("tcp", std::string("nodelay=") + spelling).take_bool("nodelay"));
  }
  EXPECT_TRUE(of_type("tcp", "listen").take_bool("listen")) << "a bare key means 1";
  EXPECT_FALSE(of_type("tcp", "").take_bool("listen")) << "the table's default";
  EXPECT_TRUE(of_type("tcp", "").take_bool("nodelay")) << "the table's default";
  for (const char* bad : {"2", "", "maybe", "y"}) {
    EXPECT_EQ(wiretape::parse_bool(bad), std::nullopt) << bad;
  }
  auto bad = of_type("tcp", "listen=2");
  try {
    bad.take_bool("listen");
    FAIL();
  } catch (const OptionError& e) {
    EXPECT_EQ(e.key(), "listen");
    EXPECT_NE(std::string(e.what()).find("not a boolean"), std::string::npos) << e.what();
  }
}

TEST(OptionsTake, IntegersRejectTrailingTextAndRange) {
  for (const char* bad : {"12abc", "", "1.5", "99999999999999999999", "-1", "9"}) {
    auto options = of_type("serial", std::string("databits=\"") + bad + "\"");
    try {
      options.take_int("databits");
      ADD_FAILURE() << "accepted databits=" << bad;
    } catch (const OptionError& e) {
      EXPECT_EQ(e.key(), "databits");
      EXPECT_NE(std::string(e.what()).find("5 to 8"), std::string::npos) << e.what();
    }
  }
}

TEST(OptionsTake, PrefixedKeysAreCollected) {
  auto options = of_type("loopback", "meta_robot=r2,meta_site=\"lab 3\",other=1");
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

TEST(OptionString, ValuesAreQuotedAndNumbersWrittenByOneRule) {
  using Pairs = std::vector<std::pair<std::string, wiretape::OptionValue>>;
  EXPECT_EQ(wiretape::option_string(Pairs{{"type", std::string("replay")},
                                          {"file", std::string("/a b/s.wtape")},
                                          {"speed", 2.0},
                                          {"gap", 0.25},
                                          {"jitter", 1e-6},
                                          {"seed", std::int64_t{-7}},
                                          {"fsync", true},
                                          {"restart", false}}),
            "type=replay,file=\"/a b/s.wtape\",speed=2,gap=0.25,jitter=1e-06,seed=-7,"
            "fsync=true,restart=false");
  EXPECT_EQ(wiretape::option_string(Pairs{}), "");
}

TEST(OptionString, ParseGivesThePairsBack) {
  const std::vector<std::string> values = {"", "a,b", "k=v", "say \"x\"", "back\\slash",
                                           "tab\tnew\nline", "caf\xc3\xa9 \xe2\x9c\x93", "=,\"\\"};
  std::vector<std::pair<std::string, wiretape::OptionValue>> pairs;
  for (std::size_t i = 0; i < values.size(); ++i) {
    pairs.emplace_back("meta_" + std::to_string(i), values[i]);
  }
  const auto entries = wiretape::parse_options(wiretape::option_string(pairs));
  ASSERT_EQ(entries.size(), values.size());
  for (std::size_t i = 0; i < values.size(); ++i) {
    EXPECT_EQ(entries[i].key, "meta_" + std::to_string(i));
    EXPECT_EQ(entries[i].value, values[i]) << i;
  }
}

TEST(OptionString, ABadKeyOrValueIsAnOptionErrorNamingTheKey) {
  using Pairs = std::vector<std::pair<std::string, wiretape::OptionValue>>;
  const std::vector<std::string> keys = {"", "a,b", "a b", "a=b", "say\"", std::string("n\0l", 3)};
  for (const std::string& key : keys) {
    try {
      wiretape::option_string(Pairs{{key, std::string("v")}});
      FAIL() << "no OptionError for key " << key;
    } catch (const OptionError& error) {
      EXPECT_EQ(error.key(), key);
      EXPECT_NE(std::string(error.what()).find("is not a key"), std::string::npos);
    }
  }
  try {
    wiretape::option_string(Pairs{{"speed", 1.0}, {"speed", 2.0}});
    FAIL() << "no OptionError for a key given twice";
  } catch (const OptionError& error) {
    EXPECT_EQ(error.key(), "speed");
  }
  EXPECT_THROW(wiretape::option_string(Pairs{{"gap", std::numeric_limits<double>::infinity()}}),
               OptionError);
  EXPECT_THROW(wiretape::option_string(Pairs{{"log", std::string("a\0b", 3)}}), OptionError);
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

TEST(DeviceOptions, AnRfc2217UrlMeansTheRfc2217PortType) {
  EXPECT_EQ(wiretape::device_options("rfc2217://lab-pi:2000"),
            "type=rfc2217,host=lab-pi,port=2000");
  EXPECT_EQ(wiretape::device_options(" rfc2217://[::1]:7000 "),
            "type=rfc2217,host=::1,port=7000");
  for (const char* bad : {"rfc2217://lab-pi", "rfc2217://:2000", "rfc2217://lab-pi:20x0",
                          "rfc2217://[::1:7000", "rfc2217://lab-pi:2000/ttyUSB0"}) {
    try {
      wiretape::device_options(bad);
      FAIL() << bad << ": no OptionError";
    } catch (const OptionError& error) {
      EXPECT_EQ(error.key(), "device");
      EXPECT_NE(std::string(error.what()).find(bad), std::string::npos) << error.what();
      EXPECT_NE(std::string(error.what()).find("rfc2217://HOST:PORT"), std::string::npos);
    }
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
  // A generous bound for a loaded CI machine under ASan (5.8 s was seen
  // there at a load of 6): linear parsing takes about a tenth of a second
  // in a plain build, the old quadratic lookup over ten seconds for half
  // as many pairs, so four times that for these.
  EXPECT_LT(elapsed, std::chrono::seconds(20))
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

// The key table (DESIGN.md section 17, "Options"): every key of every port
// type once, with what its value may be.
TEST(OptionKeys, EveryPortTypeHasItsKeysAndCommonKeysApplyToAll) {
  for (auto type : wiretape::port_types()) {
    for (const char* common : {"type", "timeout", "access", "log", "flush_ms", "debug"}) {
      const auto* key = wiretape::find_option_key(common, type);
      ASSERT_NE(key, nullptr) << common << " for " << type;
    }
  }
  EXPECT_EQ(wiretape::find_option_key("baud", "serial")->default_value, "9600");
  EXPECT_EQ(wiretape::find_option_key("baud", "tcp"), nullptr);
  EXPECT_TRUE(wiretape::find_option_key("port", "tcp")->required);
  EXPECT_FALSE(wiretape::find_option_key("port", "udp")->required);
  EXPECT_EQ(wiretape::find_option_key("ip", "tcp")->alias_of, "host");
  EXPECT_EQ(wiretape::find_option_key("meta_robot", "pty")->name, "meta_");
  EXPECT_EQ(wiretape::find_option_key("meta_", "pty"), nullptr) << "a prefix needs a KEY";
  EXPECT_EQ(wiretape::find_option_key("at_end", "replay")->flag, "--at-end");
}

TEST(OptionKeys, EveryDefaultIsAValidValueOfItsRow) {
  for (const auto& key : wiretape::option_keys()) {
    if (key.default_value.empty() || key.alias_of.size()) continue;
    for (auto type : key.port_types) {
      auto options = Options::parse("");
      options.set_port_type(type);
      using wiretape::OptionType;
      SCOPED_TRACE(std::string(key.name) + " of " + std::string(type));
      switch (key.type) {
        case OptionType::boolean: EXPECT_NO_THROW(options.take_bool(key.name)); break;
        case OptionType::integer: EXPECT_NO_THROW(options.take_int(key.name)); break;
        case OptionType::number: EXPECT_NO_THROW(options.take_double(key.name)); break;
        case OptionType::seconds: EXPECT_NO_THROW(options.take_timeout(key.name)); break;
        case OptionType::choice:
          EXPECT_EQ(options.take_choice(key.name), key.default_value);
          break;
        case OptionType::text:
        case OptionType::path:
          EXPECT_EQ(options.take_string(key.name), key.default_value);
          break;
      }
    }
  }
}

TEST(OptionKeys, RowsAreWellFormed) {
  for (const auto& key : wiretape::option_keys()) {
    SCOPED_TRACE(std::string(key.name));
    EXPECT_FALSE(key.help.empty());
    EXPECT_FALSE(key.port_types.empty());
    EXPECT_EQ(key.type == wiretape::OptionType::choice, !key.choices.empty());
    if (key.type == wiretape::OptionType::integer) EXPECT_LE(key.min_integer, key.max_integer);
    if (key.type == wiretape::OptionType::number || key.type == wiretape::OptionType::seconds) {
      EXPECT_LT(key.min_number, key.max_number);
    }
    if (!key.alias_of.empty()) {
      // seriallog's file is log of serial, the type it opens.
      for (auto type : key.port_types) {
        const std::string opened(type.substr(0, type.size() - (type.size() > 3 &&
                                                                type.substr(type.size() - 3) == "log"
                                                                ? 3 : 0)));
        EXPECT_NE(wiretape::find_option_key(key.alias_of, opened), nullptr) << type;
      }
    }
    for (auto type : key.port_types) {
      EXPECT_EQ(wiretape::find_option_key(key.name, type) == &key ||
                    key.prefix,
                true)
          << "a key is listed once per port type: " << type;
    }
  }
}

TEST(OptionKeys, ParityAndFlowSpellingsAreThePortNames) {
  using wiretape::Parity;
  for (Parity parity : {Parity::none, Parity::even, Parity::odd, Parity::mark, Parity::space}) {
    EXPECT_EQ(wiretape::parse_parity(wiretape::to_string(parity)), parity);
  }
  EXPECT_EQ(wiretape::parse_parity("EVEN"), Parity::even);
  EXPECT_EQ(wiretape::parse_parity("e"), std::nullopt);
  EXPECT_EQ(wiretape::parse_flow_control("RtsCts"), wiretape::FlowControl::rtscts);
  EXPECT_EQ(wiretape::parse_flow_control("hardware"), std::nullopt);
  const auto& parity_choices = wiretape::find_option_key("parity", "serial")->choices;
  ASSERT_EQ(parity_choices.size(), 5u);
  for (auto choice : parity_choices) EXPECT_TRUE(wiretape::parse_parity(choice)) << choice;
}

TEST(OptionKeys, RequiredKeysMissingNameTheKeyAndType) {
  auto options = of_type("tcp", "host=h");
  try {
    options.take_int("port");
    FAIL();
  } catch (const OptionError& e) {
    EXPECT_EQ(e.key(), "port");
    EXPECT_NE(std::string(e.what()).find("missing option 'port' for type=tcp"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(of_type("udp", "").take_int("port"), 0) << "udp's port is not required";
}

TEST(OptionKeys, ReadingAKeyOutsideTheTableIsAProgrammingError) {
  auto options = of_type("serial", "colour=blue");
  EXPECT_THROW(options.take_bool("colour"), std::logic_error);
  EXPECT_THROW(options.take_int("parity"), std::logic_error) << "parity is a choice";
  EXPECT_THROW(options.take_bool("listen"), std::logic_error) << "listen is tcp's";
}

TEST(OptionKeys, SuggestionsComeFromTheKeysOfTheType) {
  EXPECT_EQ(wiretape::suggest_key("bod", "serial"), "baud");
  EXPECT_EQ(wiretape::suggest_key("buad", "serial"), "baud") << "a swap is one edit";
  EXPECT_EQ(wiretape::suggest_key("BAUD", "serial"), "baud");
  EXPECT_EQ(wiretape::suggest_key("timign", "replay"), "timing");
  EXPECT_EQ(wiretape::suggest_key("at-end", "replay"), "at_end");
  EXPECT_EQ(wiretape::suggest_key("colour", "serial"), std::nullopt);
  EXPECT_NE(wiretape::suggest_key("bod", "tcp"), "baud") << "baud is serial's";
  EXPECT_EQ(wiretape::suggest_key("lisen", "tcp"), "listen");
  EXPECT_EQ(wiretape::suggest_key("xy", "tcp"), std::nullopt);
}

TEST(OptionsFinish, AnUnknownKeyNearAValidOneSaysDidYouMean) {
  auto options = of_type("serial", "device=/dev/ttyS0,bud=9600");
  options.take_required("device");
  try {
    options.finish("serial");
    FAIL();
  } catch (const OptionError& e) {
    EXPECT_EQ(e.key(), "bud");
    EXPECT_NE(std::string(e.what()).find("did you mean 'baud'?"), std::string::npos) << e.what();
    // the suggestion alone: no list of every key to read through
    EXPECT_EQ(std::string(e.what()).find("valid keys"), std::string::npos) << e.what();
  }
}

TEST(ParseOptions, PairsInOrderWithTheParsersErrors) {
  const auto pairs = wiretape::parse_options(R"(type=tcp, host="a b",listen)");
  ASSERT_EQ(pairs.size(), 3u);
  EXPECT_EQ(pairs[1].key, "host");
  EXPECT_EQ(pairs[1].value, "a b");
  EXPECT_EQ(pairs[2].value, "1");
  EXPECT_THROW(wiretape::parse_options("a=1,a=2"), OptionError);
}
