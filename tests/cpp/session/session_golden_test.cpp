// Golden session files (tests/data/golden): each .wtape is read back as its
// .jsonl says, and the writer re-creates it byte for byte from the .jsonl
// (so a change of the byte layout cannot go unnoticed). See make_jsonl.py
// for the .jsonl layout; WIRETAPE_REGENERATE_GOLDEN=1 rewrites the .wtape
// files after a deliberate format change.
#include <unistd.h>

#include <gtest/gtest.h>

#include "support/port_test_support.hpp"

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "util/json.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/session.hpp"

using namespace wiretape;
namespace json = wiretape::detail::json;

namespace {

const std::string golden_dir = std::string(WIRETAPE_TEST_DATA_DIR) + "/golden/";

using wiretape::test::read_file;
using wiretape::test::write_file;

std::string from_hex(const std::string& hex) {
  std::string bytes;
  for (std::size_t i = 0; i + 1 < hex.size(); i += 2) {
    bytes.push_back(static_cast<char>(std::stoi(hex.substr(i, 2), nullptr, 16)));
  }
  return bytes;
}

struct Line {
  std::uint64_t t_ns = 0;
  int kind_code = 0;
  std::string data;
  bool skipped = false;
  bool readable = true;
  std::uint16_t channel = 0;
};

struct Golden {
  SessionHeader header;
  // Written as a Recorder writes: this much header room, channels added.
  std::optional<std::size_t> header_room;
  std::vector<Line> lines;
  std::optional<std::pair<std::size_t, int>> corrupt;  // byte, xor
  std::optional<std::uint64_t> damage_offset;
};

Golden load(const std::string& name) {
  std::ifstream in(golden_dir + name + ".jsonl");
  if (!in) throw std::runtime_error("cannot read " + name + ".jsonl");
  Golden golden;
  std::string text;
  while (std::getline(in, text)) {
    if (text.empty()) continue;
    const json::Value line = json::parse(text);
    if (const json::Value* header = line.find("header")) {
      SessionHeader& o = golden.header;
      o.port_options = header->string_member("port_options").value_or("");
      o.port_type = header->string_member("port_type").value_or("");
      o.start_utc = header->string_member("start_utc").value_or("");
      o.wiretape_version = header->string_member("wiretape_version").value_or("");
      o.host = header->string_member("host").value_or("");
      o.capture = header->string_member("capture") == "wire" ? Capture::wire : Capture::client;
      for (const auto& [key, value] : header->find("metadata")->members) {
        o.user_metadata[key] = value.text;
      }
      o.source_format = header->string_member("source_format").value_or("");
      if (const json::Value* files = header->find("source_files")) {
        for (const auto& item : files->items) o.source_files.push_back(item.text);
      }
      if (const json::Value* details = header->find("source_details")) {
        for (const auto& [key, value] : details->members) o.source_details[key] = value.text;
      }
      o.device_address = header->string_member("device_address").value_or("");
      if (const json::Value* edits = header->find("edits")) {
        for (const auto& item : edits->items) o.edits.push_back(item.text);
      }
      if (const json::Value* channels = header->find("channels")) {
        for (const auto& item : channels->items) {
          Channel& channel = o.channels.emplace_back();
          channel.id = static_cast<std::uint16_t>(item.find("id")->number);
          channel.name = item.string_member("name").value_or("");
          channel.port_options = item.string_member("port_options").value_or("");
          channel.port_type = item.string_member("port_type").value_or("");
          channel.capture =
              item.string_member("capture") == "wire" ? Capture::wire : Capture::client;
          channel.device_address = item.string_member("device_address").value_or("");
        }
      }
      if (const json::Value* room = line.find("header_room")) {
        golden.header_room = static_cast<std::size_t>(room->number);
      }
      continue;
    }
    if (const json::Value* corrupt = line.find("corrupt")) {
      golden.corrupt.emplace(static_cast<std::size_t>(corrupt->find("byte")->number),
                             static_cast<int>(corrupt->find("xor")->number));
      golden.damage_offset = static_cast<std::uint64_t>(line.find("damage_offset")->number);
      continue;
    }
    Line record;
    record.t_ns = std::stoull(line.find("t_ns")->text);
    if (const auto kind = line.string_member("kind")) {
      const auto known = record_kind_from_string(*kind);
      if (!known) throw std::runtime_error("unknown kind " + *kind + " in " + name);
      record.kind_code = static_cast<int>(*known);
    } else {
      record.kind_code = static_cast<int>(line.find("kind_code")->number);
    }
    record.data = from_hex(line.string_member("data_hex").value_or(""));
    if (const json::Value* skipped = line.find("skipped")) record.skipped = skipped->boolean;
    if (const json::Value* readable = line.find("readable")) record.readable = readable->boolean;
    if (const json::Value* channel = line.find("channel")) {
      record.channel = static_cast<std::uint16_t>(channel->number);
    }
    golden.lines.push_back(record);
  }
  return golden;
}

class GoldenFile : public ::testing::TestWithParam<std::string> {};

}  // namespace

TEST_P(GoldenFile, WriterRecreatesItByteForByte) {
  const Golden golden = load(GetParam());
  char pattern[] = "/tmp/wiretape-golden-XXXXXX";
  ASSERT_NE(::mkstemp(pattern), -1);
  const std::string path = pattern;
  {
    SessionHeader first = golden.header;
    first.channels.clear();
    SessionWriter writer(path, golden.header_room ? first : golden.header, FlushPolicy{},
                         golden.header_room.value_or(0));
    if (golden.header_room) {
      for (const Channel& channel : golden.header.channels) writer.add_channel(channel);
    }
    for (const Line& line : golden.lines) {
      writer.write(static_cast<RecordKind>(line.kind_code), line.t_ns, line.data, line.channel);
    }
  }
  std::string bytes = read_file(path);
  ::unlink(path.c_str());
  if (golden.corrupt) {
    ASSERT_LT(golden.corrupt->first, bytes.size());
    bytes[golden.corrupt->first] =
        static_cast<char>(bytes[golden.corrupt->first] ^ golden.corrupt->second);
  }
  const std::string golden_path = golden_dir + GetParam() + ".wtape";
  if (std::getenv("WIRETAPE_REGENERATE_GOLDEN") != nullptr) write_file(golden_path, bytes);
  EXPECT_EQ(bytes, read_file(golden_path))
      << "the writer no longer produces " << golden_path
      << " (a format change needs a new format version, see docs/session-format.md)";
}

namespace {

class ReadOnlyGoldenFile : public GoldenFile {};

void expect_reads_as_golden(const std::string& name, std::uint16_t version_minor) {
  const Golden golden = load(name);
  SessionReader reader(golden_dir + name + ".wtape");
  const SessionHeader& header = reader.header();
  EXPECT_EQ(header.version_major, 1);
  EXPECT_EQ(header.version_minor, version_minor);
  EXPECT_EQ(header.port_options, golden.header.port_options);
  EXPECT_EQ(header.port_type, golden.header.port_type);
  EXPECT_EQ(header.start_utc, golden.header.start_utc);
  EXPECT_EQ(header.wiretape_version, golden.header.wiretape_version);
  EXPECT_EQ(header.host, golden.header.host);
  EXPECT_EQ(header.capture, golden.header.capture);
  EXPECT_EQ(header.user_metadata, golden.header.user_metadata);
  EXPECT_EQ(header.source_format,
            golden.header.source_format.empty() ? "wiretape" : golden.header.source_format);
  EXPECT_EQ(header.source_files, golden.header.source_files);
  EXPECT_EQ(header.source_details, golden.header.source_details);
  EXPECT_EQ(header.device_address, golden.header.device_address);
  EXPECT_EQ(header.edits, golden.header.edits);
  ASSERT_EQ(header.channels.size(), golden.header.channels.size());
  for (std::size_t i = 0; i < header.channels.size(); ++i) {
    const Channel& got = header.channels[i];
    const Channel& want = golden.header.channels[i];
    EXPECT_EQ(got.id, want.id) << i;
    EXPECT_EQ(got.name, want.name) << i;
    EXPECT_EQ(got.port_options, want.port_options) << i;
    EXPECT_EQ(got.port_type, want.port_type) << i;
    EXPECT_EQ(got.capture, want.capture) << i;
    EXPECT_EQ(got.device_address, want.device_address) << i;
  }
  // The header room's padding is not part of the header's JSON.
  EXPECT_EQ(header.metadata_json.back(), '}');
  std::vector<Line> expected;
  for (const Line& line : golden.lines) {
    if (!line.skipped && line.readable) expected.push_back(line);
  }
  Record record;
  std::size_t index = 0;
  while (reader.next(record)) {
    ASSERT_LT(index, expected.size());
    EXPECT_EQ(record.t_ns, expected[index].t_ns) << index;
    EXPECT_EQ(static_cast<int>(record.kind), expected[index].kind_code) << index;
    EXPECT_EQ(record.data, expected[index].data) << index;
    EXPECT_EQ(record.channel, expected[index].channel) << index;
    ++index;
  }
  EXPECT_EQ(index, expected.size());
  ASSERT_EQ(reader.damage().has_value(), golden.damage_offset.has_value());
  if (golden.damage_offset) EXPECT_EQ(reader.damage()->offset(), *golden.damage_offset);
}

}  // namespace

TEST_P(GoldenFile, ReaderReturnsTheExpectedRecords) { expect_reads_as_golden(GetParam(), 3); }

// Files an older version of the format wrote: still read, no longer written.
// Each is named v1_MINOR.
TEST_P(ReadOnlyGoldenFile, ReaderReturnsTheExpectedRecords) {
  const std::string name = GetParam();
  expect_reads_as_golden(name, static_cast<std::uint16_t>(std::stoi(name.substr(3))));
}

INSTANTIATE_TEST_SUITE_P(Golden, GoldenFile,
                         ::testing::Values("all_kinds", "wire", "unknown_kind", "damaged",
                                           "v1_1_additions", "v1_2_channels"));
INSTANTIATE_TEST_SUITE_P(Golden, ReadOnlyGoldenFile, ::testing::Values("v1_0", "v1_1", "v1_2"));
