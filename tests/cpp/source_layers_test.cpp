// Rules over every source file of libwiretape (DESIGN.md sections 18 and
// 25, docs/architecture.md "Layers"): folders include downward only, and
// nothing outside src/posix/ calls the operating system.
//
// The layers, lowest first:
//   util ← core ← posix ← session ← ports ← replay ← open ← bridge, attach ← python
// core and posix are one level in the design; of the two, posix uses core's
// public API (Port, Options, errors: ports are Ports) and core uses nothing
// of posix, so core is held below posix. A public header in
// include/wiretape/ is at the level of the folder that implements it.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

const fs::path source_root = WIRETAPE_SOURCE_DIR;

// The level of each folder of src/, and of each public header.
const std::map<std::string, int> folder_levels = {
    {"util", 0},   {"core", 1},  {"posix", 2}, {"session", 3}, {"ports", 4},
    {"replay", 5}, {"open", 6},  {"bridge", 7}, {"attach", 7}, {"python", 8},
};
const std::map<std::string, int> public_header_levels = {
    {"timeout.hpp", 1},        {"errors.hpp", 1},  {"port.hpp", 1},
    {"options.hpp", 1},        {"version.hpp", 1}, {"device_identity.hpp", 1},
    {"fuzzing.hpp", 6},       {"session.hpp", 3},        {"recorder.hpp", 3}, {"profile.hpp", 5},
    {"bridge.hpp", 7},         {"attach.hpp", 7},  {"cassette_names.hpp", 8}, {"testing.hpp", 8},
    {"wiretape.hpp", 8},
};
// The shim is a C library loaded into other programs: it includes nothing
// of wiretape, and only the bridge, which speaks its line protocol, includes
// its header (src/shim/line_protocol.h).
constexpr int shim_reader_level = 7;

struct Source {
  fs::path path;  // relative to the repository
  int level;
  std::string text;
};

std::string read_text(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

bool is_cpp(const fs::path& path) {
  const std::string ext = path.extension().string();
  return ext == ".cpp" || ext == ".hpp" || ext == ".h" || ext == ".c";
}

// Every file of src/ (the shim aside) and include/wiretape/, with its level.
std::vector<Source> layered_sources() {
  std::vector<Source> sources;
  for (const auto& entry : fs::recursive_directory_iterator(source_root / "src")) {
    if (!entry.is_regular_file() || !is_cpp(entry.path())) continue;
    const fs::path relative = fs::relative(entry.path(), source_root);
    const std::string folder = (++relative.begin())->string();
    if (folder == "shim") continue;
    const auto level = folder_levels.find(folder);
    EXPECT_NE(level, folder_levels.end())
        << relative << ": src/" << folder << "/ has no level; give it one here and in "
        << "docs/architecture.md";
    if (level == folder_levels.end()) continue;
    sources.push_back({relative, level->second, read_text(entry.path())});
  }
  for (const auto& entry : fs::directory_iterator(source_root / "include" / "wiretape")) {
    if (!entry.is_regular_file()) continue;
    const std::string name = entry.path().filename().string();
    const auto level = public_header_levels.find(name);
    EXPECT_NE(level, public_header_levels.end())
        << "include/wiretape/" << name << " has no level; give it one here";
    if (level == public_header_levels.end()) continue;
    sources.push_back({fs::relative(entry.path(), source_root), level->second,
                       read_text(entry.path())});
  }
  return sources;
}

// The level of what `#include "target"` names; -1 for something unlayered.
int level_of_include(const std::string& target) {
  const std::size_t slash = target.find('/');
  if (slash == std::string::npos) return -1;
  const std::string folder = target.substr(0, slash);
  if (folder == "wiretape") {
    const auto level = public_header_levels.find(target.substr(slash + 1));
    return level == public_header_levels.end() ? -1 : level->second;
  }
  if (folder == "shim") return shim_reader_level;
  const auto level = folder_levels.find(folder);
  return level == folder_levels.end() ? -1 : level->second;
}

// `path:line: text` of each include in `source` above its own level.
std::vector<std::string> upward_includes(const Source& source) {
  static const std::regex include(R"re(^\s*#\s*include\s*"([^"]+)")re");
  std::vector<std::string> found;
  std::istringstream lines(source.text);
  std::string line;
  for (int number = 1; std::getline(lines, line); ++number) {
    std::smatch match;
    if (!std::regex_search(line, match, include)) continue;
    const int target = level_of_include(match[1].str());
    if (target > source.level) {
      found.push_back(source.path.string() + ":" + std::to_string(number) + ": " + line);
    }
  }
  return found;
}

// A call of a global function (`::socket(`, `::ioctl(`): in this code base
// that is always libc, so always the operating system.
const std::regex global_call(R"re((^|[^\w:>.])::([a-z_][a-z_0-9]*)\s*\()re");

std::vector<std::string> system_calls(const std::string& path, const std::string& text) {
  std::vector<std::string> found;
  std::istringstream lines(text);
  std::string line;
  for (int number = 1; std::getline(lines, line); ++number) {
    const std::string code = line.substr(0, line.find("//"));
    std::smatch match;
    if (std::regex_search(code, match, global_call)) {
      found.push_back(path + ":" + std::to_string(number) + ": " + line);
    }
  }
  return found;
}

std::string joined(const std::vector<std::string>& lines) {
  std::string text;
  for (const std::string& line : lines) text += line + "\n";
  return text;
}

}  // namespace

TEST(SourceLayers, FoldersIncludeDownwardOnly) {
  const std::vector<Source> sources = layered_sources();
  ASSERT_GT(sources.size(), 50u) << "found too few sources under " << source_root;
  std::vector<std::string> upward;
  for (const Source& source : sources) {
    for (const std::string& line : upward_includes(source)) upward.push_back(line);
  }
  EXPECT_TRUE(upward.empty()) << "includes of a higher layer (" << "util < core < posix < "
                              << "session < ports < replay < open < bridge < python):\n"
                              << joined(upward);
}

TEST(SourceLayers, TheRuleSeesAnUpwardInclude) {
  const Source ports{"src/ports/example.cpp", folder_levels.at("ports"),
                     "#include \"session/reader.hpp\"\n#include \"replay/replay_port.hpp\"\n"};
  EXPECT_EQ(upward_includes(ports).size(), 1u);
  const Source posix{"src/posix/example.hpp", folder_levels.at("posix"),
                     "#include \"wiretape/port.hpp\"\n  #include \"wiretape/session.hpp\"\n"};
  EXPECT_EQ(upward_includes(posix).size(), 1u);
}

TEST(SourceLayers, NoFileOutsidePosixCallsTheOperatingSystem) {
  std::vector<std::string> calls;
  for (const auto& entry : fs::recursive_directory_iterator(source_root / "src")) {
    if (!entry.is_regular_file() || !is_cpp(entry.path())) continue;
    const fs::path relative = fs::relative(entry.path(), source_root);
    const std::string folder = (++relative.begin())->string();
    // posix/ is the seam; the shim is loaded into other programs and calls
    // the libc it wraps.
    if (folder == "posix" || folder == "shim") continue;
    for (const std::string& line : system_calls(relative.string(), read_text(entry.path()))) {
      calls.push_back(line);
    }
  }
  EXPECT_TRUE(calls.empty()) << "system calls outside src/posix/ (route them through "
                             << "src/posix/syscalls.hpp, sys::NAME):\n"
                             << joined(calls);
}

TEST(SourceLayers, TheRuleSeesASystemCall) {
  EXPECT_EQ(system_calls("x.cpp", "  if (::stat(path, &s) != 0) {").size(), 1u);
  EXPECT_EQ(system_calls("x.cpp", "fd(::accept4(l, nullptr, nullptr, 0));").size(), 1u);
  EXPECT_TRUE(system_calls("x.cpp", "sys::stat(path, &s); std::move(x); a->b(); // ::f()")
                  .empty());
}
