// Response fixes by frame (DESIGN.md section 17): a profile's fix_response
// applies at each response frame's own offsets, however the recording split
// the frames into rx records (a frame over several records, several frames
// in one record), in match=sequence and match=request alike; and mismatch
// reports under a profile name the recorded frame's own time and exchange.
#include <gtest/gtest.h>

#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "replay/profile.hpp"
#include "replay/replay_config.hpp"
#include "replay/response_fixer.hpp"
#include "replay/replay_port.hpp"
#include "session/record_source.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"
#include "wiretape/port.hpp"

using namespace wiretape;

namespace {

std::unique_ptr<Port> replay(std::vector<Record> records, const std::string& keys) {
  Options options = Options::parse("file=synthetic.wtape," + keys);
  detail::ReplayConfig config = detail::take_replay_config(options);
  auto port = detail::open_replay_session(config, detail::vector_source_factory(std::move(records)));
  port->set_timeout(test::kEventDeadline);
  return port;
}

Record tx(std::uint64_t t, std::string data) { return {t, RecordKind::tx, std::move(data)}; }
Record rx(std::uint64_t t, std::string data) { return {t, RecordKind::rx, std::move(data)}; }

std::string be16(unsigned value) {
  return {static_cast<char>(value >> 8), static_cast<char>(value & 0xFF)};
}

std::string mbap(unsigned tid, const std::string& pdu) {
  return be16(tid) + be16(0) + be16(static_cast<unsigned>(pdu.size() + 1)) + '\x01' + pdu;
}

std::string read_holding(unsigned address) {
  return std::string("\x03", 1) + be16(address) + be16(1);
}

std::string registers(unsigned value) { return std::string("\x03\x02", 2) + be16(value); }

class ResponseFixByFrame : public ::testing::TestWithParam<const char*> {
 protected:
  std::string mode() const { return std::string("timing=none,match=") + GetParam(); }
};

TEST_P(ResponseFixByFrame, ModbusTcpResponseSplitOverTwoRecords) {
  const std::string response = mbap(1, registers(0x1234));
  auto port = replay({tx(1, mbap(1, read_holding(0))), rx(2, response.substr(0, 4)),
                      rx(3, response.substr(4))},
                     mode() + ",profile=modbus-tcp");
  port->write_all(mbap(0x7777, read_holding(0)));
  // Not the transaction id written over the length field of the second part.
  EXPECT_EQ(port->read_exactly(response.size()), mbap(0x7777, registers(0x1234)));
}

TEST_P(ResponseFixByFrame, ModbusTcpResponseSplitInsideTheTransactionId) {
  const std::string response = mbap(1, registers(0x1234));
  auto port = replay({tx(1, mbap(1, read_holding(0))), rx(2, response.substr(0, 1)),
                      rx(3, response.substr(1, 5)), rx(4, response.substr(6))},
                     mode() + ",profile=modbus-tcp");
  port->write_all(mbap(0x7777, read_holding(0)));
  EXPECT_EQ(port->read_exactly(response.size()), mbap(0x7777, registers(0x1234)));
}

TEST_P(ResponseFixByFrame, TwoPipelinedResponsesInOneRecordGetTheirOwnRequestsIds) {
  auto port = replay({tx(1, mbap(1, read_holding(0))), tx(2, mbap(2, read_holding(5))),
                      rx(3, mbap(1, registers(0xA)) + mbap(2, registers(0xB)))},
                     mode() + ",profile=modbus-tcp");
  port->write_all(mbap(0x51, read_holding(0)) + mbap(0x52, read_holding(5)));
  EXPECT_EQ(port->read_exactly(22), mbap(0x51, registers(0xA)) + mbap(0x52, registers(0xB)));
}

TEST_P(ResponseFixByFrame, ResponsesInOneRecordToRequestsWrittenApart) {
  auto port = replay({tx(1, mbap(1, read_holding(0))), rx(2, mbap(1, registers(0xA))),
                      tx(3, mbap(2, read_holding(5))), rx(4, mbap(2, registers(0xB))),
                      rx(5, mbap(2, registers(0xC)))},
                     mode() + ",profile=modbus-tcp");
  port->write_all(mbap(0x61, read_holding(0)));
  EXPECT_EQ(port->read_exactly(11), mbap(0x61, registers(0xA)));
  port->write_all(mbap(0x62, read_holding(5)));
  // Both frames answer the one request: both carry its id.
  EXPECT_EQ(port->read_exactly(22), mbap(0x62, registers(0xB)) + mbap(0x62, registers(0xC)));
}

TEST_P(ResponseFixByFrame, DeclaredEchoOverASplitResponse) {
  const std::string keys = mode() + ",framing=delimiter:0a,echo=0:2";
  auto port = replay({tx(1, "\xAB\x01?\n"), rx(2, "\xAB\x01"), rx(3, "\x34\x56\n")}, keys);
  port->write_all("\xCD\x01?\n");
  EXPECT_EQ(port->read_exactly(5), "\xCD\x01\x34\x56\n");
}

TEST_P(ResponseFixByFrame, AResponseThatNeverCompletesAFrameIsServedAsRecordedWhenTheSessionEnds) {
  // A tail the framer never completes is served, and as the device sent it:
  // a fix applies to whole frames only.
  auto port = replay({tx(1, mbap(1, read_holding(0))), rx(2, be16(1) + be16(0))},
                     mode() + ",profile=modbus-tcp");
  port->write_all(mbap(0x7777, read_holding(0)));
  EXPECT_EQ(port->read_exactly(4), be16(1) + be16(0));
}

// A declared frame of 7 bytes: an id the response echoes, 5 bytes, a sum8.
std::string sum8(std::string_view bytes) {
  unsigned sum = 0;
  for (const char byte : bytes) sum += static_cast<unsigned char>(byte);
  return std::string(1, static_cast<char>(sum & 0xFF));
}
std::string sealed(const std::string& six) { return six + sum8(six); }
const char* const kSealedFixed = ",framing=fixed:7,echo=0:1,checksum=sum8@-1";

TEST_P(ResponseFixByFrame, ABytePastTheLastWholeFrameIsServedAsRecordedNotResealed) {
  // 8 bytes under fixed:7: one whole frame (fixed: the client's id, its sum
  // recomputed) and a 1-byte frame that never completes, the recorded 'j'
  // (a sum8 over no bytes would make it \x00).
  const std::string response = sealed("Aresp1") + "j";
  auto port = replay({tx(1, sealed("Aaskme")), rx(2, response)}, mode() + kSealedFixed);
  port->write_all(sealed("Baskme"));
  EXPECT_EQ(port->read_exactly(8), sealed("Bresp1") + "j");
}

TEST_P(ResponseFixByFrame, AnIncompleteFrameSplitOverRecordsIsServedAsRecordedRecordByRecord) {
  // The whole frame and the 3-byte tail both cut across records.
  const std::string response = sealed("Aresp1") + "xyz";
  auto port = replay({tx(1, sealed("Aaskme")), rx(2, response.substr(0, 5)),
                      rx(3, response.substr(5, 3)), rx(4, response.substr(8))},
                     mode() + kSealedFixed);
  port->write_all(sealed("Baskme"));
  EXPECT_EQ(port->read_exactly(10), sealed("Bresp1") + "xyz");
}

TEST_P(ResponseFixByFrame, ABrokenFrameIsServedAsRecordedAndTheWholeOneAfterItFixed) {
  // The device's first frame has a wrong sum: the profile cannot read it as
  // its protocol's, so neither its id nor its sum is rewritten.
  const std::string broken = "Abad!!" + std::string(1, '\x00');
  ASSERT_NE(sum8("Abad!!"), std::string(1, '\x00'));
  auto port = replay({tx(1, sealed("Aaskme")), rx(2, broken + sealed("Agood1"))},
                     mode() + kSealedFixed);
  port->write_all(sealed("Baskme"));
  EXPECT_EQ(port->read_exactly(14), broken + sealed("Bgood1"));
}

INSTANTIATE_TEST_SUITE_P(BothMatchModes, ResponseFixByFrame,
                         ::testing::Values("sequence", "request"));

// --- mismatch reports name the recorded frame's own time and exchange ---------

struct Location {
  std::uint64_t t_ns = 0;
  std::int64_t exchange = -2;
  std::string message;
};

Location mismatch_location(const std::string& keys, const std::vector<std::string>& writes) {
  const std::vector<Record> records = {
      tx(1'000'000, mbap(1, read_holding(0))), rx(2'000'000, mbap(1, registers(0xA))),
      tx(3'000'000'000, mbap(2, read_holding(5))), rx(3'100'000'000, mbap(2, registers(0xB)))};
  auto port = replay(records, "timing=none," + keys);
  try {
    for (const std::string& bytes : writes) {
      port->write_all(bytes);
      port->read_exactly(11);
    }
  } catch (const ReplayMismatch& error) {
    return {error.session_time_ns(), error.exchange(), error.what()};
  }
  ADD_FAILURE() << "no mismatch";
  return {};
}

TEST(MismatchLocation, FirstFrameNamesItsOwnTimeAndExchangeZero) {
  for (const char* keys : {"profile=modbus-tcp", "unused=ignore"}) {
    const Location at = mismatch_location(keys, {mbap(1, read_holding(9))});
    EXPECT_EQ(at.t_ns, 1'000'000u) << keys << ": " << at.message;
    EXPECT_EQ(at.exchange, 0) << keys << ": " << at.message;
    EXPECT_NE(at.message.find("session time 0.001000 s, exchange 0"), std::string::npos)
        << keys << ": " << at.message;
  }
}

TEST(MismatchLocation, SecondFrameNamesItsOwnTimeAndExchangeOne) {
  for (const char* keys : {"profile=modbus-tcp", "unused=ignore"}) {
    const Location at =
        mismatch_location(keys, {mbap(1, read_holding(0)), mbap(2, read_holding(9))});
    EXPECT_EQ(at.t_ns, 3'000'000'000u) << keys << ": " << at.message;
    EXPECT_EQ(at.exchange, 1) << keys << ": " << at.message;
    EXPECT_NE(at.message.find("session time 3.000000 s, exchange 1"), std::string::npos)
        << keys << ": " << at.message;
  }
}

TEST(MismatchLocation, AFrameSplitOverRecordsNamesTheTimeOfItsFirstByte) {
  const std::string request = mbap(2, read_holding(5));
  const std::vector<Record> records = {
      tx(1'000'000, mbap(1, read_holding(0))), rx(2'000'000, mbap(1, registers(0xA))),
      tx(3'000'000'000, request.substr(0, 3)), tx(4'000'000'000, request.substr(3))};
  auto port = replay(records, "timing=none,profile=modbus-tcp,unused=ignore");
  port->write_all(mbap(1, read_holding(0)));
  port->read_exactly(11);
  try {
    port->write_all(mbap(2, read_holding(9)));
    FAIL() << "no mismatch";
  } catch (const ReplayMismatch& error) {
    EXPECT_EQ(error.session_time_ns(), 3'000'000'000u) << error.what();
    EXPECT_EQ(error.exchange(), 1) << error.what();
  }
}

// --- the fixer alone: any split of the records gives the same bytes ------------

TEST(ResponseFixer, AnySplitOfTheResponsesGivesTheSameFixedBytesAndKeepsEachRecord) {
  const auto profile = find_profile("modbus-tcp");
  std::mt19937 random(22);
  for (int round = 0; round < 200; ++round) {
    // Requests 1..n (pipelined), their responses end to end, split anyhow.
    const unsigned n = 1 + random() % 4;
    std::string stream;
    std::string expected;
    detail::ResponseFixer fixer(profile);
    for (unsigned i = 1; i <= n; ++i) {
      fixer.request(i * 12, mbap(i, read_holding(i)), mbap(0x100 + i, read_holding(i)));
      stream += mbap(i, registers(i));
      expected += mbap(0x100 + i, registers(i));
    }
    std::vector<std::size_t> sizes;
    std::string served;
    std::vector<std::size_t> served_sizes;
    std::vector<std::uint64_t> served_times;
    for (std::size_t at = 0; at < stream.size();) {
      const std::size_t size = std::min<std::size_t>(1 + random() % 15, stream.size() - at);
      detail::RxItem item;
      item.t_ns = sizes.size();
      item.data = stream.substr(at, size);
      fixer.push(std::move(item), n * 12);
      sizes.push_back(size);
      at += size;
      while (fixer.ready()) {
        detail::RxItem out = fixer.take();
        served += out.data;
        served_sizes.push_back(out.data.size());
        served_times.push_back(out.t_ns);
      }
    }
    fixer.end_response();
    EXPECT_FALSE(fixer.holding());
    while (fixer.ready()) {
      detail::RxItem out = fixer.take();
      served += out.data;
      served_sizes.push_back(out.data.size());
      served_times.push_back(out.t_ns);
    }
    ASSERT_EQ(served, expected) << "round " << round;
    EXPECT_EQ(served_sizes, sizes) << "round " << round;  // the records' boundaries
    for (std::size_t i = 0; i < served_times.size(); ++i) EXPECT_EQ(served_times[i], i);
  }
}

}  // namespace
