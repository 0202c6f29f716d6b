// GoogleTest helper: driver tests that record a device once and replay it in
// CI. Header-only; include it in test programs that link GoogleTest (it is
// not part of <wiretape/wiretape.hpp>).
//
//   #include <wiretape/testing.hpp>
//
//   class ScannerTest : public wiretape::testing::CassetteTest {};
//
//   TEST_F(ScannerTest, ReadsOneScan) {
//     wiretape::Port& device = port();          // or port("match=request")
//     MyDriver driver(device);
//     EXPECT_EQ(driver.scan().size(), 682u);
//   }
//
// Each test has a cassette, a session file next to its source:
//   <dir of the .cpp>/recordings/<source file stem>/<Suite>.<Test>.wtape
// (names made safe as wiretape/cassette_names.hpp says, the pytest plugin's
// rules).
// By default the test replays it (type=replay,timing=none, plus the keys given
// to port()); a missing cassette fails the test with the command that records
// it. With the environment
//   WIRETAPE_RECORD=1 WIRETAPE_DEVICE=OPTS ./my_test --gtest_filter=...
// the port is the real device (OPTS is an option string; a bare path means
// type=serial,device=PATH) recording to the cassette. A recording is kept only
// when the test passes; a failing test leaves the previous cassette as it was.
// The cassette's header names the cassette (log=<its file name>), not the
// temporary file it was recorded to (publish_recording).
// WIRETAPE_RECORD=once records only the missing cassettes.
// WIRETAPE_CASSETTE_DIR=DIR puts cassettes under DIR instead of next to the
// source (for sources compiled with relative __FILE__ paths, or read-only
// trees).
//
// A test of a driver that talks to several devices gets one port per
// channel of one cassette (DESIGN §19) with port_of("gps"), port_of("rtk"):
// recorded through one wiretape::Recorder from WIRETAPE_DEVICE_gps=OPTS,
// WIRETAPE_DEVICE_rtk=OPTS (the channel's name, a '-' in it spelled '_'), on
// one clock; replayed with channel=NAME, the channels of the cassette on one
// clock. A test uses either port() or port_of(), not both.
#pragma once

#include <gtest/gtest.h>

#include <cctype>
#include <cerrno>  // program_invocation_name (glibc)
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <functional>
#include <memory>
#include <map>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>

#include <unistd.h>

#include "wiretape/cassette_names.hpp"
#include "wiretape/options.hpp"
#include "wiretape/port.hpp"
#include "wiretape/recorder.hpp"
#include "wiretape/session.hpp"

namespace wiretape::testing {

enum class RecordMode {
  none,     // replay only
  once,     // record the cassettes that are missing, replay the others
  rewrite,  // record every cassette anew
};

// Where the mode and the device come from (the environment, for tests).
struct CassetteSettings {
  RecordMode record = RecordMode::none;
  std::string device;     // the device's option string, when recording
  std::string directory;  // replaces the directory of cassettes ("" = next to the source)
  // The device of each channel when recording (WIRETAPE_DEVICE_<name>), by
  // channel name; filled as channels are asked for (channel_device).
  std::function<const char*(const char*)> lookup;

  // The environment variable naming channel `name`'s device:
  // WIRETAPE_DEVICE_<name>, a '-' in it spelled '_'.
  static std::string channel_device_variable(const std::string& name) {
    std::string variable = "WIRETAPE_DEVICE_" + name;
    for (char& c : variable) {
      if (c == '-') c = '_';
    }
    return variable;
  }

  // The option string of channel `name`'s device, "" when none is given.
  std::string channel_device(const std::string& name) const {
    const std::string variable = channel_device_variable(name);
    const char* value = lookup ? lookup(variable.c_str()) : std::getenv(variable.c_str());
    return value ? value : "";
  }

  // WIRETAPE_RECORD (unset/0/none, 1/rewrite, once), WIRETAPE_DEVICE,
  // WIRETAPE_CASSETTE_DIR. `lookup` is getenv unless a test gives another.
  static CassetteSettings from_environment(
      const std::function<const char*(const char*)>& lookup = [](const char* name) {
        return std::getenv(name);
      }) {
    CassetteSettings settings;
    settings.lookup = lookup;
    const char* record = lookup("WIRETAPE_RECORD");
    const std::string mode = record ? record : "";
    if (mode.empty() || mode == "0" || mode == "none") {
      settings.record = RecordMode::none;
    } else if (mode == "1" || mode == "rewrite") {
      settings.record = RecordMode::rewrite;
    } else if (mode == "once") {
      settings.record = RecordMode::once;
    } else {
      throw std::invalid_argument("WIRETAPE_RECORD=" + mode +
                                  " is not one of 0, 1, none, once, rewrite");
    }
    if (const char* device = lookup("WIRETAPE_DEVICE")) settings.device = device;
    if (const char* directory = lookup("WIRETAPE_CASSETTE_DIR")) settings.directory = directory;
    return settings;
  }
};

// One test's cassette: whether it records or replays, the option string, the
// port, and what happens to the recording when the test ends.
class Cassette {
 public:
  Cassette(std::string path, CassetteSettings settings, std::string replay_keys = {},
           std::string test_name = {})
      : path_(std::move(path)),
        settings_(std::move(settings)),
        replay_keys_(std::move(replay_keys)),
        test_name_(std::move(test_name)) {
    const bool exists = std::filesystem::exists(path_);
    recording_ = settings_.record == RecordMode::rewrite ||
                 (settings_.record == RecordMode::once && !exists);
    partial_path_ = path_ + ".recording-" + std::to_string(::getpid());
  }
  ~Cassette() {
    try {
      finish(false);
    } catch (...) {
      // Destructors must not throw; finish(false) only cleans up.
    }
  }
  Cassette(const Cassette&) = delete;
  Cassette& operator=(const Cassette&) = delete;

  const std::string& path() const noexcept { return path_; }
  bool recording() const noexcept { return recording_; }

  // The option string that opens the device (recording) or the replay.
  // Throws std::runtime_error, naming the cassette and the way out, when the
  // test cannot run: no cassette to replay, or no device to record from.
  std::string options() const {
    if (recording_) {
      if (settings_.device.empty()) {
        throw std::runtime_error("wiretape: cassette " + path_ +
                                 " must be recorded (WIRETAPE_RECORD is set) but "
                                 "WIRETAPE_DEVICE names no device");
      }
      std::string text = device_options(settings_.device) + ",log=" +
                         quote_option_value(partial_path_);
      if (!test_name_.empty()) text += ",meta_gtest=" + quote_option_value(test_name_);
      return text;
    }
    if (!std::filesystem::exists(path_)) {
      throw std::runtime_error("wiretape: no recording " + path_ +
                               "; record it from the device with\n    " +
                               record_command());
    }
    std::string text = "type=replay,file=" + quote_option_value(path_);
    if (!Options::parse(replay_keys_).has("timing")) text += ",timing=none";
    if (!replay_keys_.empty()) text += "," + replay_keys_;
    return text;
  }

  // The shell command that records this cassette from its device: `once`
  // while it is missing, `rewrite` once it exists. The device is
  // WIRETAPE_DEVICE when set, else the one the cassette's header says it was
  // recorded from (each channel's, for a cassette of several), else OPTS.
  std::string record_command() const {
    std::string program = "<this test program>";
#ifdef __GLIBC__
    if (program_invocation_name != nullptr && *program_invocation_name != '\0') {
      program = program_invocation_name;
    }
#endif
    const bool exists = std::filesystem::exists(path_);
    std::string text = std::string("WIRETAPE_RECORD=") + (exists ? "rewrite" : "once") + " " +
                       device_assignments(exists) + program;
    if (!test_name_.empty()) text += " --gtest_filter=" + shell_quoted(test_name_);
    return text;
  }

  // The port (opened on first use).
  Port& port() {
    if (!channel_ports_.empty()) {
      throw std::logic_error("wiretape: cassette " + path_ + " has named ports already "
                             "(port_of()); a test uses port() or port_of(NAME), not both");
    }
    if (!port_) port_ = open_port(options());
    return *port_;
  }

  // The option string of channel `name` of a cassette of several channels:
  // its device, recorded into the cassette's channel NAME, or its replay.
  // Throws std::runtime_error as options() does, naming the channel.
  std::string channel_options(const std::string& name) const {
    if (recording_) {
      const std::string device = settings_.channel_device(name);
      if (device.empty()) {
        const std::string variable = CassetteSettings::channel_device_variable(name);
        throw std::runtime_error("wiretape: cassette " + path_ + " must be recorded "
                                 "(WIRETAPE_RECORD is set) but " + variable +
                                 " names no device for its channel \"" + name + "\"");
      }
      return "name=" + name + "," + device_options(device);
    }
    if (!std::filesystem::exists(path_)) {
      throw std::runtime_error("wiretape: no recording " + path_ +
                               "; record it from the devices with\n    " +
                               record_command());
    }
    std::string text = "type=replay,file=" + quote_option_value(path_) + ",channel=" + name;
    if (!Options::parse(replay_keys_).has("timing")) text += ",timing=none";
    if (!replay_keys_.empty()) text += "," + replay_keys_;
    return text;
  }

  // The port of channel `name` (opened on first use): a cassette of several
  // channels, recorded through one Recorder, replayed with channel=NAME.
  Port& port_of(const std::string& name) {
    if (port_) {
      throw std::logic_error("wiretape: cassette " + path_ + " has one unnamed port already "
                             "(port()); a test uses port() or port_of(NAME), not both");
    }
    const auto found = channel_ports_.find(name);
    if (found != channel_ports_.end()) return *found->second;
    std::unique_ptr<Port> opened;
    if (recording_) {
      const std::string options = channel_options(name);
      if (!recorder_) {
        SessionHeader header = SessionHeader::starting_now();
        if (!test_name_.empty()) header.user_metadata["gtest"] = test_name_;
        recorder_ = std::make_shared<Recorder>(partial_path_, header);
      }
      opened = recorder_->open_port(options);
    } else {
      opened = open_port(channel_options(name));
    }
    return *channel_ports_.emplace(name, std::move(opened)).first->second;
  }

  // Ends the test: closes the port, letting what close() raises through (a
  // replay with unused=error reports unused data there); keeps the recording
  // when `passed`, otherwise removes it and leaves any previous cassette.
  void finish(bool passed) {
    if (finished_) return;
    finished_ = true;
    std::exception_ptr close_error;
    if (port_) {
      try {
        if (port_->is_open()) port_->close();
      } catch (...) {
        close_error = std::current_exception();
      }
      port_.reset();
    }
    for (auto& [name, channel_port] : channel_ports_) {
      try {
        if (channel_port->is_open()) channel_port->close();
      } catch (...) {
        if (!close_error) close_error = std::current_exception();
      }
      channel_port.reset();
    }
    channel_ports_.clear();
    if (recorder_) {
      try {
        recorder_->close();
      } catch (...) {
        if (!close_error) close_error = std::current_exception();
      }
      recorder_.reset();
    }
    if (recording_) {
      std::error_code ignored;
      if (passed && !close_error && std::filesystem::exists(partial_path_)) {
        std::filesystem::create_directories(std::filesystem::path(path_).parent_path());
        publish_recording(partial_path_, path_);
      } else {
        std::filesystem::remove(partial_path_, ignored);
      }
    }
    if (close_error) std::rethrow_exception(close_error);
  }

 private:
  // `WIRETAPE_DEVICE='...' ` (or one WIRETAPE_DEVICE_<name> per channel) for
  // record_command().
  std::string device_assignments(bool exists) const {
    if (!settings_.device.empty()) return "WIRETAPE_DEVICE=" + shell_quoted(settings_.device) + " ";
    std::string text;
    if (exists) {
      try {
        for (const Channel& channel : SessionReader(path_).header().channel_list()) {
          const std::string device = recorded_device(channel.port_options);
          if (device.empty()) continue;
          text += (channel.name.empty() ? std::string("WIRETAPE_DEVICE")
                                        : CassetteSettings::channel_device_variable(channel.name)) +
                  "=" + shell_quoted(device) + " ";
        }
      } catch (const std::exception&) {
        // A cassette that cannot be read says nothing of its device.
      }
    }
    return text.empty() ? "WIRETAPE_DEVICE=OPTS " : text;
  }

  std::string path_;
  std::string partial_path_;
  CassetteSettings settings_;
  std::string replay_keys_;
  std::string test_name_;
  bool recording_ = false;
  bool finished_ = false;
  std::unique_ptr<Port> port_;
  std::shared_ptr<Recorder> recorder_;
  std::map<std::string, std::unique_ptr<Port>> channel_ports_;
};

// A GoogleTest fixture whose tests get a port from their cassette.
class CassetteTest : public ::testing::Test {
 protected:
  // The port of this test's cassette, opened on first call. `replay_keys`
  // (e.g. "match=request,unused=error") apply when replaying; timing=none
  // unless they say otherwise. `source_file` locates the cassette: the
  // default is the file of the calling test (GCC, Clang and MSVC support
  // __builtin_FILE()).
  //
  // Every failure of the test from then on (a replay mismatch that escapes
  // the test body, unused data at the end) carries the file and line of
  // this call, the cassette and the command that records it again.
  Port& port(std::string_view replay_keys = {},
             const char* source_file = __builtin_FILE(), int source_line = __builtin_LINE()) {
    return start_cassette(replay_keys, source_file, source_line).port();
  }

  // The port of channel `name` of this test's cassette of several channels
  // (DESIGN §19), opened on first call: recorded through one Recorder from
  // WIRETAPE_DEVICE_<name>, replayed with channel=NAME. `replay_keys` apply
  // to every channel; the first call's are kept.
  Port& port_of(const std::string& name, std::string_view replay_keys = {},
                const char* source_file = __builtin_FILE(), int source_line = __builtin_LINE()) {
    return start_cassette(replay_keys, source_file, source_line).port_of(name);
  }

  // The cassette, once port() was called (nullptr before).
  Cassette* cassette() const noexcept { return cassette_.get(); }

  void TearDown() override {
    if (!cassette_) return;
    const bool failed = HasFailure();
    try {
      cassette_->finish(!failed);
    } catch (const std::exception& error) {
      // A test that failed already (a mismatch) leaves recorded data unused
      // and the replay says so at close: one cause, reported once.
      if (!failed) {
        ADD_FAILURE() << "closing the port of cassette " << cassette_->path()
                      << " failed: " << error.what();
      }
    }
    trace_.reset();
  }

 private:
  Cassette& start_cassette(std::string_view replay_keys, const char* source_file,
                           int source_line) {
    if (!cassette_) {
      const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
      const std::string suite = info->test_suite_name();
      const std::string test = info->name();
      CassetteSettings settings = CassetteSettings::from_environment();
      std::string path = default_cassette_path(source_file, suite, test, settings.directory);
      if (settings.record != RecordMode::none) {
        std::filesystem::create_directories(std::filesystem::path(path).parent_path());
      }
      cassette_ = std::make_unique<Cassette>(std::move(path), std::move(settings),
                                             std::string(replay_keys), suite + "." + test);
      // GoogleTest reports an exception that escapes the test body at
      // "unknown file"; a trace alive until TearDown ends gives that failure
      // (and any other) this test's line and the way out.
      trace_ = std::make_unique<::testing::ScopedTrace>(
          source_file, source_line,
          cassette_->recording() ? "recording cassette " + cassette_->path()
          : std::filesystem::exists(cassette_->path())
              ? "replaying cassette " + cassette_->path() +
                    "; if the driver changed on purpose, record it again with\n    " +
                    cassette_->record_command()
              // The error that the missing cassette raises gives the command.
              : "replaying cassette " + cassette_->path() + " (missing)");
    }
    return *cassette_;
  }

  std::unique_ptr<Cassette> cassette_;
  std::unique_ptr<::testing::ScopedTrace> trace_;
};

}  // namespace wiretape::testing
