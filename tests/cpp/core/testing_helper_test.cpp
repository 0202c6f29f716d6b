// wiretape/testing.hpp: the GoogleTest helper records from a device when
// asked to and replays otherwise, keeping recordings of passing tests only.
#include "wiretape/testing.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <vector>

#include "wiretape/errors.hpp"
#include "wiretape/session.hpp"

namespace fs = std::filesystem;
using wiretape::testing::Cassette;
using wiretape::testing::CassetteSettings;
using wiretape::testing::RecordMode;

namespace {

using namespace std::chrono_literals;

class TemporaryDirectory {
 public:
  TemporaryDirectory() {
    std::string pattern = (fs::temp_directory_path() / "wiretape-testing-XXXXXX").string();
    if (!::mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~TemporaryDirectory() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

std::string file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// All tx bytes and all rx bytes of a session, in order.
std::pair<std::string, std::string> streams(const fs::path& path) {
  wiretape::SessionReader reader(path.string());
  std::pair<std::string, std::string> tx_rx;
  wiretape::Record record;
  while (reader.next(record)) {
    if (record.kind == wiretape::RecordKind::tx) tx_rx.first += record.data;
    if (record.kind == wiretape::RecordKind::rx) tx_rx.second += record.data;
  }
  return tx_rx;
}

void echo(wiretape::Port& port, const std::string& text) {
  ASSERT_EQ(port.write_all(text), text.size());
  EXPECT_EQ(port.read_exactly(text.size(), 5s), text);
}

CassetteSettings recording_from_loopback() {
  CassetteSettings settings;
  settings.record = RecordMode::rewrite;
  settings.device = "type=loopback";
  return settings;
}

std::size_t leftovers(const fs::path& directory) {
  std::size_t count = 0;
  for (const auto& entry : fs::directory_iterator(directory)) {
    if (entry.path().filename().string().find(".recording-") != std::string::npos) ++count;
  }
  return count;
}

TEST(Cassette, RecordsFromTheDeviceThenReplaysWithoutIt) {
  TemporaryDirectory directory;
  const fs::path path = directory.path() / "echo.wtape";
  {
    Cassette cassette(path.string(), recording_from_loopback(), {}, "Suite.Echo");
    EXPECT_TRUE(cassette.recording());
    echo(cassette.port(), "hello\n");
    cassette.finish(true);
  }
  ASSERT_TRUE(fs::exists(path));
  EXPECT_EQ(streams(path), std::make_pair(std::string("hello\n"), std::string("hello\n")));
  EXPECT_EQ(leftovers(directory.path()), 0u);
  wiretape::SessionReader reader(path.string());
  EXPECT_NE(reader.header().metadata_json.find("Suite.Echo"), std::string::npos);

  Cassette replay(path.string(), CassetteSettings{}, "unused=error");
  EXPECT_FALSE(replay.recording());
  EXPECT_NE(replay.options().find("type=replay"), std::string::npos);
  EXPECT_NE(replay.options().find("timing=none"), std::string::npos);
  echo(replay.port(), "hello\n");
  EXPECT_NO_THROW(replay.finish(true));
}

TEST(Cassette, ReplayReallyServesTheRecording) {
  TemporaryDirectory directory;
  const fs::path path = directory.path() / "echo.wtape";
  {
    Cassette cassette(path.string(), recording_from_loopback());
    echo(cassette.port(), "hello\n");
    cassette.finish(true);
  }
  Cassette replay(path.string(), CassetteSettings{}, "unused=ignore");
  wiretape::Port& port = replay.port();
  EXPECT_THROW(
      {
        port.write_all(std::string("howdy\n"));
        port.read_exactly(6, 1s);
      },
      wiretape::ReplayMismatch);
}

TEST(Cassette, UnusedRecordedDataFailsAtTheEndUnderUnusedError) {
  TemporaryDirectory directory;
  const fs::path path = directory.path() / "two.wtape";
  {
    Cassette cassette(path.string(), recording_from_loopback());
    echo(cassette.port(), "one\n");
    echo(cassette.port(), "two\n");
    cassette.finish(true);
  }
  Cassette replay(path.string(), CassetteSettings{}, "unused=error");
  echo(replay.port(), "one\n");
  EXPECT_THROW(replay.finish(true), wiretape::ReplayMismatch);
}

TEST(Cassette, AFailedRecordingLeavesThePreviousCassette) {
  TemporaryDirectory directory;
  const fs::path path = directory.path() / "echo.wtape";
  {
    Cassette cassette(path.string(), recording_from_loopback());
    echo(cassette.port(), "first\n");
    cassette.finish(true);
  }
  const std::string previous = file_bytes(path);
  {
    Cassette cassette(path.string(), recording_from_loopback());
    echo(cassette.port(), "second\n");
    cassette.finish(false);
  }
  EXPECT_EQ(file_bytes(path), previous);
  EXPECT_EQ(leftovers(directory.path()), 0u);
  {
    // A cassette left unfinished (the test threw) is not kept either.
    Cassette cassette(path.string(), recording_from_loopback());
    echo(cassette.port(), "third\n");
  }
  EXPECT_EQ(file_bytes(path), previous);
  EXPECT_EQ(leftovers(directory.path()), 0u);
}

TEST(Cassette, OnceRecordsOnlyMissingCassettes) {
  TemporaryDirectory directory;
  const fs::path path = directory.path() / "echo.wtape";
  CassetteSettings once = recording_from_loopback();
  once.record = RecordMode::once;
  {
    Cassette cassette(path.string(), once);
    EXPECT_TRUE(cassette.recording());
    echo(cassette.port(), "hi\n");
    cassette.finish(true);
  }
  Cassette again(path.string(), once);
  EXPECT_FALSE(again.recording());
}

TEST(Cassette, MissingCassetteOrDeviceIsAClearError) {
  TemporaryDirectory directory;
  const fs::path path = directory.path() / "missing.wtape";
  Cassette replay(path.string(), CassetteSettings{}, {}, "Suite.Name");
  try {
    replay.port();
    FAIL() << "expected an error";
  } catch (const std::runtime_error& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find(path.string()), std::string::npos) << message;
    EXPECT_NE(message.find("WIRETAPE_RECORD=once WIRETAPE_DEVICE="), std::string::npos) << message;
    EXPECT_NE(message.find("--gtest_filter='Suite.Name'"), std::string::npos) << message;
  }
  CassetteSettings no_device;
  no_device.record = RecordMode::rewrite;
  Cassette recording(path.string(), no_device);
  try {
    recording.port();
    FAIL() << "expected an error";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find("WIRETAPE_DEVICE"), std::string::npos);
  }
}

TEST(CassetteNames, RecordedDeviceIsTheDeviceWithoutWhatTheRecordingAdded) {
  using wiretape::testing::recorded_device;
  EXPECT_EQ(recorded_device("type=serial,device=/dev/ttyUSB0,baud=115200,log=t.wtape,"
                            "meta_gtest=Suite.Test"),
            "type=serial,device=/dev/ttyUSB0,baud=115200");
  EXPECT_EQ(recorded_device("type=tcp,host=10.0.0.5,port=502,log=t.wtape,meta_pytest_node="
                            "'t.py::test',meta_board=rev2"),
            "type=tcp,host=10.0.0.5,port=502,meta_board=rev2");
  EXPECT_EQ(recorded_device("log=t.wtape"), "");
  EXPECT_EQ(recorded_device(""), "");
  EXPECT_EQ(wiretape::testing::shell_quoted("device=/dev/it's"), "'device=/dev/it'\\''s'");
}

TEST(Cassette, TheRecordCommandNamesTheDeviceTheCassetteWasRecordedFrom) {
  TemporaryDirectory directory;
  const fs::path path = directory.path() / "echo.wtape";
  CassetteSettings settings = recording_from_loopback();
  settings.device = "type=loopback,timeout=2";
  {
    Cassette cassette(path.string(), settings, {}, "Suite.Echo");
    echo(cassette.port(), "hello\n");
    cassette.finish(true);
  }
  const std::string command = Cassette(path.string(), CassetteSettings{}, {}, "Suite.Echo")
                                  .record_command();
  EXPECT_NE(command.find("WIRETAPE_RECORD=rewrite WIRETAPE_DEVICE='type=loopback,timeout=2' "),
            std::string::npos)
      << command;
  EXPECT_NE(command.find("--gtest_filter='Suite.Echo'"), std::string::npos) << command;
}

TEST(Cassette, BarePathDeviceMeansASerialPort) {
  CassetteSettings settings = recording_from_loopback();
  settings.device = "/dev/ttyUSB0";
  Cassette cassette("/tmp/never.wtape", settings);
  EXPECT_EQ(cassette.options().rfind("type=serial,device=/dev/ttyUSB0,log=", 0), 0u)
      << cassette.options();
}

TEST(Cassette, ReplayKeysOverrideTheDefaultTiming) {
  TemporaryDirectory directory;
  const fs::path path = directory.path() / "x.wtape";
  std::ofstream(path) << "placeholder";
  Cassette cassette(path.string(), CassetteSettings{}, "timing=causal,match=request");
  const std::string options = cassette.options();
  EXPECT_EQ(options.find("timing=none"), std::string::npos) << options;
  EXPECT_NE(options.find("timing=causal,match=request"), std::string::npos) << options;
}

TEST(CassetteSettings, ComeFromTheEnvironment) {
  std::map<std::string, std::string> environment{{"WIRETAPE_RECORD", "1"},
                                                 {"WIRETAPE_DEVICE", "type=loopback"},
                                                 {"WIRETAPE_CASSETTE_DIR", "/tmp/c"}};
  auto lookup = [&](const char* name) -> const char* {
    auto found = environment.find(name);
    return found == environment.end() ? nullptr : found->second.c_str();
  };
  auto settings = CassetteSettings::from_environment(lookup);
  EXPECT_EQ(settings.record, RecordMode::rewrite);
  EXPECT_EQ(settings.device, "type=loopback");
  EXPECT_EQ(settings.directory, "/tmp/c");
  environment["WIRETAPE_RECORD"] = "once";
  EXPECT_EQ(CassetteSettings::from_environment(lookup).record, RecordMode::once);
  environment.erase("WIRETAPE_RECORD");
  EXPECT_EQ(CassetteSettings::from_environment(lookup).record, RecordMode::none);
  environment["WIRETAPE_RECORD"] = "sometimes";
  EXPECT_THROW(CassetteSettings::from_environment(lookup), std::invalid_argument);
}

TEST(CassettePath, IsNextToTheSourceWithSafeNames) {
  // A name that had to change ends with 12 hex digits of its SHA-1
  // (wiretape/cassette_names.hpp; the pytest plugin's names are the same).
  EXPECT_EQ(wiretape::testing::default_cassette_path("/src/tests/cpp/scan_test.cpp",
                                                     "Models/ScanTest", "Reads/3"),
            "/src/tests/cpp/recordings/scan_test/Models_ScanTest.Reads_3-" +
                wiretape::testing::detail::sha1_hex("Models/ScanTest.Reads/3").substr(0, 12) +
                ".wtape");
  EXPECT_EQ(wiretape::testing::default_cassette_path("/src/a_test.cpp", "S", "T", "/elsewhere"),
            "/elsewhere/a_test/S.T.wtape");
  EXPECT_EQ(wiretape::testing::safe_file_name("../x y").substr(0, 4), "x_y-");
}

TEST(CassettePath, NamesThatCollideOnceMadeSafeGetDistinctCassettes) {
  using wiretape::testing::safe_file_name;
  EXPECT_NE(safe_file_name("t[a b]"), safe_file_name("t[a_b]"));
  EXPECT_EQ(safe_file_name("t_a_b"), "t_a_b");  // a safe name is kept as it is
  const std::string long_name(300, 'x');
  EXPECT_EQ(safe_file_name(long_name).size(), wiretape::testing::max_cassette_name_length);
  EXPECT_NE(safe_file_name(long_name), safe_file_name(long_name + "y"));
}

TEST(CassettePath, Sha1IsTheStandardOne) {
  EXPECT_EQ(wiretape::testing::detail::sha1_hex(""), "da39a3ee5e6b4b0d3255bfef95601890afd80709");
  EXPECT_EQ(wiretape::testing::detail::sha1_hex("abc"),
            "a9993e364706816aba3e25717850c26c9cd0d89d");
  EXPECT_EQ(wiretape::testing::detail::sha1_hex(std::string(1000, 'a')),
            "291e9a6c66994949b57ba5e650361e98fc36b1ba");
}

// The header's JSON less its start time, the one field that differs between
// two recordings of one test on one machine.
std::string header_without_start(const fs::path& cassette) {
  wiretape::SessionReader reader(cassette.string());
  const wiretape::SessionHeader& header = reader.header();
  std::string json = header.metadata_json;
  const std::size_t at = json.find(header.start_utc);
  if (!header.start_utc.empty() && at != std::string::npos) {
    json.erase(at, header.start_utc.size());
  }
  return json;
}

TEST(Cassette, TwoRecordingsOfATestHaveTheSameHeaderButForTheStartTime) {
  // Before, the header kept the temporary file it was recorded to, an
  // absolute path ending with the recording process's PID.
  TemporaryDirectory first, second;
  std::vector<std::string> headers;
  for (const TemporaryDirectory* directory : {&first, &second}) {
    const fs::path path = directory->path() / "recordings" / "Suite.Echo.wtape";
    fs::create_directories(path.parent_path());
    Cassette cassette(path.string(), recording_from_loopback(), {}, "Suite.Echo");
    echo(cassette.port(), "hello\n");
    cassette.finish(true);
    ASSERT_TRUE(fs::exists(path));
    EXPECT_EQ(leftovers(path.parent_path()), 0u);
    EXPECT_EQ(streams(path), std::make_pair(std::string("hello\n"), std::string("hello\n")));
    wiretape::SessionReader reader(path.string());
    EXPECT_EQ(reader.header().port_options,
              "type=loopback,log=Suite.Echo.wtape,meta_gtest=Suite.Echo");
    headers.push_back(header_without_start(path));
    EXPECT_EQ(headers.back().find(directory->path().string()), std::string::npos) << headers.back();
    EXPECT_EQ(headers.back().find(".recording-"), std::string::npos) << headers.back();
  }
  EXPECT_EQ(headers[0], headers[1]);
}

TEST(Cassette, ADamagedRecordingIsPublishedAsItIs) {
  TemporaryDirectory directory;
  const fs::path recording = directory.path() / "t.wtape.recording-1";
  {
    wiretape::SessionHeader header;
    header.port_options = "type=loopback,log=" + recording.string();
    wiretape::SessionWriter writer(recording.string(), header);
    writer.write(wiretape::RecordKind::tx, 1, "abc");
    writer.write(wiretape::RecordKind::rx, 2, "abc");
  }
  const std::string bytes = file_bytes(recording);
  {
    std::ofstream cut(recording, std::ios::binary | std::ios::trunc);
    cut << bytes.substr(0, bytes.size() - 2);
  }
  wiretape::testing::publish_recording(recording.string(), (directory.path() / "t.wtape").string());
  EXPECT_FALSE(fs::exists(recording));
  EXPECT_EQ(file_bytes(directory.path() / "t.wtape"), bytes.substr(0, bytes.size() - 2));
  EXPECT_EQ(leftovers(directory.path()), 0u);
}

// A cassette that is a symbolic link (into a store of recordings, dangling
// before its first recording) is written where the link points; the link
// stays, and the header names the cassette by the link's name.
TEST(Cassette, ALinkedCassetteIsWrittenThroughTheLink) {
  TemporaryDirectory directory;
  fs::create_directories(directory.path() / "store");
  const fs::path cassette = directory.path() / "t.wtape";
  fs::create_symlink(fs::path("store") / "t-1.wtape", cassette);  // dangling, relative
  EXPECT_EQ(wiretape::testing::cassette_target(cassette), directory.path() / "store" / "t-1.wtape");
  for (const char* data : {"first", "second"}) {
    const fs::path recording = directory.path() / "t.wtape.recording-1";
    {
      wiretape::SessionHeader header;
      header.port_options = "type=loopback,log=" + recording.string();
      wiretape::SessionWriter writer(recording.string(), header);
      writer.write(wiretape::RecordKind::tx, 1, data);
    }
    wiretape::testing::publish_recording(recording.string(), cassette.string());
    EXPECT_TRUE(fs::is_symlink(cassette));
    EXPECT_FALSE(fs::exists(recording));
    wiretape::SessionReader reader((directory.path() / "store" / "t-1.wtape").string());
    EXPECT_EQ(reader.header().port_options, "type=loopback,log=t.wtape");
    wiretape::Record record;
    ASSERT_TRUE(reader.next(record));
    EXPECT_EQ(record.data, data);
  }
}

// The fixture itself, on a cassette recorded from type=loopback and kept in
// tests/cpp/core/recordings/testing_helper_test/ (record it again with
// WIRETAPE_RECORD=1 WIRETAPE_DEVICE=type=loopback).
class CassetteFixture : public wiretape::testing::CassetteTest {};

TEST_F(CassetteFixture, EchoesThroughTheCassette) {
  wiretape::Port& device = port("unused=error");
  echo(device, "PING\r");
  echo(device, "VV\n");
  ASSERT_NE(cassette(), nullptr);
  EXPECT_EQ(fs::path(cassette()->path()).filename(), "CassetteFixture.EchoesThroughTheCassette.wtape");
  EXPECT_EQ(fs::path(cassette()->path()).parent_path().filename(), "testing_helper_test");
}

// Run by CassetteFixtureProgram below only, on copies of the cassette above:
// the driver writes what the cassette does not hold (a mismatch escapes the
// test body), or leaves recorded data unused.
TEST_F(CassetteFixture, DISABLED_WritesWhatTheCassetteDoesNotHold) {
  wiretape::Port& device = port("unused=error");  // kPortCallLine
  echo(device, "PING\r");
  device.write_all("XX\n");
}

TEST_F(CassetteFixture, DISABLED_LeavesRecordedDataUnused) {
  wiretape::Port& device = port("unused=error");  // kPortCallLine
  echo(device, "PING\r");
}

// The fixture's two paths through the environment, as a developer runs them:
// this program runs its own CassetteFixture test, first recording from
// type=loopback, then replaying what it recorded.
int run_fixture_test(const std::string& environment) {
  const std::string program = std::string(WIRETAPE_BIN_DIR) + "/testing_helper_test";
  const std::string command = environment + " '" + program +
                              "' --gtest_filter=CassetteFixture.EchoesThroughTheCassette"
                              " > /dev/null 2>&1";
  return std::system(command.c_str());
}

TEST(CassetteFixtureProgram, RecordsWithTheEnvironmentThenReplays) {
  TemporaryDirectory directory;
  const std::string where = "WIRETAPE_CASSETTE_DIR='" + directory.path().string() + "'";
  const fs::path cassette = directory.path() / "testing_helper_test" /
                            "CassetteFixture.EchoesThroughTheCassette.wtape";

  EXPECT_NE(run_fixture_test("env -u WIRETAPE_RECORD " + where), 0)
      << "replay must fail while the cassette is missing";
  EXPECT_FALSE(fs::exists(cassette));

  ASSERT_EQ(run_fixture_test("env WIRETAPE_RECORD=1 WIRETAPE_DEVICE=type=loopback " + where), 0);
  ASSERT_TRUE(fs::exists(cassette));
  EXPECT_EQ(streams(cassette), std::make_pair(std::string("PING\rVV\n"), std::string("PING\rVV\n")));

  EXPECT_EQ(run_fixture_test("env -u WIRETAPE_RECORD -u WIRETAPE_DEVICE " + where), 0);
  const std::string recorded = file_bytes(cassette);
  EXPECT_NE(run_fixture_test("env -u WIRETAPE_DEVICE WIRETAPE_RECORD=1 " + where), 0)
      << "recording without WIRETAPE_DEVICE must fail";
  EXPECT_EQ(file_bytes(cassette), recorded);
}

// What a failing CassetteTest prints: the output of one test of this program
// run on its own, with cassettes under `directory`.
std::string fixture_test_output(const std::string& test, const fs::path& directory) {
  const std::string program = std::string(WIRETAPE_BIN_DIR) + "/testing_helper_test";
  const std::string command = "env -u WIRETAPE_RECORD -u WIRETAPE_DEVICE WIRETAPE_CASSETTE_DIR='" +
                              directory.string() + "' '" + program + "' --gtest_filter='" + test +
                              "' --gtest_also_run_disabled_tests 2>&1";
  std::string output;
  FILE* pipe = ::popen(command.c_str(), "r");
  if (pipe == nullptr) return output;
  char buffer[4096];
  for (std::size_t n; (n = std::fread(buffer, 1, sizeof buffer, pipe)) > 0;) output.append(buffer, n);
  ::pclose(pipe);
  return output;
}

std::size_t occurrences(const std::string& text, const std::string& word) {
  std::size_t count = 0;
  for (auto at = text.find(word); at != std::string::npos; at = text.find(word, at + 1)) ++count;
  return count;
}

// A failure names the line of the test's port() call: this file's line
// that holds the marker, within `test`'s body.
std::string port_call_location(const std::string& test) {
  // This file, found from the test data folder: __FILE__ may be relative to
  // a build folder (a compiler cache's base directory).
  std::ifstream source(fs::path(WIRETAPE_TEST_DATA_DIR).parent_path() / "cpp" / "core" /
                       fs::path(__FILE__).filename());
  std::string line;
  bool in_test = false;
  for (int number = 1; std::getline(source, line); ++number) {
    if (line.find(test) != std::string::npos) in_test = true;
    if (in_test && line.find("// kPortCallLine") != std::string::npos) {
      return fs::path(__FILE__).filename().string() + ":" + std::to_string(number) + ": ";
    }
  }
  return {};
}

class FailingFixtureTests : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_EQ(run_fixture_test("env WIRETAPE_RECORD=1 WIRETAPE_DEVICE=type=loopback "
                               "WIRETAPE_CASSETTE_DIR='" + directory_.path().string() + "'"),
              0);
    const fs::path folder = directory_.path() / "testing_helper_test";
    for (const char* test : {"WritesWhatTheCassetteDoesNotHold", "LeavesRecordedDataUnused"}) {
      fs::copy_file(folder / "CassetteFixture.EchoesThroughTheCassette.wtape",
                    folder / ("CassetteFixture.DISABLED_" + std::string(test) + ".wtape"));
    }
  }
  TemporaryDirectory directory_;
};

TEST_F(FailingFixtureTests, AMismatchFailsOnceAtThePortCallWithTheWayOut) {
  const std::string test = "CassetteFixture.DISABLED_WritesWhatTheCassetteDoesNotHold";
  const std::string output = fixture_test_output(test, directory_.path());
  EXPECT_EQ(occurrences(output, "Failure"), 1u) << output;
  EXPECT_NE(output.find("mismatch"), std::string::npos) << output;
  const std::string location = port_call_location("DISABLED_WritesWhatTheCassetteDoesNotHold");
  ASSERT_FALSE(location.empty()) << "the test's source is not in " << WIRETAPE_TEST_DATA_DIR;
  EXPECT_NE(output.find(location + "replaying cassette "), std::string::npos) << output;
  // The device the cassette was recorded from, as its header keeps it.
  EXPECT_NE(output.find("WIRETAPE_RECORD=rewrite WIRETAPE_DEVICE='type=loopback' "),
            std::string::npos)
      << output;
  EXPECT_EQ(output.find("OPTS"), std::string::npos) << output;
  EXPECT_NE(output.find("--gtest_filter='" + test + "'"), std::string::npos) << output;
  EXPECT_NE(output.find("[  FAILED  ] " + test), std::string::npos) << output;
}

TEST(CassetteFixtureProgram, AMissingCassettePrintsOneCommandThatRecordsIt) {
  TemporaryDirectory directory;
  const std::string output =
      fixture_test_output("CassetteFixture.EchoesThroughTheCassette", directory.path());
  EXPECT_NE(output.find("no recording "), std::string::npos) << output;
  EXPECT_EQ(occurrences(output, "WIRETAPE_RECORD="), 1u) << output;
  EXPECT_NE(output.find("WIRETAPE_RECORD=once WIRETAPE_DEVICE=OPTS "), std::string::npos)
      << output;
  EXPECT_NE(output.find("(missing)"), std::string::npos) << output;
}

TEST_F(FailingFixtureTests, UnusedDataFailsOnceAtThePortCall) {
  const std::string test = "CassetteFixture.DISABLED_LeavesRecordedDataUnused";
  const std::string output = fixture_test_output(test, directory_.path());
  EXPECT_EQ(occurrences(output, "Failure"), 1u) << output;
  EXPECT_NE(output.find("unused"), std::string::npos) << output;
  const std::string location = port_call_location("DISABLED_LeavesRecordedDataUnused");
  ASSERT_FALSE(location.empty()) << "the test's source is not in " << WIRETAPE_TEST_DATA_DIR;
  EXPECT_NE(output.find(location + "replaying cassette "), std::string::npos) << output;
}

// --- cassettes of several channels (DESIGN §19) ----------------------------------------

CassetteSettings recording_channels_from_loopback() {
  CassetteSettings settings;
  settings.record = RecordMode::rewrite;
  settings.lookup = [](const char* name) -> const char* {
    const std::string variable = name;
    if (variable == "WIRETAPE_DEVICE_gps") return "type=loopback";
    if (variable == "WIRETAPE_DEVICE_rtk_1") return "type=loopback,timeout=2";
    return nullptr;
  };
  return settings;
}

TEST(CassetteChannels, RecordThroughOneRecorderIntoOneCassette) {
  TemporaryDirectory directory;
  const fs::path path = directory.path() / "two.wtape";
  {
    Cassette cassette(path.string(), recording_channels_from_loopback(), {}, "Suite.Two");
    echo(cassette.port_of("gps"), "$GPGGA\n");
    echo(cassette.port_of("rtk-1"), "RTCM\n");
    echo(cassette.port_of("gps"), "$GPRMC\n");  // the same port again
    cassette.finish(true);
  }
  ASSERT_TRUE(fs::exists(path));
  EXPECT_EQ(leftovers(directory.path()), 0u);
  wiretape::SessionReader reader(path.string());
  const auto& channels = reader.header().channels;
  ASSERT_EQ(channels.size(), 2u);
  EXPECT_EQ(channels[0].name, "gps");
  EXPECT_EQ(channels[0].port_options, "type=loopback");
  EXPECT_EQ(channels[1].name, "rtk-1");
  EXPECT_EQ(channels[1].port_options, "type=loopback,timeout=2");
  EXPECT_EQ(reader.header().user_metadata.at("gtest"), "Suite.Two");
  std::map<std::uint16_t, std::string> tx;
  wiretape::Record record;
  while (reader.next(record)) {
    if (record.kind == wiretape::RecordKind::tx) tx[record.channel] += record.data;
  }
  EXPECT_EQ(tx[0], "$GPGGA\n$GPRMC\n");
  EXPECT_EQ(tx[1], "RTCM\n");
}

TEST(CassetteChannels, AChannelWithoutADeviceOrMixedWithPortIsAClearError) {
  TemporaryDirectory directory;
  const fs::path path = directory.path() / "bad.wtape";
  Cassette cassette(path.string(), recording_channels_from_loopback());
  try {
    cassette.port_of("imu");
    FAIL() << "expected an error";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find("WIRETAPE_DEVICE_imu"), std::string::npos)
        << error.what();
  }
  cassette.port_of("gps");
  EXPECT_THROW(cassette.port(), std::logic_error);
  cassette.finish(false);
  EXPECT_FALSE(fs::exists(path));
  EXPECT_EQ(leftovers(directory.path()), 0u);
}

TEST(CassetteChannels, TheRecordCommandNamesEachChannelsDevice) {
  TemporaryDirectory directory;
  const fs::path path = directory.path() / "two.wtape";
  {
    Cassette cassette(path.string(), recording_channels_from_loopback());
    echo(cassette.port_of("gps"), "$GPGGA\n");
    echo(cassette.port_of("rtk-1"), "RTCM\n");
    cassette.finish(true);
  }
  const std::string command = Cassette(path.string(), CassetteSettings{}).record_command();
  EXPECT_NE(command.find("WIRETAPE_RECORD=rewrite WIRETAPE_DEVICE_gps='type=loopback' "
                         "WIRETAPE_DEVICE_rtk_1='type=loopback,timeout=2' "),
            std::string::npos)
      << command;
}

// Replays each channel with channel=NAME (part C of issue 25, engineer
// replaych): this test can pass only once type=replay takes channel=.
TEST(CassetteChannels, ReplaysEachChannelOfTheCassette) {
  TemporaryDirectory directory;
  const fs::path path = directory.path() / "replayed.wtape";
  {
    Cassette cassette(path.string(), recording_channels_from_loopback());
    echo(cassette.port_of("gps"), "$GPGGA\n");
    echo(cassette.port_of("rtk-1"), "RTCM\n");
    cassette.finish(true);
  }
  Cassette replay(path.string(), CassetteSettings{}, "unused=error");
  EXPECT_NE(replay.channel_options("gps").find("channel=gps"), std::string::npos);
  echo(replay.port_of("rtk-1"), "RTCM\n");
  echo(replay.port_of("gps"), "$GPGGA\n");
  EXPECT_NO_THROW(replay.finish(true));
}

}  // namespace
