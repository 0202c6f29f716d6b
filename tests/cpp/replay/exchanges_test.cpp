// The one segmentation of a session into exchanges (replay/exchanges.hpp):
// raw tx runs, request frames with a profile however records split them,
// datagrams, client sessions (a monitor's connect is none, a
// client_disconnect ends one), a greeting; and the streaming cursor agrees
// with the whole-session form.
#include "replay/exchanges.hpp"

#include <gtest/gtest.h>

#include <dirent.h>

#include <set>
#include <string>
#include <vector>

#include "open/open_port.hpp"
#include "open/port_types.hpp"
#include "replay/faults.hpp"
#include "replay/profile.hpp"
#include "replay/replay_config.hpp"
#include "replay/replay_port.hpp"
#include "session/reader.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"
#include "wiretape/port.hpp"

using namespace wiretape;
using namespace wiretape::detail;

namespace {

Record tx(std::uint64_t t, std::string data) { return {t, RecordKind::tx, std::move(data)}; }
Record rx(std::uint64_t t, std::string data) { return {t, RecordKind::rx, std::move(data)}; }
Record connect(std::uint64_t t, const std::string& peer, const std::string& role) {
  return {t, RecordKind::client_connect, "{\"peer\":\"" + peer + "\",\"role\":\"" + role + "\"}"};
}
Record disconnect(std::uint64_t t, const std::string& peer) {
  return {t, RecordKind::client_disconnect, "{\"peer\":\"" + peer + "\",\"reason\":\"closed\"}"};
}

SessionSegments segments_of(const std::vector<Record>& records, Segmentation how = {}) {
  auto source = vector_source_factory(records)();
  return segment_session(*source, how);
}

// The exchange the cursor gives each rx record.
std::vector<std::uint64_t> rx_exchanges(const std::vector<Record>& records, Segmentation how = {}) {
  ExchangeCursor cursor(how);
  std::vector<std::uint64_t> numbers;
  for (const Record& record : records) {
    const std::uint64_t exchange = cursor.feed(record);
    if (record.kind == RecordKind::rx && !record.data.empty()) numbers.push_back(exchange);
  }
  return numbers;
}

// The exchange the whole-session form gives each rx record.
std::vector<std::uint64_t> rx_exchanges_whole(const std::vector<Record>& records,
                                              Segmentation how = {}) {
  std::vector<std::uint64_t> numbers;
  for (const Exchange& exchange : segments_of(records, how).exchanges) {
    for (std::uint64_t i = 0; i < exchange.response_records; ++i) numbers.push_back(exchange.index);
  }
  return numbers;
}

std::string be16(unsigned value) {
  return {static_cast<char>(value >> 8), static_cast<char>(value & 0xFF)};
}
std::string mbap(unsigned tid) {
  const std::string pdu = std::string("\x03", 1) + be16(0) + be16(1);
  return be16(tid) + be16(0) + be16(static_cast<unsigned>(pdu.size() + 1)) + '\x01' + pdu;
}

TEST(Exchanges, RawTxRunsWithAGreetingInExchangeZero) {
  const std::vector<Record> records = {rx(1, "hello"), tx(2, "A"), tx(3, "B"), rx(4, "ab"),
                                       rx(5, "more"), tx(6, "C"), rx(7, "c"), tx(8, "D")};
  const SessionSegments segments = segments_of(records);
  ASSERT_EQ(segments.exchanges.size(), 3u);
  const Exchange& first = segments.exchanges[0];
  EXPECT_EQ(first.index, 0u);
  EXPECT_EQ(first.first_record, 0u);
  EXPECT_EQ(first.end_record, 5u);
  EXPECT_EQ(first.request_bytes, 2u);
  EXPECT_EQ(first.response_bytes, 11u);
  EXPECT_EQ(first.response_records, 3u);
  EXPECT_EQ(*first.request_first_t_ns, 2u);
  EXPECT_EQ(*first.request_last_t_ns, 3u);
  EXPECT_EQ(*first.response_first_t_ns, 1u);
  EXPECT_EQ(*first.response_last_t_ns, 5u);
  EXPECT_FALSE(first.client_session);
  EXPECT_EQ(segments.exchanges[1].first_record, 5u);
  EXPECT_EQ(segments.exchanges[2].request_bytes, 1u);
  EXPECT_FALSE(segments.exchanges[2].response_first_t_ns);
  EXPECT_EQ(rx_exchanges(records), (std::vector<std::uint64_t>{0, 0, 0, 1}));
  EXPECT_EQ(rx_exchanges_whole(records), rx_exchanges(records));
}

TEST(Exchanges, UnderMatchRequestAGreetingIsAnExchangeOfItsOwn) {
  const std::vector<Record> records = {rx(1, "hello"), tx(2, "A"), rx(3, "a")};
  const Segmentation how{nullptr, false, ReplayMatch::request};
  const SessionSegments segments = segments_of(records, how);
  ASSERT_EQ(segments.exchanges.size(), 2u);
  EXPECT_EQ(segments.exchanges[0].request_bytes, 0u);
  EXPECT_EQ(segments.exchanges[1].request_bytes, 1u);
  EXPECT_EQ(rx_exchanges(records, how), (std::vector<std::uint64_t>{0, 1}));
}

TEST(Exchanges, WithAProfileRequestFramesDecideHoweverRecordsSplitThem) {
  const std::string one = mbap(1), two = mbap(2), three = mbap(3);
  // Frame one split over two records; two and three in one record.
  const std::vector<Record> records = {tx(1, one.substr(0, 5)), tx(2, one.substr(5)), rx(3, "r1"),
                                       tx(4, two + three), rx(5, "r3"), rx(6, "r3b")};
  const Segmentation how{find_profile("modbus-tcp")};
  const SessionSegments segments = segments_of(records, how);
  ASSERT_EQ(segments.exchanges.size(), 3u);
  EXPECT_EQ(segments.exchanges[0].request_frames, (std::vector<std::string>{one}));
  EXPECT_EQ(segments.exchanges[1].request_frames, (std::vector<std::string>{two}));
  EXPECT_EQ(segments.exchanges[2].request_frames, (std::vector<std::string>{three}));
  EXPECT_EQ(segments.exchanges[0].first_record, 0u);
  EXPECT_EQ(segments.exchanges[0].response_bytes, 2u);
  EXPECT_EQ(segments.exchanges[1].response_bytes, 0u);
  EXPECT_EQ(segments.exchanges[2].response_bytes, 5u);
  EXPECT_EQ(rx_exchanges(records, how), (std::vector<std::uint64_t>{0, 2, 2}));
  EXPECT_EQ(rx_exchanges_whole(records, how), rx_exchanges(records, how));
  // Without the profile the same records are two tx runs.
  EXPECT_EQ(rx_exchanges(records), (std::vector<std::uint64_t>{0, 1, 1}));
}

TEST(Exchanges, WithAProfileResponseFramesGoToTheExchangeTheyBeganIn) {
  const std::string response = mbap(1);
  const std::vector<Record> records = {tx(1, mbap(1)), rx(2, response.substr(0, 3)),
                                       rx(3, response.substr(3) + response)};
  const SessionSegments segments = segments_of(records, {find_profile("modbus-tcp")});
  ASSERT_EQ(segments.exchanges.size(), 1u);
  EXPECT_EQ(segments.exchanges[0].response_frames, (std::vector<std::string>{response, response}));
}

TEST(Exchanges, EachDatagramIsARequest) {
  const std::vector<Record> records = {tx(1, "A"), tx(2, "B"), rx(3, "b"), tx(4, "C"), rx(5, "c")};
  const Segmentation how{nullptr, true};
  EXPECT_EQ(segments_of(records, how).exchanges.size(), 3u);
  EXPECT_EQ(rx_exchanges(records, how), (std::vector<std::uint64_t>{1, 2}));
  EXPECT_EQ(rx_exchanges_whole(records, how), rx_exchanges(records, how));
}

TEST(Exchanges, ClientSessionsSkipMonitorsAndEndAtTheClientsDisconnect) {
  const std::vector<Record> records = {
      connect(1, "a", "control"),   // 0: session 0
      rx(2, "hi"),                  // 1: its greeting: exchange 0
      tx(3, "A"),                   // 2
      connect(4, "m", "monitor"),   // 3: a monitor: no session
      rx(5, "a"),                   // 4
      disconnect(6, "m"),           // 5: the monitor's: the session goes on
      tx(7, "B"),                   // 6: exchange 1
      rx(8, "b"),                   // 7
      disconnect(9, "a"),           // 8: session 0 ends
      rx(10, "said to nobody"),     // 9
      connect(11, "c", "control"),  // 10: session 1
      tx(12, "C"),                  // 11: exchange 2
      rx(13, "c")};
  const SessionSegments segments = segments_of(records);
  ASSERT_EQ(segments.client_sessions.size(), 2u);
  EXPECT_EQ(segments.client_sessions[0].first_record, 0u);
  EXPECT_EQ(segments.client_sessions[0].end_record, 9u);
  EXPECT_EQ(*segments.client_sessions[0].disconnect_t_ns, 9u);
  EXPECT_EQ(segments.client_sessions[1].first_record, 10u);
  EXPECT_EQ(segments.client_sessions[1].end_record, 13u);
  EXPECT_FALSE(segments.client_sessions[1].disconnect_t_ns);
  ASSERT_EQ(segments.exchanges.size(), 3u);
  EXPECT_EQ(segments.exchanges[0].client_session, 0u);
  EXPECT_EQ(segments.exchanges[0].response_bytes, 3u);  // the greeting and "a"
  EXPECT_EQ(segments.exchanges[1].client_session, 0u);
  EXPECT_EQ(segments.exchanges[2].client_session, 1u);
  EXPECT_EQ(segments.exchanges[2].first_record, 11u);
  EXPECT_EQ(rx_exchanges(records), (std::vector<std::uint64_t>{0, 0, 1, 1, 2}));
  // What was said to nobody belongs to no exchange.
  EXPECT_EQ(rx_exchanges_whole(records), (std::vector<std::uint64_t>{0, 0, 1, 2}));
  EXPECT_EQ(segments.exchanges[1].end_record, 9u);
}

TEST(Exchanges, ASecondClientsConnectDuringASessionIsNoSession) {
  const std::vector<Record> records = {connect(1, "a", "control"), tx(2, "A"),
                                       connect(3, "b", "control"), disconnect(4, "b"),
                                       rx(5, "a"), disconnect(6, "a")};
  const SessionSegments segments = segments_of(records);
  ASSERT_EQ(segments.client_sessions.size(), 1u);
  EXPECT_EQ(segments.client_sessions[0].end_record, 6u);
  ASSERT_EQ(segments.exchanges.size(), 1u);
  EXPECT_EQ(segments.exchanges[0].response_bytes, 1u);
}

TEST(Exchanges, AnEmptySessionHasNone) {
  EXPECT_TRUE(segments_of({}).exchanges.empty());
  EXPECT_TRUE(segments_of({Record{1, RecordKind::settings, "{}"}}).exchanges.empty());
}

TEST(Exchanges, ARequestEndsAtItsLastByteAndItsAnswerStartsAfterIt) {
  // The greeting before the request is not its answer; a tx run ends at its
  // last record.
  const std::vector<Record> records = {rx(1, "hello"), tx(2, "A"), tx(3, "B"), rx(5, "ab"),
                                       tx(8, "C")};
  const SessionSegments segments = segments_of(records);
  ASSERT_EQ(segments.exchanges.size(), 2u);
  EXPECT_EQ(segments.exchanges[0].request_end_t_ns, 3u);
  EXPECT_EQ(segments.exchanges[0].response_start_t_ns, 5u);
  EXPECT_EQ(segments.exchanges[0].response_first_t_ns, 1u);
  EXPECT_EQ(segments.exchanges[1].request_end_t_ns, 8u);
  EXPECT_FALSE(segments.exchanges[1].response_start_t_ns);
  // Under match=request the greeting is an exchange without a request.
  const Segmentation request{nullptr, false, ReplayMatch::request};
  const SessionSegments by_match = segments_of(records, request);
  EXPECT_FALSE(by_match.exchanges[0].request_end_t_ns);
  EXPECT_FALSE(by_match.exchanges[0].response_start_t_ns);
}

TEST(Exchanges, WithAProfileARequestEndsWhereItsFrameIsComplete) {
  // The tx after the frame begins the next one: the wait is from the frame.
  const std::string one = mbap(1), two = mbap(2);
  const std::vector<Record> records = {tx(1, one.substr(0, 5)), tx(2, one.substr(5)),
                                       tx(3, two.substr(0, 4)), rx(7, "r1"), tx(9, two.substr(4)),
                                       rx(10, "r2")};
  const SessionSegments segments = segments_of(records, {find_profile("modbus-tcp")});
  ASSERT_EQ(segments.exchanges.size(), 2u);
  EXPECT_EQ(segments.exchanges[0].request_end_t_ns, 2u);
  EXPECT_EQ(segments.exchanges[0].request_last_t_ns, 3u);
  EXPECT_EQ(segments.exchanges[0].response_start_t_ns, 7u);
  EXPECT_EQ(segments.exchanges[1].request_end_t_ns, 9u);
  LatencyMeter meter({find_profile("modbus-tcp")});
  for (const Record& record : records) meter.feed(record.kind, record.t_ns, record.data);
  const std::vector<RequestLatency>& latencies = meter.answered();
  ASSERT_EQ(latencies.size(), 2u);
  EXPECT_EQ(latencies[0].wait_ns, 5u);
  EXPECT_EQ(latencies[1].wait_ns, 1u);
  EXPECT_FALSE(latencies[0].request_name.empty());
}

TEST(Exchanges, AnOpenOrCloseBetweenARequestAndItsAnswerDoesNotCutThem) {
  // The replay serves the answer to the request across them: so is it paired.
  const std::vector<Record> records = {tx(1, "Q"), Record{2, RecordKind::close, "{}"},
                                       Record{3, RecordKind::open, "{}"}, rx(6, "R")};
  LatencyMeter meter({});
  for (const Record& record : records) meter.feed(record.kind, record.t_ns, record.data);
  const std::vector<RequestLatency>& latencies = meter.answered();
  ASSERT_EQ(latencies.size(), 1u);
  EXPECT_EQ(latencies[0].wait_ns, 5u);
  EXPECT_TRUE(latencies[0].request_name.empty());
  EXPECT_EQ(segments_of(records).exchanges[0].response_start_t_ns, 6u);
}

TEST(Exchanges, TheServedShapeIsEveryClientSessionsOnTheSessionsClock) {
  // A virtual device serves its second client the second client session,
  // and a fault's place may be there: what no client heard is no place.
  const std::vector<Record> records = {
      rx(1, "before any client"), connect(2'000, "a", "control"), tx(2'100, "A"),
      rx(2'500, "aa"), tx(3'000, "B"), rx(3'500, "bbb"), disconnect(4'000, "a"),
      rx(4'500, "to nobody"), connect(5'000, "c", "control"), tx(5'100, "C"), rx(5'500, "c"),
      disconnect(6'000, "c")};
  const SessionShape shape = served_shape(segments_of(records));
  EXPECT_EQ(shape.first_exchange, 1u);
  EXPECT_EQ(shape.exchange_end, 4u);
  EXPECT_EQ(shape.rx_bytes, 6u);
  EXPECT_EQ(shape.last_rx_t_ns, 5'500u);  // session time, not time since the connect
}

// --- the replay's own numbering agrees with the whole-session form ------------

// Every real recording the tests and the example use.
std::vector<std::string> recordings() {
  std::vector<std::string> paths;
  const std::string data = WIRETAPE_TEST_DATA_DIR;
  for (const std::string& folder :
       {data + "/flexiport", data + "/golden", data + "/../../examples/hokuyo/recordings"}) {
    DIR* dir = opendir(folder.c_str());
    if (dir == nullptr) continue;
    while (const dirent* entry = readdir(dir)) {
      const std::string name = entry->d_name;
      const auto ends = [&](const std::string& tail) {
        return name.size() > tail.size() && name.compare(name.size() - tail.size(), tail.size(), tail) == 0;
      };
      if (ends(".wtape") || ends(".logr")) {
        paths.push_back(folder + "/" + (ends(".logr") ? name.substr(0, name.size() - 1) : name));
      }
    }
    closedir(dir);
  }
  return paths;
}

// The exchanges with rx, as a replay of `path` by a faithful client (each
// recorded tx record written, then what was released read) numbers them:
// every:1 fires once at the first rx of each exchange served.
std::set<std::uint64_t> replayed_exchanges(const std::string& path, const std::string& keys) {
  Options options = Options::parse(
      "timing=none,check=off,unused=ignore,faults=duplicate@every:1," + keys);
  options.set("file", path);
  auto port = open_replay(options, datagram_port_types());
  std::set<std::uint64_t> fired;
  report_faults_to(*port, [&](const FaultEvent& event) { fired.insert(event.exchange); });
  SessionHeader header;
  auto source = open_session_source(path, header);
  Record record;
  char buffer[65536];
  const auto drain = [&] {
    while (port->available() > 0) port->read(buffer, sizeof buffer, Timeout(std::chrono::milliseconds(0)));
  };
  try {
    drain();
    while (source->next(record)) {
      if (record.kind == RecordKind::tx && !record.data.empty()) {
        port->write_all(record.data);
      }
      drain();
    }
  } catch (const PortClosed&) {
    // A recorded close or loss: nothing after it is served.
  }
  return fired;
}

TEST(ExchangesAgree, TheReplaysNumberingIsTheWholeSessionFormsOnEveryRecording) {
  const std::vector<std::string> paths = recordings();
  ASSERT_GE(paths.size(), 4u);
  std::size_t compared = 0;
  for (const std::string& path : paths) {
    SessionHeader header;
    std::unique_ptr<RecordSource> source;
    try {
      source = open_session_source(path, header);
    } catch (const std::exception&) {
      continue;  // a deliberately unreadable golden file
    }
    // Ends early (damage; a close or a loss with records after it): the
    // replay serves less than the file holds.
    bool whole = true;
    bool ended = false;
    Record record;
    while (source->next(record)) {
      if (ended) whole = false;
      if (record.kind == RecordKind::close || record.kind == RecordKind::device_lost) {
        ended = true;
      }
    }
    if (source->damage() || !whole) continue;
    for (const char* profile : {"", "scip"}) {
      for (const char* match : {"sequence", "request"}) {
        if (*profile && path.find("urg") == std::string::npos &&
            path.find("utm") == std::string::npos) {
          continue;  // scip only for the Hokuyo recordings
        }
        std::string keys = std::string("match=") + match;
        if (std::string(match) == "request") keys += ",gap=0";
        if (*profile) keys += std::string(",profile=") + profile;
        std::set<std::uint64_t> expected;
        const SessionSegments segments = segment_session_file(path, keys, datagram_port_types());
        for (const Exchange& exchange : segments.exchanges) {
          if (exchange.response_bytes > 0) expected.insert(exchange.index);
        }
        EXPECT_EQ(replayed_exchanges(path, keys), expected) << path << " " << keys;
        ++compared;
      }
    }
  }
  EXPECT_GE(compared, 20u);  // the flexiport pair and the Hokuyo recordings, at least
}

TEST(ExchangesAgree, AVirtualDevicesLaterClientSessionNumbersOnFromTheFile) {
  const std::vector<Record> records = {
      connect(1, "a", "control"), tx(2, "Q0\n"), rx(3, "R0\n"), tx(4, "Q1\n"), rx(5, "R1\n"),
      disconnect(6, "a"),         connect(7, "b", "control"), tx(8, "Q2\n"), rx(9, "R2\n")};
  EXPECT_EQ(first_exchange_of_client_session(*vector_source_factory(records)(), {}, 2), 2u);
  for (const char* match : {"sequence", "request"}) {
    Options options = Options::parse(std::string("file=synthetic.wtape,timing=none,match=") +
                                     match + ",faults=drop@exchange:2");
    auto port = open_replay_session(take_replay_config(options), vector_source_factory(records));
    port->set_timeout(test::kEventDeadline);
    std::vector<std::uint64_t> fired;
    report_faults_to(*port, [&](const FaultEvent& event) { fired.push_back(event.exchange); });
    ASSERT_TRUE(replay_begin_client_session(*port));
    port->write_all("Q0\n");
    EXPECT_EQ(port->read_exactly(3), "R0\n");
    port->write_all("Q1\n");
    EXPECT_EQ(port->read_exactly(3), "R1\n");
    replay_await_client(*port);
    ASSERT_TRUE(replay_begin_client_session(*port));
    port->write_all("Q2\n");
    EXPECT_EQ(port->available(), 0u) << match;  // exchange 2 of the file: dropped
    EXPECT_EQ(fired, (std::vector<std::uint64_t>{2})) << match;
  }
}

}  // namespace
