// The JSON reader and writer of header metadata and event payloads: the
// limits that keep hostile input harmless (nesting, UTF-8), and text that
// reads back as it was written.
#include <gtest/gtest.h>

#include <cstddef>
#include <optional>
#include <string>

#include "util/json.hpp"

namespace json = wiretape::detail::json;

namespace {

std::string nested(int levels) {
  return std::string(static_cast<std::size_t>(levels), '[') +
         std::string(static_cast<std::size_t>(levels), ']');
}

}  // namespace

TEST(JsonLimits, NestingUpToTheLimitParsesAndDeeperIsAnErrorWithItsOffset) {
  EXPECT_NO_THROW(json::parse(nested(json::max_nesting_depth)));
  const std::string deep = nested(50'000);
  try {
    json::parse(deep);
    FAIL() << "50,000 levels accepted";
  } catch (const json::ParseError& e) {
    EXPECT_EQ(e.offset(), static_cast<std::size_t>(json::max_nesting_depth));
    EXPECT_NE(std::string(e.what()).find("deeper than 64"), std::string::npos) << e.what();
  }
  const std::string objects = R"({"a":)" + nested(json::max_nesting_depth) + "}";
  EXPECT_THROW(json::parse(objects), json::ParseError);
}

TEST(JsonLimits, StringsMustBeValidUtf8) {
  EXPECT_EQ(json::parse("\"caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80\"").text,
            "caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80");
  EXPECT_EQ(json::parse(R"("\ud83d\ude00")").text, "\xf0\x9f\x98\x80");
  for (const std::string bad :
       {"\"\xff\"", "\"a\x80\"", "\"\xc3\"", "\"\xc0\xaf\"", "\"\xed\xa0\x80\"",
        "\"\xf4\x90\x80\x80\"", R"("\ud800")", R"("\udc00")", R"("\ud800\u0041")"}) {
    try {
      json::parse(bad);
      ADD_FAILURE() << "accepted " << ::testing::PrintToString(bad);
    } catch (const json::ParseError& e) {
      EXPECT_GE(e.offset(), 1u);
      EXPECT_LT(e.offset(), bad.size());
    }
  }
  try {
    json::parse("{\"k\":\"ok\xff\"}");
    FAIL();
  } catch (const json::ParseError& e) {
    EXPECT_EQ(e.offset(), 8u);
    EXPECT_NE(std::string(e.what()).find("UTF-8"), std::string::npos);
  }
}

TEST(JsonLimits, InvalidUtf8OffsetFindsTheFirstBadByte) {
  EXPECT_EQ(json::invalid_utf8_offset("plain \xc3\xa9"), std::nullopt);
  EXPECT_EQ(json::invalid_utf8_offset("ab\xff"), std::optional<std::size_t>(2));
  EXPECT_EQ(json::invalid_utf8_offset("\xe2\x82"), std::optional<std::size_t>(0));
}

TEST(JsonText, QuoteEscapesWhatJsonMustAndParseReadsItBack) {
  EXPECT_EQ(json::quote("a\"b\\c\n\r\t"), R"("a\"b\\c\n\r\t")");
  EXPECT_EQ(json::quote(std::string("\x01\x1f", 2)), R"("\u0001\u001f")");
  const std::string awkward = std::string("quote \" slash \\ nul ") + '\0' + " caf\xc3\xa9";
  EXPECT_EQ(json::parse(json::quote(awkward)).text, awkward);
}

TEST(JsonText, ObjectsKeepTheirKeysInFileOrderAndNumbersTheirText) {
  const json::Value value = json::parse(R"( {"z": 1.50, "a": [true, null], "m": "x"} )");
  ASSERT_TRUE(value.is_object());
  ASSERT_EQ(value.members.size(), 3u);
  EXPECT_EQ(value.members[0].first, "z");
  EXPECT_EQ(value.members[1].first, "a");
  EXPECT_EQ(value.find("z")->text, "1.50");
  EXPECT_DOUBLE_EQ(value.find("z")->number, 1.5);
  EXPECT_EQ(value.string_member("m"), std::optional<std::string>("x"));
  EXPECT_EQ(value.string_member("z"), std::nullopt);
  EXPECT_EQ(value.find("absent"), nullptr);
  EXPECT_EQ(json::serialize(value), R"({"z":1.50,"a":[true,null],"m":"x"})");
}

TEST(JsonText, ObjectWriterWritesItsKeysInTheOrderAdded) {
  json::ObjectWriter writer;
  writer.add("name", "port").add("open", true).add("count", -3).add_raw("raw", "[1]");
  EXPECT_EQ(writer.str(), R"({"name":"port","open":true,"count":-3,"raw":[1]})");
  EXPECT_EQ(json::ObjectWriter().str(), "{}");
}

TEST(JsonText, TextThatIsNotOneValueIsAnErrorWithItsOffset) {
  try {
    json::parse(R"({"a":1} x)");
    FAIL() << "trailing text accepted";
  } catch (const json::ParseError& e) {
    EXPECT_EQ(e.offset(), 8u) << e.what();
  }
  EXPECT_THROW(json::parse(""), json::ParseError);
  EXPECT_THROW(json::parse(R"({"a":})"), json::ParseError);
}
