// The rule of DESIGN.md section 25 (docs/architecture.md "Where the tests
// are"): every source file of libwiretape has a test file named after it in
// the folder that mirrors its own, src/FOLDER/NAME.cpp →
// tests/cpp/FOLDER/NAME_test.cpp, or is listed below with where it is tested
// and why it has no file of its own. The extension (src/python/) is tested
// from Python and the shim (src/shim/) by tests/python/shim/.
#include <fnmatch.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

const fs::path source_root = WIRETAPE_SOURCE_DIR;

struct TestedElsewhere {
  std::string source;              // relative to the repository
  std::vector<std::string> tests;  // the files that test it (a * in a file name matches)
  std::string why;                 // why it has no test file of its own
};

// Kept in the order of the source tree.
const std::vector<TestedElsewhere> tested_elsewhere = {
    {"src/attach/syscall_recorder.cpp",
     {"tests/cpp/attach/attach_test.cpp"},
     "what a system call means is seen only in a traced program's calls, end to end"},
    {"src/attach/tracer.cpp",
     {"tests/cpp/attach/attach_test.cpp", "tests/cpp/attach/process_test.cpp"},
     "ptrace is tested on a real traced program; its refusals through the seam"},
    {"src/bridge/com_port_adapter.cpp",
     {"tests/cpp/core/rfc2217_test.cpp", "tests/python/cli/test_rfc2217.py"},
     "RFC 2217's view of the device is what a Telnet client sees of the bridge"},
    {"src/bridge/device_side.cpp",
     {"tests/cpp/bridge/bridge_test.cpp", "tests/cpp/bridge/bridge_bounds_test.cpp",
      "tests/cpp/bridge/bridge_recorder_test.cpp"},
     "the bridge's device side is the bridge seen from its device"},
    {"src/bridge/line_channel.cpp",
     {"tests/python/cli/test_line_channel.py", "tests/cpp/posix/syscalls_test.cpp"},
     "the shim's side channel needs the shim at its other end, which Python starts"},
    {"src/bridge/pty_endpoint.cpp",
     {"tests/cpp/bridge/bridge_test.cpp", "tests/python/cli/test_pty_*.py"},
     "an endpoint is tested through the bridge that owns it"},
    {"src/bridge/tcp_endpoint.cpp",
     {"tests/cpp/bridge/bridge_test.cpp", "tests/cpp/core/rfc2217_test.cpp",
      "tests/python/cli/test_tcp_chunks_not_held.py"},
     "an endpoint is tested through the bridge that owns it"},
    {"src/bridge/udp_endpoint.cpp",
     {"tests/cpp/bridge/bridge_udp_test.cpp", "tests/python/cli/test_udp_bridge.py"},
     "an endpoint is tested through the bridge that owns it"},
    {"src/core/option_keys.cpp",
     {"tests/cpp/core/options_test.cpp", "tests/cpp/open/port_types_test.cpp"},
     "the key table is data that options.cpp checks against; options_test tests both"},
    {"src/core/port.cpp",
     {"tests/cpp/core/port_api_test.cpp", "tests/cpp/core/port_capabilities_test.cpp"},
     "the Port base class is the public port API, tested as that API"},
    {"src/posix/fd_port.cpp",
     {"tests/cpp/posix/serial_port_test.cpp", "tests/cpp/posix/pty_port_test.cpp",
      "tests/cpp/posix/tcp_port_test.cpp", "tests/cpp/posix/udp_port_test.cpp",
      "tests/cpp/ports/recording_failure_test.cpp"},
     "the part every descriptor port shares, tested in each of them"},
    {"src/posix/file_size_limit.cpp",
     {"tests/cpp/ports/recording_failure_test.cpp", "tests/cpp/session/session_test.cpp"},
     "what it changes (EFBIG instead of SIGXFSZ) is seen in a writer past the limit"},
    {"src/posix/listener.cpp",
     {"tests/cpp/bridge/bridge_test.cpp", "tests/cpp/posix/syscalls_test.cpp"},
     "the bridge's TCP client side, tested through the bridge"},
    {"src/posix/poll_set.cpp",
     {"tests/cpp/bridge/bridge_test.cpp"},
     "a thin wrapper of poll() for the bridge's event loop"},
    {"src/posix/socket_port.cpp",
     {"tests/cpp/posix/tcp_port_test.cpp", "tests/cpp/posix/udp_port_test.cpp"},
     "what the tcp and udp ports share, tested in each of them"},
    {"src/posix/wake_pipe.cpp",
     {"tests/cpp/posix/pty_port_test.cpp", "tests/cpp/posix/tcp_port_test.cpp",
      "tests/cpp/posix/serial_port_test.cpp"},
     "a close from another thread waking a blocked call (CloseFromAnotherThread...)"},
    {"src/replay/client_session.cpp",
     {"tests/cpp/replay/exchanges_test.cpp"},
     "client sessions are cut from the exchanges, and tested with them"},
    {"src/replay/fault_stage.cpp",
     {"tests/cpp/replay/faults_test.cpp"},
     "the stage carries out the fault plan; faults_test tests plan and stage together"},
    {"src/replay/profiles/checksums.cpp",
     {"tests/cpp/replay/profile_builtin_test.cpp"},
     "the built-in profiles are tested together, each through the profile interface"},
    {"src/replay/profiles/declared.cpp",
     {"tests/cpp/replay/profile_builtin_test.cpp"},
     "the built-in profiles are tested together, each through the profile interface"},
    {"src/replay/profiles/lines.cpp",
     {"tests/cpp/replay/profile_builtin_test.cpp"},
     "the built-in profiles are tested together, each through the profile interface"},
    {"src/replay/profiles/mavlink.cpp",
     {"tests/cpp/replay/profile_builtin_test.cpp"},
     "the built-in profiles are tested together, each through the profile interface"},
    {"src/replay/profiles/modbus.cpp",
     {"tests/cpp/replay/profile_builtin_test.cpp"},
     "the built-in profiles are tested together, each through the profile interface"},
    {"src/replay/profiles/nmea.cpp",
     {"tests/cpp/replay/profile_builtin_test.cpp"},
     "the built-in profiles are tested together, each through the profile interface"},
    {"src/replay/profiles/scip.cpp",
     {"tests/cpp/replay/profile_builtin_test.cpp", "tests/cpp/replay/profile_test.cpp"},
     "the built-in profiles are tested together, each through the profile interface"},
    {"src/replay/profiles/slcan.cpp",
     {"tests/cpp/replay/profile_builtin_test.cpp"},
     "the built-in profiles are tested together, each through the profile interface"},
    {"src/replay/replay_session_file.cpp",
     {"tests/cpp/replay/replay_port_test.cpp", "tests/cpp/replay/replay_channels_test.cpp"},
     "the file side of type=replay, seen through the replay port that opens it"},
    {"src/session/buffered_file.cpp",
     {"tests/cpp/session/session_test.cpp", "tests/cpp/session/flexiport_test.cpp"},
     "the reader's and the flexiport importer's buffer, tested through both"},
    {"src/session/reader.cpp",
     {"tests/cpp/session/session_test.cpp", "tests/cpp/session/session_views_test.cpp",
      "tests/cpp/session/session_content_test.cpp"},
     "the format is tested as one: what the writer writes, the reader reads"},
    {"src/session/recorder_file.cpp",
     {"tests/cpp/open/recorder_test.cpp", "tests/cpp/ports/recording_port_test.cpp"},
     "the file behind the Recorder and log=, tested through both"},
    {"src/session/writer.cpp",
     {"tests/cpp/session/session_test.cpp", "tests/cpp/session/session_golden_test.cpp"},
     "the format is tested as one: what the writer writes, the reader reads"},
};

// The test file the rule asks of `source` (relative to the repository).
fs::path expected_test(const fs::path& source) {
  const fs::path below_src = source.lexically_relative("src");
  return fs::path("tests") / "cpp" / below_src.parent_path() /
         (below_src.stem().string() + "_test.cpp");
}

// The sources under `root`/src the rule covers, relative to `root`, sorted.
std::vector<fs::path> covered_sources(const fs::path& root) {
  std::vector<fs::path> sources;
  for (const auto& entry : fs::recursive_directory_iterator(root / "src")) {
    if (!entry.is_regular_file() || entry.path().extension() != ".cpp") continue;
    const fs::path relative = fs::relative(entry.path(), root);
    const std::string folder = (++relative.begin())->string();
    if (folder == "python" || folder == "shim") continue;
    sources.push_back(relative);
  }
  std::sort(sources.begin(), sources.end());
  return sources;
}

// The sources under `root` with neither a test file of their name nor an
// entry in `listed`.
std::vector<std::string> untested_sources(const fs::path& root,
                                          const std::vector<TestedElsewhere>& listed) {
  std::set<std::string> excused;
  for (const TestedElsewhere& entry : listed) excused.insert(entry.source);
  std::vector<std::string> untested;
  for (const fs::path& source : covered_sources(root)) {
    if (fs::exists(root / expected_test(source)) || excused.count(source.string())) continue;
    untested.push_back(source.string() + " (no " + expected_test(source).string() + ")");
  }
  return untested;
}

// Whether `path` (relative to the repository; a * in its file name matches
// anything) names at least one file.
bool names_a_file(const fs::path& path) {
  const std::string pattern = path.filename().string();
  if (pattern.find('*') == std::string::npos) return fs::is_regular_file(source_root / path);
  const fs::path folder = source_root / path.parent_path();
  if (!fs::is_directory(folder)) return false;
  for (const auto& entry : fs::directory_iterator(folder)) {
    if (fnmatch(pattern.c_str(), entry.path().filename().c_str(), 0) == 0) return true;
  }
  return false;
}

std::string read_text(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

std::string joined(const std::vector<std::string>& lines) {
  std::string text;
  for (const std::string& line : lines) text += line + "\n";
  return text;
}

// A scratch repository of empty files, removed at the end of the test.
class ScratchTree {
 public:
  ScratchTree()
      : root_(fs::temp_directory_path() / ("test_per_source_" + std::to_string(getpid()))) {
    fs::remove_all(root_);
  }
  ~ScratchTree() { fs::remove_all(root_); }
  void add(const fs::path& relative) {
    fs::create_directories((root_ / relative).parent_path());
    std::ofstream(root_ / relative).put('\n');
  }
  const fs::path& root() const { return root_; }

 private:
  fs::path root_;
};

}  // namespace

TEST(TestPerSource, EverySourceHasATestFileOfItsNameOrIsListed) {
  ASSERT_GT(covered_sources(source_root).size(), 50u) << "found too few sources under "
                                                      << source_root;
  const std::vector<std::string> untested = untested_sources(source_root, tested_elsewhere);
  EXPECT_TRUE(untested.empty())
      << "sources without a test file of their name: write it (and list it in "
      << "tests/CMakeLists.txt), or list the source in tested_elsewhere in " << __FILE__
      << " with where it is tested and why it has none:\n"
      << joined(untested);
}

TEST(TestPerSource, EachListedSourceExistsHasNoTestOfItsOwnAndNamesItsTests) {
  std::vector<std::string> wrong;
  std::set<std::string> seen;
  for (const TestedElsewhere& entry : tested_elsewhere) {
    if (!seen.insert(entry.source).second) wrong.push_back(entry.source + ": listed twice");
    if (!fs::is_regular_file(source_root / entry.source)) {
      wrong.push_back(entry.source + ": no such source; remove its entry");
    } else if (fs::exists(source_root / expected_test(entry.source))) {
      wrong.push_back(entry.source + ": has " + expected_test(entry.source).string() +
                      " now; remove its entry");
    }
    if (entry.why.empty()) wrong.push_back(entry.source + ": says not why it has no test file");
    if (entry.tests.empty()) wrong.push_back(entry.source + ": names no test");
    for (const std::string& test : entry.tests) {
      if (!names_a_file(test)) wrong.push_back(entry.source + ": " + test + " does not exist");
    }
  }
  EXPECT_TRUE(wrong.empty()) << "tested_elsewhere in " << __FILE__ << ":\n" << joined(wrong);
}

TEST(TestPerSource, EveryTestFileIsAProgramOfTestsCMakeLists) {
  const std::string programs = read_text(source_root / "tests" / "CMakeLists.txt");
  std::vector<std::string> unlisted;
  for (const auto& entry : fs::recursive_directory_iterator(source_root / "tests" / "cpp")) {
    const std::string name = entry.path().filename().string();
    if (!entry.is_regular_file() || name.size() < 9 ||
        name.compare(name.size() - 9, 9, "_test.cpp") != 0) {
      continue;
    }
    const fs::path program =
        fs::relative(entry.path(), source_root / "tests" / "cpp").replace_extension();
    if (programs.find("\n  " + program.string() + "\n") == std::string::npos) {
      unlisted.push_back(program.string());
    }
  }
  EXPECT_TRUE(unlisted.empty()) << "test files not in WIRETAPE_TEST_PROGRAMS of "
                                << "tests/CMakeLists.txt (they would never run):\n"
                                << joined(unlisted);
}

TEST(TestPerSource, TheRuleSeesASourceWithoutATest) {
  ScratchTree tree;
  tree.add("src/posix/tested.cpp");
  tree.add("tests/cpp/posix/tested_test.cpp");
  tree.add("src/replay/profiles/listed.cpp");
  tree.add("src/replay/profiles/new_profile.cpp");
  tree.add("tests/cpp/replay/new_profile_test.cpp");  // the wrong folder
  tree.add("src/util/new_helper.cpp");
  tree.add("src/python/module.cpp");
  tree.add("src/shim/redirect.c");
  const std::vector<TestedElsewhere> listed = {
      {"src/replay/profiles/listed.cpp", {"tests/cpp/replay/x_test.cpp"}, "because"}};
  EXPECT_EQ(untested_sources(tree.root(), listed),
            (std::vector<std::string>{
                "src/replay/profiles/new_profile.cpp "
                "(no tests/cpp/replay/profiles/new_profile_test.cpp)",
                "src/util/new_helper.cpp (no tests/cpp/util/new_helper_test.cpp)"}));
}
