// Chunking independence: any split of the same byte streams replays the
// same, checked with seeded random splits over synthetic and real sessions;
// and the real Hokuyo recordings replayed in request mode to a client that
// speaks in its own order.
#include <gtest/gtest.h>

#include <chrono>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "session/record_source.hpp"
#include "support/port_test_support.hpp"
#include "replay/replay_config.hpp"
#include "replay/replay_port.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

using namespace wiretape;
using namespace std::chrono_literals;

namespace {

const std::string kFlexiportDir = std::string(WIRETAPE_TEST_DATA_DIR) + "/flexiport/";

std::unique_ptr<Port> replay(std::vector<Record> records, const std::string& keys) {
  Options options = Options::parse("file=synthetic.wtape," + keys);
  detail::ReplayConfig config = detail::take_replay_config(options);
  auto port = detail::open_replay_session(
      config, detail::vector_source_factory(std::move(records)));
  port->set_timeout(10s);
  return port;
}

std::string stream_of(const std::vector<Record>& records, RecordKind kind) {
  std::string bytes;
  for (const Record& record : records) {
    if (record.kind == kind) bytes += record.data;
  }
  return bytes;
}

// A random command/response session: greeting, exchanges, unprompted rx.
std::vector<Record> synthetic_session(std::mt19937& random) {
  std::vector<Record> records;
  std::uint64_t t = 0;
  auto bytes = [&](std::size_t max) {
    std::string data(std::uniform_int_distribution<std::size_t>(1, max)(random), '\0');
    for (char& c : data) c = static_cast<char>(random() & 0xff);
    return data;
  };
  if (random() % 2) records.push_back({t, RecordKind::rx, bytes(50)});
  const int exchanges = std::uniform_int_distribution<int>(1, 40)(random);
  for (int i = 0; i < exchanges; ++i) {
    const int tx_records = std::uniform_int_distribution<int>(1, 3)(random);
    for (int k = 0; k < tx_records; ++k) records.push_back({t += 1000, RecordKind::tx, bytes(20)});
    const int rx_records = std::uniform_int_distribution<int>(0, 4)(random);
    for (int k = 0; k < rx_records; ++k) records.push_back({t += 1000, RecordKind::rx, bytes(300)});
  }
  return records;
}

// The client writes the tx stream and reads the rx stream in random splits,
// interleaved at random; returns everything it read.
std::string replay_with_random_splits(const std::vector<Record>& records,
                                      std::mt19937& random) {
  const std::string to_write = stream_of(records, RecordKind::tx);
  const std::size_t to_read = stream_of(records, RecordKind::rx).size();
  auto port = replay(records, "timing=none,unused=error");
  std::string got;
  std::size_t written = 0;
  std::uniform_int_distribution<std::size_t> chunk(1, 97);
  while (written < to_write.size() || got.size() < to_read) {
    const bool write_now = written < to_write.size() && random() % 2;
    if (write_now) {
      const std::size_t n = std::min(chunk(random), to_write.size() - written);
      EXPECT_EQ(port->write_all(to_write.data() + written, n), n);
      written += n;
    } else {
      std::string buffer(chunk(random), '\0');
      // Poll when more writes are due, block when everything was asked for.
      const Timeout timeout = written < to_write.size() ? Timeout(0s) : Timeout(5s);
      const std::size_t n = port->read(buffer.data(), buffer.size(), timeout);
      if (n == 0 && written == to_write.size()) break;  // would be a bug
      got.append(buffer.data(), n);
    }
  }
  port->close();  // unused=error: everything was consumed
  return got;
}

}  // namespace

TEST(ReplayChunking, RandomSplitsOfSyntheticSessionsReplayTheSameBytes) {
  std::mt19937 random(20261123);
  for (int round = 0; round < 60; ++round) {
    const std::vector<Record> session = synthetic_session(random);
    EXPECT_EQ(replay_with_random_splits(session, random),
              stream_of(session, RecordKind::rx))
        << "round " << round;
  }
}

TEST(ReplayChunking, RandomSplitsOfRealRecordingsReplayTheSameBytes) {
  std::mt19937 random(4242);
  for (const char* name : {"urg04lx_2011.log", "utm30lx_2011.log"}) {
    const std::vector<Record> session = wiretape::test::load_records(kFlexiportDir + name);
    ASSERT_FALSE(session.empty()) << name;
    for (int round = 0; round < 5; ++round) {
      EXPECT_EQ(replay_with_random_splits(session, random),
                stream_of(session, RecordKind::rx))
          << name << " round " << round;
    }
  }
}

namespace {

// Request -> the rx the recording gave it (first occurrence).
std::map<std::string, std::string> recorded_answers(const std::vector<Record>& records) {
  std::map<std::string, std::string> answers;
  std::string request;
  bool in_request = false;
  std::string* answer = nullptr;
  for (const Record& record : records) {
    if (record.kind == RecordKind::tx) {
      if (!in_request) request.clear();
      request += record.data;
      in_request = true;
      answer = nullptr;
    } else if (record.kind == RecordKind::rx) {
      if (in_request) {
        auto inserted = answers.emplace(request, std::string());
        answer = inserted.second ? &inserted.first->second : nullptr;
        in_request = false;
      }
      if (answer != nullptr) *answer += record.data;
    }
  }
  return answers;
}

}  // namespace

TEST(ReplayRealRecordings, RequestModeServesAClientInItsOwnOrderAndSplits) {
  std::mt19937 random(7);
  for (const auto& [name, scan] :
       std::vector<std::pair<std::string, std::string>>{
           {"urg04lx_2011.log", "GD0044072501\n"},
           {"utm30lx_2011.log", "ME0000108001101\n"}}) {
    const std::vector<Record> session = wiretape::test::load_records(kFlexiportDir + name);
    const auto answers = recorded_answers(session);
    ASSERT_TRUE(answers.count("VV\n") && answers.count("PP\n") && answers.count(scan))
        << name;
    auto port = replay(session, "timing=none,match=request,unused=ignore");
    port->set_timeout(5s);
    // Not the recorded order (VV, VV, PP, II, BM, CR00, ...): scan first.
    for (const std::string& command : {scan, std::string("PP\n"), std::string("VV\n")}) {
      std::size_t sent = 0;
      while (sent < command.size()) {
        const std::size_t n = std::min<std::size_t>(1 + random() % 4, command.size() - sent);
        port->write_all(command.data() + sent, n);
        sent += n;
      }
      const std::string& expected = answers.at(command);
      EXPECT_EQ(port->read_exactly(expected.size()), expected) << name << " " << command;
      EXPECT_EQ(port->available(), 0u) << name << " " << command;
    }
    const std::string version = answers.at("VV\n");
    EXPECT_NE(version.find("VV\n00P\n"), std::string::npos) << version;
  }
}

TEST(ReplayRealRecordings, SequenceModeReplaysTheRecordedProgram) {
  for (const char* name : {"urg04lx_2011.log", "utm30lx_2011.log"}) {
    auto port = open_port(std::string("type=replay,timing=none,timeout=5,unused=error,file=") +
                          kFlexiportDir + name);
    const std::vector<Record> session = wiretape::test::load_records(kFlexiportDir + name);
    std::string got;
    for (const Record& record : session) {
      if (record.kind == RecordKind::tx) port->write_all(record.data);
      if (record.kind == RecordKind::rx) got += port->read_exactly(record.data.size());
    }
    EXPECT_EQ(got, stream_of(session, RecordKind::rx)) << name;
    EXPECT_NO_THROW(port->close()) << name;
  }
}
