// The session reader's view API (open_session_source): payloads handed out as
// views into the read buffers must stay intact while held, match what
// SessionReader returns, and be CRC-checked.
#include <gtest/gtest.h>

#include <cstddef>
#include <string>
#include <vector>

#include "session/buffered_file.hpp"
#include "session/format.hpp"
#include "session/reader.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/session.hpp"

using namespace wiretape;
using wiretape::detail::PayloadView;

namespace {

using wiretape::test::read_file;
using wiretape::test::TempDir;
using wiretape::test::write_file;

// Payload i: `size` bytes that differ from record to record.
std::string payload(std::size_t i, std::size_t size) {
  std::string bytes(size, '\0');
  for (std::size_t j = 0; j < size; ++j) {
    bytes[j] = static_cast<char>((i * 131 + j * 7) & 0xFF);
  }
  return bytes;
}

// Sizes across the view threshold and the read buffer, so that records
// straddle buffer refills.
std::vector<std::size_t> sizes() {
  std::vector<std::size_t> out;
  const std::size_t pattern[] = {4096, 1, 511, 512, 5000, 40000, 70000, 3000, 33000};
  for (int round = 0; round < 20; ++round) {
    for (std::size_t size : pattern) out.push_back(size);
  }
  return out;
}

void write_session(const std::string& path) {
  SessionHeader header;
  header.start_utc = "2026-01-02T03:04:05.000006Z";
  header.host = "testhost";
  header.wiretape_version = "9.9.9";
  SessionWriter writer(path, header);
  const auto all = sizes();
  for (std::size_t i = 0; i < all.size(); ++i) {
    writer.write(i % 3 == 2 ? RecordKind::tx : RecordKind::rx, i * 1000,
                 payload(i, all[i]));
  }
  writer.close();
}

TEST(SessionViews, HeldViewsStayIntactAndMatchTheReader) {
  TempDir dir;
  const std::string path = dir.file("mixed.wtape");
  write_session(path);
  SessionHeader header;
  auto cursor = detail::open_session_source(path, header);
  Record record;
  PayloadView view;
  // Every view kept until the end, with its record's number.
  std::vector<std::pair<std::size_t, PayloadView>> held;
  std::size_t count = 0;
  const auto all = sizes();
  while (cursor->next(record, view)) {
    ASSERT_LT(count, all.size());
    if (view) {
      EXPECT_TRUE(record.data.empty());
      EXPECT_GE(view.bytes.size(), detail::min_view_payload);
      held.emplace_back(count, view);
    } else {
      EXPECT_EQ(record.data, payload(count, all[count])) << "record " << count;
    }
    ++count;
  }
  EXPECT_FALSE(cursor->damage());
  EXPECT_EQ(count, all.size());
  std::size_t viewable = 0;
  for (std::size_t size : all) {
    if (size >= detail::min_view_payload &&
        size <= detail::BufferedFile::max_view_size()) {
      ++viewable;
    }
  }
  EXPECT_EQ(held.size(), viewable);
  EXPECT_GT(viewable, all.size() / 3);
  // The bytes are still right after the source went on through many refills.
  for (const auto& [index, kept] : held) {
    EXPECT_EQ(std::string(kept.bytes), payload(index, all[index])) << "record " << index;
  }
}

TEST(SessionViews, CorruptViewedPayloadStopsThereLikeTheReader) {
  TempDir dir;
  const std::string path = dir.file("bad.wtape");
  write_session(path);
  std::string bytes = read_file(path);
  const std::size_t header_end = 16 + detail::get_u32le(&bytes[12]) + 4;
  // Flip a byte inside the payload of record 3 (512 bytes: a view).
  std::size_t at = header_end;
  for (int i = 0; i < 3; ++i) at += 16 + detail::get_u32le(&bytes[at]) + 4;
  ASSERT_EQ(detail::get_u32le(&bytes[at]), 512u);
  bytes[at + 16 + 100] ^= 0x20;
  write_file(path, bytes);

  SessionHeader header;
  auto cursor = detail::open_session_source(path, header);
  Record record;
  PayloadView view;
  int count = 0;
  while (cursor->next(record, view)) ++count;
  EXPECT_EQ(count, 3);
  ASSERT_TRUE(cursor->damage());
  EXPECT_EQ(cursor->damage()->offset(), at);
  EXPECT_NE(std::string(cursor->damage()->what()).find("CRC32C"), std::string::npos);
  EXPECT_FALSE(view);

  SessionReader reader(path);
  int reader_count = 0;
  while (reader.next(record)) ++reader_count;
  EXPECT_EQ(reader_count, count);
  EXPECT_EQ(std::string(reader.damage()->what()), std::string(cursor->damage()->what()));
}

}  // namespace
