// The SCIP driver against a scripted in-memory device (and against the
// replies of a real URG-04LX and UTM-30LX, taken from flexiport logs).
#include <gtest/gtest.h>

#include <cstdint>
#include <deque>
#include <fstream>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "hokuyo/scip.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"
#include <memory>

namespace {

using namespace std::chrono_literals;

// A device double: every complete command line written to it is answered
// by `respond`, whose reply becomes readable at once. Reads never block
// longer than there is data (the test thread is the only one).
class ScriptedDevice : public wiretape::Port {
 public:
  std::function<std::string(const std::string&)> respond;
  std::vector<std::string> commands;
  std::string rx;

  std::size_t available() override { return rx.size(); }
  void flush_input() override { rx.clear(); }
  void flush_output() override {}
  void drain() override {}
  void close() override { open_ = false; }
  bool is_open() const override { return open_; }
  std::string description() const override { return "scripted device"; }
  std::string type() const override { return "scripted"; }
  int native_handle() const override { return -1; }

 protected:
  std::size_t read_some(void* buffer, std::size_t size, wiretape::Deadline) override {
    const std::size_t n = std::min(size, rx.size());
    std::copy_n(rx.begin(), n, static_cast<char*>(buffer));
    rx.erase(0, n);
    return n;
  }
  std::size_t write_some(const void* data, std::size_t size, wiretape::Deadline) override {
    pending_.append(static_cast<const char*>(data), size);
    for (auto end = pending_.find('\n'); end != std::string::npos; end = pending_.find('\n')) {
      const std::string command = pending_.substr(0, end);
      pending_.erase(0, end + 1);
      commands.push_back(command);
      if (respond) rx += respond(command);
    }
    return size;
  }
  bool wait_readable_until(wiretape::Deadline) override { return !rx.empty(); }

 private:
  std::string pending_;
  bool open_ = true;
};

std::string status_line(const std::string& status) {
  return status + hokuyo::checksum(status) + "\n";
}

std::string data_line(const std::string& data) {
  return data + hokuyo::checksum(data) + "\n";
}

std::string param_line(const std::string& data) {
  return data + ";" + hokuyo::checksum(data) + "\n";
}

std::string simple_reply(const std::string& command, const std::string& status) {
  return command + "\n" + status_line(status) + "\n";
}

std::string version_reply() {
  return "VV\n" + status_line("00") + param_line("VEND:Hokuyo Automatic Co.,Ltd.") +
         param_line("PROD:SOKUIKI Sensor URG-04LX") +
         param_line("FIRM:3.1.04(02/Aug./2007)") + param_line("PROT:SCIP 2.0") +
         param_line("SERI:H0706400") + "\n";
}

// Scan data split into 64-character lines, each with its own sum.
std::string scan_body(std::uint32_t timestamp, const std::vector<std::uint32_t>& values,
                      int digits) {
  std::string data;
  for (auto value : values) data += hokuyo::encode(value, digits);
  std::string body = data_line(hokuyo::encode(timestamp, 4));
  for (std::size_t at = 0; at < data.size(); at += 64) body += data_line(data.substr(at, 64));
  return body + "\n";
}

hokuyo::DriverOptions fast_options() {
  hokuyo::DriverOptions options;
  options.line_timeout = 100ms;
  options.probe_timeout = 100ms;
  return options;
}

std::vector<std::uint32_t> ramp(std::size_t count) {
  std::vector<std::uint32_t> values;
  for (std::size_t i = 0; i < count; ++i) values.push_back(static_cast<std::uint32_t>(20 + i * 37 % 5000));
  return values;
}

TEST(ScipEncoding, SumsAndCharacterGroupsRoundTrip) {
  EXPECT_EQ(hokuyo::checksum("00"), 'P');
  EXPECT_EQ(hokuyo::checksum("99"), 'b');
  EXPECT_EQ(hokuyo::checksum("DMIN:20"), '4');
  for (int digits : {2, 3, 4})
    for (std::uint32_t value : {0u, 1u, 63u, 64u, 4095u})
      EXPECT_EQ(hokuyo::decode(hokuyo::encode(value, digits)), value);
  EXPECT_EQ(hokuyo::decode("JUGn"), 6968830u);  // the real URG-04LX GD timestamp
  EXPECT_THROW(hokuyo::decode("0\x7f"), std::invalid_argument);
}

TEST(ScipDriver, OpenReadsTheVersion) {
  ScriptedDevice device;
  device.respond = [](const std::string& command) {
    return command == "VV" ? version_reply() : std::string();
  };
  hokuyo::Driver driver(device, fast_options());
  const auto version = driver.open();
  EXPECT_EQ(version.serial, "H0706400");
  EXPECT_EQ(version.protocol, "SCIP 2.0");
  EXPECT_FALSE(driver.switched_from_scip1());
  EXPECT_EQ(device.commands, std::vector<std::string>{"VV"});
}

TEST(ScipDriver, OpenSwitchesAScip11DeviceOnlyWhenVvFails) {
  ScriptedDevice device;
  bool scip2 = false;
  device.respond = [&](const std::string& command) -> std::string {
    if (command == "SCIP2.0") {
      scip2 = true;
      return "SCIP2.0\n0\n\n";
    }
    if (!scip2) return command + "\nE\n\n";  // SCIP 1.1 style
    return command == "VV" ? version_reply() : std::string();
  };
  hokuyo::Driver driver(device, fast_options());
  EXPECT_EQ(driver.open().serial, "H0706400");
  EXPECT_TRUE(driver.switched_from_scip1());
  EXPECT_EQ(device.commands, (std::vector<std::string>{"VV", "QT", "VV", "SCIP2.0", "VV"}));
}

TEST(ScipDriver, OpenStopsAStreamLeftRunningWithoutSwitchingProtocol) {
  ScriptedDevice device;
  // Scans of an earlier program's stream are still waiting to be read.
  device.rx = "MD0044072501000\n" + status_line("99") + scan_body(5, ramp(682), 3);
  device.respond = [&](const std::string& command) -> std::string {
    if (command == "QT") return "MD0044072501000\n" + status_line("99") + "QT\n" + status_line("00") + "\n";
    return command == "VV" ? version_reply() : std::string();
  };
  hokuyo::Driver driver(device, fast_options());
  EXPECT_EQ(driver.open().serial, "H0706400");
  EXPECT_FALSE(driver.switched_from_scip1());
  EXPECT_EQ(device.commands, (std::vector<std::string>{"VV", "QT", "VV"}));
}

TEST(ScipDriver, SilentDeviceIsAClearError) {
  ScriptedDevice device;
  hokuyo::Driver driver(device, fast_options());
  try {
    driver.open();
    FAIL() << "open() of a silent device succeeded";
  } catch (const hokuyo::ProtocolError& error) {
    EXPECT_EQ(error.command(), "SCIP2.0");
    EXPECT_NE(std::string(error.what()).find("no reply"), std::string::npos) << error.what();
  }
}

TEST(ScipDriver, WrongEchoNamesTheCommand) {
  ScriptedDevice device;
  device.respond = [](const std::string&) { return simple_reply("BN", "00"); };
  hokuyo::Driver driver(device, fast_options());
  try {
    driver.laser_on();
    FAIL();
  } catch (const hokuyo::ProtocolError& error) {
    EXPECT_EQ(error.command(), "BM");
    EXPECT_NE(std::string(error.what()).find("echo is \"BN\""), std::string::npos) << error.what();
  }
}

TEST(ScipDriver, StatusesAlreadyAreAcceptedFaultsAreNot) {
  ScriptedDevice device;
  std::string next_status = "02";
  device.respond = [&](const std::string& command) { return simple_reply(command, next_status); };
  hokuyo::Driver driver(device, fast_options());
  EXPECT_NO_THROW(driver.laser_on());  // 02: already on
  next_status = "01";
  EXPECT_THROW(driver.laser_on(), hokuyo::StatusError);
  next_status = "0E";
  try {
    driver.reset();
    FAIL();
  } catch (const hokuyo::StatusError& error) {
    EXPECT_EQ(error.status(), "0E");
    EXPECT_NE(std::string(error.what()).find("not recognised"), std::string::npos);
    EXPECT_FALSE(error.hardware_fault());
  }
  next_status = "10";
  try {
    driver.get_scan(hokuyo::ScanMode::gd, 44, 725, 1);
    FAIL();
  } catch (const hokuyo::StatusError& error) {
    EXPECT_NE(std::string(error.what()).find("laser is off"), std::string::npos) << error.what();
  }
  next_status = "55";
  try {
    driver.get_scan(hokuyo::ScanMode::gd, 44, 725, 1);
    FAIL();
  } catch (const hokuyo::StatusError& error) {
    EXPECT_TRUE(error.hardware_fault());
    EXPECT_NE(std::string(error.what()).find("hardware fault"), std::string::npos);
  }
  next_status = "03";
  EXPECT_NO_THROW(driver.leave_time_mode());  // already out
}

TEST(ScipDriver, DecodesValuesThatStraddleLineBreaks) {
  for (auto mode : {hokuyo::ScanMode::gd, hokuyo::ScanMode::gs}) {
    const int digits = mode == hokuyo::ScanMode::gd ? 3 : 2;
    const auto values = ramp(100);  // 300 or 200 characters: values cross lines
    ScriptedDevice device;
    device.respond = [&](const std::string& command) {
      return command + "\n" + status_line("00") + scan_body(1234, values, digits);
    };
    hokuyo::Driver driver(device, fast_options());
    const auto scan = driver.get_scan(mode, 10, 109, 1);
    EXPECT_EQ(device.commands.back(), std::string(hokuyo::scan_mode_command(mode)) + "0010010901");
    EXPECT_EQ(scan.ranges, values);
    EXPECT_EQ(scan.timestamp_ms, 1234u);
  }
}

TEST(ScipDriver, ClusteredScanHasOneValuePerCluster) {
  const auto values = ramp(4);  // steps 0..10 in clusters of 3: 4 values
  ScriptedDevice device;
  device.respond = [&](const std::string& command) {
    return command + "\n" + status_line("00") + scan_body(1, values, 3);
  };
  hokuyo::Driver driver(device, fast_options());
  EXPECT_EQ(driver.get_scan(hokuyo::ScanMode::gd, 0, 10, 3).ranges, values);
}

TEST(ScipDriver, WrongDataSumIsCaughtWithTheLine) {
  ScriptedDevice device;
  device.respond = [&](const std::string& command) {
    std::string reply = command + "\n" + status_line("00") + scan_body(1, ramp(50), 3);
    reply[reply.find('\n', reply.find('\n', command.size() + 4) + 1) + 5] ^= 1;
    return reply;
  };
  hokuyo::Driver driver(device, fast_options());
  try {
    driver.get_scan(hokuyo::ScanMode::gd, 0, 49, 1);
    FAIL();
  } catch (const hokuyo::ProtocolError& error) {
    EXPECT_NE(std::string(error.what()).find("line 4: wrong sum"), std::string::npos) << error.what();
  }
}

TEST(ScipDriver, WrongValueCountIsCaught) {
  ScriptedDevice device;
  device.respond = [&](const std::string& command) {
    return command + "\n" + status_line("00") + scan_body(1, ramp(49), 3);
  };
  hokuyo::Driver driver(device, fast_options());
  EXPECT_THROW(driver.get_scan(hokuyo::ScanMode::gd, 0, 49, 1), hokuyo::ProtocolError);
}

TEST(ScipDriver, TimestampWrapIsUnwrapped) {
  ScriptedDevice device;
  std::vector<std::uint32_t> stamps = {0xFFFFF0, 0x000010, 0x000005, 0x800000};
  std::size_t next = 0;
  device.respond = [&](const std::string& command) {
    return command + "\n" + status_line("00") + scan_body(stamps[next++], ramp(3), 3);
  };
  hokuyo::Driver driver(device, fast_options());
  std::vector<std::uint64_t> unwrapped;
  for (std::size_t i = 0; i < stamps.size(); ++i) {
    const auto scan = driver.get_scan(hokuyo::ScanMode::gd, 0, 2, 1);
    EXPECT_EQ(scan.timestamp_ms, stamps[i]);
    unwrapped.push_back(scan.timestamp_unwrapped_ms);
  }
  // A small step back is jitter, not a wrap.
  EXPECT_EQ(unwrapped, (std::vector<std::uint64_t>{0xFFFFF0, 0x1000010, 0x1000005, 0x1800000}));
}

TEST(ScipDriver, StreamCountsDownAndEnds) {
  ScriptedDevice device;
  device.respond = [&](const std::string& command) {
    std::string reply = simple_reply(command, "00");
    const std::string prefix = command.substr(0, 13);
    for (int remaining = 2; remaining >= 0; --remaining)
      reply += prefix + "0" + std::to_string(remaining) + "\n" + status_line("99") +
               scan_body(100 + remaining, ramp(5), 2);
    return reply;
  };
  hokuyo::Driver driver(device, fast_options());
  driver.start_stream(hokuyo::ScanMode::ms, 0, 4, 1, 0, 3);
  EXPECT_EQ(device.commands.back(), "MS0000000401003");
  for (int remaining = 2; remaining >= 0; --remaining) {
    ASSERT_TRUE(driver.streaming());
    const auto scan = driver.read_stream_scan();
    EXPECT_EQ(scan.remaining, remaining);
    EXPECT_EQ(scan.ranges, ramp(5));
  }
  EXPECT_FALSE(driver.streaming());
}

TEST(ScipDriver, StreamCounterOutOfStepIsCaught) {
  ScriptedDevice device;
  device.respond = [&](const std::string& command) {
    return simple_reply(command, "00") + command.substr(0, 13) + "00\n" + status_line("99") +
           scan_body(1, ramp(5), 3);
  };
  hokuyo::Driver driver(device, fast_options());
  driver.start_stream(hokuyo::ScanMode::md, 0, 4, 1, 0, 3);
  try {
    driver.read_stream_scan();
    FAIL();
  } catch (const hokuyo::ProtocolError& error) {
    EXPECT_NE(std::string(error.what()).find("remaining-scan counter"), std::string::npos);
  }
}

TEST(ScipDriver, MeStreamCarriesIntensities) {
  ScriptedDevice device;
  device.respond = [&](const std::string& command) {
    std::string data;
    for (std::uint32_t i = 0; i < 3; ++i) data += hokuyo::encode(100 + i, 3) + hokuyo::encode(2000 + i, 3);
    return simple_reply(command, "00") + command.substr(0, 13) + "00\n" + status_line("99") +
           data_line(hokuyo::encode(42, 4)) + data_line(data) + "\n";
  };
  hokuyo::Driver driver(device, fast_options());
  driver.start_stream(hokuyo::ScanMode::me, 0, 2, 1, 1, 1);
  const auto scan = driver.read_stream_scan();
  EXPECT_EQ(scan.ranges, (std::vector<std::uint32_t>{100, 101, 102}));
  EXPECT_EQ(scan.intensities, (std::vector<std::uint32_t>{2000, 2001, 2002}));
  EXPECT_EQ(scan.timestamp_ms, 42u);
}

TEST(ScipDriver, RecoversFromAPartialReplyWithQt) {
  ScriptedDevice device;
  device.respond = [&](const std::string& command) -> std::string {
    if (command == "QT") return "05h05c\nQT\n" + status_line("00") + "\n";
    if (command == "VV") return version_reply();
    // A GD reply cut off in the middle of a data line.
    return command + "\n" + status_line("00") + data_line(hokuyo::encode(1, 4)) + "05m05";
  };
  hokuyo::Driver driver(device, fast_options());
  try {
    driver.get_scan(hokuyo::ScanMode::gd, 0, 99, 1);
    FAIL();
  } catch (const hokuyo::ProtocolError& error) {
    EXPECT_NE(std::string(error.what()).find("middle of a line"), std::string::npos) << error.what();
  }
  driver.recover();
  EXPECT_EQ(device.commands.back(), "QT");
  EXPECT_EQ(driver.version().serial, "H0706400");
}

TEST(ScipDriver, TimeAdjustMode) {
  ScriptedDevice device;
  device.respond = [&](const std::string& command) {
    if (command == "TM1") return command + "\n" + status_line("00") + data_line(hokuyo::encode(777, 4)) + "\n";
    return simple_reply(command, "00");
  };
  hokuyo::Driver driver(device, fast_options());
  driver.enter_time_mode();
  EXPECT_EQ(driver.device_time_ms(), 777u);
  driver.leave_time_mode();
  EXPECT_EQ(device.commands, (std::vector<std::string>{"TM0", "TM1", "TM2"}));
}

// --- real devices -----------------------------------------------------------

// The device's bytes from a flexiport ".logr" file, cut into replies (each
// ends with an empty line); a command is answered with the first unused
// reply that echoes it.
std::deque<std::string> real_replies(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  if (!file) return {};
  std::string bytes, chunk_header(12, '\0');
  while (file.read(&chunk_header[0], 12)) {
    const auto b = [&](int i) { return static_cast<std::uint32_t>(static_cast<unsigned char>(chunk_header[i])); };
    const std::uint32_t length = b(8) << 24 | b(9) << 16 | b(10) << 8 | b(11);
    std::string payload(length, '\0');
    file.read(&payload[0], length);
    bytes += payload;
  }
  std::deque<std::string> replies;
  for (std::size_t at = 0; at < bytes.size();) {
    const auto end = bytes.find("\n\n", at);
    if (end == std::string::npos) break;
    replies.push_back(bytes.substr(at, end + 2 - at));
    at = end + 2;
  }
  return replies;
}

void answer_from(ScriptedDevice& device, std::deque<std::string>& replies) {
  device.respond = [&replies](const std::string& command) -> std::string {
    for (auto it = replies.begin(); it != replies.end(); ++it) {
      if (it->compare(0, command.size() + 1, command + "\n") == 0) {
        std::string reply = *it;
        it = replies.erase(it);
        // A stream's scans follow the command's own reply.
        while (it != replies.end() && it->compare(0, 2, command.substr(0, 2)) == 0 &&
               it->compare(0, command.size() + 1, command + "\n") != 0) {
          reply += *it;
          it = replies.erase(it);
        }
        return reply;
      }
    }
    return std::string();
  };
}

TEST(ScipRealDevice, Urg04lxGdScan) {
  auto replies = real_replies(WIRETAPE_TEST_DATA_DIR "/flexiport/urg04lx_2011.logr");
  ASSERT_FALSE(replies.empty()) << "test data missing: " WIRETAPE_TEST_DATA_DIR;
  ScriptedDevice device;
  answer_from(device, replies);
  hokuyo::Driver driver(device, fast_options());
  EXPECT_EQ(driver.open().serial, "H0706400");
  const auto params = driver.parameters();
  EXPECT_EQ(params.model, "URG-04LX");
  EXPECT_EQ(params.first_step, 44);
  EXPECT_EQ(params.last_step, 725);
  EXPECT_EQ(params.resolution, 1024u);
  EXPECT_EQ(driver.state().at("LASR"), "ON");
  driver.laser_on();  // the real device answered 02: already on
  const auto scan = driver.get_scan(hokuyo::ScanMode::gd, 44, 725, 1);
  EXPECT_EQ(scan.timestamp_ms, 6968830u);
  ASSERT_EQ(scan.ranges.size(), 682u);
  EXPECT_EQ(std::vector<std::uint32_t>(scan.ranges.begin(), scan.ranges.begin() + 5),
            (std::vector<std::uint32_t>{392, 392, 391, 385, 381}));
}

TEST(ScipRealDevice, Utm30lxMeScan) {
  auto replies = real_replies(WIRETAPE_TEST_DATA_DIR "/flexiport/utm30lx_2011.logr");
  ASSERT_FALSE(replies.empty()) << "test data missing: " WIRETAPE_TEST_DATA_DIR;
  ScriptedDevice device;
  answer_from(device, replies);
  hokuyo::Driver driver(device, fast_options());
  driver.open();
  const auto params = driver.parameters();
  EXPECT_EQ(params.model, "UTM-30LX");
  driver.start_stream(hokuyo::ScanMode::me, params.first_step, params.last_step, 1, 1, 1);
  EXPECT_EQ(device.commands.back(), "ME0000108001101");
  const auto scan = driver.read_stream_scan();
  EXPECT_EQ(scan.remaining, 0);
  EXPECT_EQ(scan.timestamp_ms, 4821609u);
  ASSERT_EQ(scan.ranges.size(), 1081u);
  ASSERT_EQ(scan.intensities.size(), 1081u);
  EXPECT_EQ(scan.ranges[0], 45u);
  EXPECT_EQ(scan.intensities[0], 1809u);
  EXPECT_EQ(scan.ranges[1], 48u);
  EXPECT_EQ(scan.intensities[1], 1780u);
  EXPECT_FALSE(driver.streaming());
}

}  // namespace

// --- through wiretape's replaying port ---------------------------------------

namespace replayed {

std::unique_ptr<wiretape::Port> open_or_skip(const std::string& options, const std::string& file) {
  if (!std::ifstream(file)) return nullptr;
  return wiretape::open_port(options);
}

TEST(ScipReplay, RealUrg04lxInRequestMode) {
  const std::string log = WIRETAPE_TEST_DATA_DIR "/flexiport/urg04lx_2011.log";
  auto port = open_or_skip("type=replay,file=" + log + ",match=request,timing=none,unused=ignore",
                           WIRETAPE_TEST_DATA_DIR "/flexiport/urg04lx_2011.logr");
  ASSERT_TRUE(port) << "test data missing: " << log;
  hokuyo::Driver driver(*port, fast_options());
  driver.open();
  driver.parameters();
  driver.state();
  driver.laser_on();
  const auto scan = driver.get_scan(hokuyo::ScanMode::gd, 44, 725, 1);
  EXPECT_EQ(scan.timestamp_ms, 6968830u);
  ASSERT_EQ(scan.ranges.size(), 682u);
  EXPECT_EQ(scan.ranges[4], 381u);
}

TEST(ScipReplay, BrokenDriverIsAMismatchAtTheScanRequest) {
  const std::string log = WIRETAPE_TEST_DATA_DIR "/flexiport/urg04lx_2011.log";
  auto port = open_or_skip("type=replay,file=" + log + ",match=request,timing=none,unused=ignore",
                           WIRETAPE_TEST_DATA_DIR "/flexiport/urg04lx_2011.logr");
  ASSERT_TRUE(port) << "test data missing: " << log;
  auto options = fast_options();
  options.inject_bug = true;
  hokuyo::Driver driver(*port, options);
  driver.open();
  driver.laser_on();
  try {
    driver.get_scan(hokuyo::ScanMode::gd, 44, 725, 1);
    FAIL() << "the replay accepted a request the device was never sent";
  } catch (const wiretape::ReplayMismatch& mismatch) {
    EXPECT_EQ(mismatch.exchange(), 9);  // GD0044072501 is the tenth exchange
    EXPECT_NE(std::string(mismatch.what()).find("GD0044072501"), std::string::npos)
        << mismatch.what();
  }
}

TEST(ScipReplay, CheckedInStreamRecordingInSequence) {
  const std::string file = HOKUYO_RECORDINGS_DIR "/urg04lx_md.wtape";
  auto port = open_or_skip("type=replay,timing=none,unused=error,file=" + file, file);
  if (!port) GTEST_SKIP() << "recording missing: " << file;
  hokuyo::Driver driver(*port, fast_options());
  driver.open();
  const auto params = driver.parameters();
  driver.state();
  driver.laser_on();
  driver.start_stream(hokuyo::ScanMode::md, params.first_step, params.last_step, 3, 0, 3);
  for (int remaining = 2; remaining >= 0; --remaining) {
    const auto scan = driver.read_stream_scan();
    EXPECT_EQ(scan.remaining, remaining);
    EXPECT_EQ(scan.ranges.size(), 228u);
  }
  EXPECT_FALSE(driver.streaming());
  port->close();
}

}  // namespace replayed

// --- hostile devices ------------------------------------------------------------

// Mutated and random replies end in ProtocolError or StatusError, never in a
// crash, a hang or a scan with the wrong number of values.
TEST(ScipHostileDevice, MutatedRepliesGiveCleanErrors) {
  std::uint32_t seed = 12345;
  auto next = [&seed]() {
    seed = seed * 1664525u + 1013904223u;
    return seed >> 8;
  };
  const std::string good = "GD0010010901\n" + status_line("00") + scan_body(77, ramp(100), 3);
  int errors = 0, scans = 0;
  for (int round = 0; round < 2000; ++round) {
    std::string reply = good;
    switch (round % 4) {
      case 0:  // flip bits
        for (int flips = 1 + next() % 3; flips > 0; --flips)
          reply[next() % reply.size()] ^= static_cast<char>(1u << (next() % 8));
        break;
      case 1:  // cut short
        reply.resize(next() % reply.size());
        break;
      case 2:  // insert noise
        reply.insert(next() % reply.size(), std::string(1 + next() % 20, static_cast<char>(next())));
        break;
      default:  // pure noise
        reply.clear();
        for (int n = next() % 600; n > 0; --n) reply += static_cast<char>(next());
    }
    ScriptedDevice device;
    device.respond = [&](const std::string&) { return reply; };
    hokuyo::Driver driver(device, fast_options());
    try {
      const auto scan = driver.get_scan(hokuyo::ScanMode::gd, 10, 109, 1);
      ASSERT_EQ(scan.ranges.size(), 100u) << "round " << round;
      ++scans;
    } catch (const hokuyo::ProtocolError&) {
      ++errors;
    } catch (const hokuyo::StatusError&) {
      ++errors;
    }
  }
  EXPECT_GT(errors, 1500);  // nearly every mutation is caught by a sum or a count
}

TEST(ScipHostileDevice, RecoverGivesUpOnANoisyDeviceInBoundedTime) {
  ScriptedDevice device;
  // A device that answers QT with endless noise and never a QT reply.
  device.respond = [](const std::string&) { return std::string(200000, 'x') + "\n"; };
  auto options = fast_options();
  hokuyo::Driver driver(device, options);
  const auto started = std::chrono::steady_clock::now();
  EXPECT_THROW(driver.recover(), hokuyo::ProtocolError);
  EXPECT_LT(std::chrono::steady_clock::now() - started, 5s);
}
