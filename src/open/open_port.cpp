#include <algorithm>
#include <cctype>
#include <cstdio>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "open/open_port.hpp"
#include "open/port_types.hpp"
#include "replay/replay_config.hpp"
#include "replay/replay_port.hpp"
#include "session/record_kinds.hpp"
#include "util/json.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"
#include "wiretape/port.hpp"

namespace wiretape {

namespace {

// flexiport spelled the access mode as a bare key.
Access take_access(Options& options) {
  std::string bare_choice;
  for (const char* bare : {"readonly", "writeonly", "readwrite"}) {
    if (!options.take_bool(bare)) continue;
    if (!bare_choice.empty() || options.has("access")) {
      throw OptionError(bare, std::string("option '") + bare +
                                  "' conflicts with another access mode; "
                                  "give one of access=, readonly, writeonly, "
                                  "readwrite");
    }
    bare_choice = bare;
  }
  if (!bare_choice.empty()) options.set("access", bare_choice);
  const std::string access = options.take_choice("access");
  if (access == "readonly") return Access::read_only;
  if (access == "writeonly") return Access::write_only;
  return Access::read_write;
}

bool value_is(const Options& options, std::string_view key, std::string_view expected) {
  const auto value = options.peek(key);
  if (!value) return false;
  std::string folded(*value);
  std::transform(folded.begin(), folded.end(), folded.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return folded == expected;
}

bool is_true(const Options& options, std::string_view key) {
  const auto value = options.peek(key);
  return value && parse_bool(*value).value_or(false);
}

// Keys that only do something next to another key (or another key's value).
// Accepted alone they would silently do nothing, so each is an error naming
// the key and what it needs. This table is the one place that knows these
// dependencies; docs/options.md says the same in its "with ..." columns.
struct KeyDependency {
  std::string_view key;
  bool is_prefix;          // key is a prefix (meta_KEY)
  std::string_view type;   // the port type the key belongs to; empty: every type
  std::string_view needs;  // what it needs, as the error says it
  bool (*satisfied)(const Options&);
};

bool recorded(const Options& options) { return options.has("log"); }
bool request_matching(const Options& options) {
  return value_is(options, "match", "request");
}
bool timing_checked(const Options& options) {
  return value_is(options, "check", "timing") || value_is(options, "strictness", "2");
}
bool faulty(const Options& options) { return options.has("faults"); }
bool clocked(const Options& options) {
  return !value_is(options, "timing", "none") && !is_true(options, "ignoretimes");
}

// The fault kinds whose waits speed= divides in every timing mode
// (docs/faults.md): a delay, a stall, a trickle's gaps, a reconnect's loss.
bool waits(detail::FaultKind kind) {
  using detail::FaultKind;
  return kind == FaultKind::delay || kind == FaultKind::stall || kind == FaultKind::trickle ||
         kind == FaultKind::reconnect;
}

bool speed_scales(const Options& options) {
  if (clocked(options)) return true;
  const auto faults = options.peek("faults");
  if (!faults) return false;
  try {
    const detail::FaultPlan plan = detail::parse_faults(*faults, 0);
    return std::any_of(plan.faults.begin(), plan.faults.end(),
                       [](const detail::FaultSpec& fault) { return waits(fault.kind); });
  } catch (const OptionError&) {
    return true;  // the plan's own error is the one to report, when it is read
  }
}

constexpr KeyDependency key_dependencies[] = {
    {"flush_ms", false, "", "log=FILE (it tunes the recording)", recorded},
    {"fsync", false, "", "log=FILE (it tunes the recording)", recorded},
    {"compress", false, "", "log=FILE (it tunes the recording)", recorded},
    {"log_errors", false, "", "log=FILE (it tunes the recording)", recorded},
    {"meta_", true, "", "log=FILE (metadata goes into the recording's header)", recorded},
    {"unmatched", false, "replay", "match=request", request_matching},
    {"repeat", false, "replay", "match=request", request_matching},
    {"gap", false, "replay", "match=request", request_matching},
    {"tolerance", false, "replay", "check=timing", timing_checked},
    {"jitter", false, "replay", "check=timing (or strictness=2)", timing_checked},
    {"speed", false, "replay",
     "a clock (timing=session or timing=causal) or an injected wait (faults= delay, stall, "
     "trickle or reconnect): with timing=none it scales nothing",
     speed_scales},
    {"seed", false, "replay", "faults=KIND@WHERE (it seeds their random choices)", faulty},
};

// Throws OptionError for the first key given without what it needs.
void check_key_dependencies(const Options& options, std::string_view type) {
  for (const KeyDependency& rule : key_dependencies) {
    if (!rule.type.empty() && rule.type != type) continue;
    for (const Options::Entry& entry : options.entries()) {
      const bool named =
          rule.is_prefix ? entry.key.size() > rule.key.size() &&
                               std::string_view(entry.key).substr(0, rule.key.size()) == rule.key
                         : entry.key == rule.key;
      if (!named || rule.satisfied(options)) continue;
      throw OptionError(entry.key, "option '" + entry.key + "' has no effect without " +
                                       std::string(rule.needs) + "; add it or leave '" +
                                       entry.key + "' out");
    }
  }
}

// A recorded port's option string and metadata go into the session
// header, which is UTF-8 JSON: refused here, before anything is opened,
// rather than when the recording starts.
void check_recordable(const Options& options) {
  for (const Options::Entry& entry : options.entries()) {
    for (const std::string* text : {&entry.key, &entry.value}) {
      if (const auto bad = detail::json::invalid_utf8_offset(*text)) {
        throw OptionError(entry.key, "option '" + entry.key + "': its " +
                                         (text == &entry.key ? "name" : "value") +
                                         " is not valid UTF-8 (byte " + std::to_string(*bad) +
                                         "), and a recorded port's options are kept in "
                                         "the session header, which is UTF-8");
      }
    }
  }
}

// The keys every type shares, taken and checked before a port is opened.
struct CommonKeys {
  std::string type;  // a registered name (port_types.hpp), aliases resolved
  Timeout timeout = forever;
  Access access = Access::read_write;
  int debug = 0;
  std::optional<std::string> log;
  detail::RecordingConfig recording;
};

CommonKeys take_common_keys(Options& options) {
  CommonKeys common;
  if (!options.has("type")) {
    throw OptionError("type",
                      "missing option 'type': say which port to open, one of " +
                          detail::registered_port_type_names() +
                          " (e.g. \"type=serial,device=/dev/ttyUSB0\")");
  }
  std::string type = options.take_choice("type");
  if (const detail::PortTypeAlias* alias = detail::find_port_type_alias(type)) {
    // flexiport's logging port types: the named port, recorded to `file`.
    if (alias->records_into_file) {
      const std::string base(alias->type);
      if (!options.has("file")) {
        throw OptionError("file", "type=" + type + " records the " + base +
                                      " port into 'file', which is missing: give "
                                      "file=FILE (or use type=" + base + ")");
      }
      options.set_port_type(type);
      options.resolve_aliases();
    }
    type = std::string(alias->type);
  }
  options.set_port_type(type);
  options.resolve_aliases();
  if (options.has("log")) check_recordable(options);
  common.type = type;

  common.timeout = options.take_timeout("timeout");
  common.access = take_access(options);
  common.debug = static_cast<int>(options.take_int("debug"));

  common.log = options.take("log");
  common.recording.flush_ms = static_cast<int>(options.take_int("flush_ms"));
  common.recording.fsync = options.take_bool("fsync");
  common.recording.compress = options.take_choice("compress") == "zstd";
  common.recording.raise_errors = options.take_choice("log_errors") == "raise";
  common.recording.metadata = options.take_prefixed("meta_");

  if (common.log && common.log->empty()) {
    throw OptionError("log", "option 'log' needs a file name (log=FILE)");
  }
  // After the common keys' values were checked, before the port is opened.
  check_key_dependencies(options, type);
  return common;
}

}  // namespace

std::unique_ptr<Port> open_port(std::string_view text) {
  return open_port(Options::parse(text));
}

std::unique_ptr<Port> open_port(Options options) {
  const std::string given = options.to_string();
  CommonKeys common = take_common_keys(options);
  const std::string& type = common.type;

  const detail::PortType* registered = detail::find_port_type(type);
  if (registered == nullptr) {
    // The key table's `type` choices and the registry disagree (a test
    // holds them equal): a defect, not bad input.
    throw std::logic_error("port type '" + type + "' is in the key table but not registered");
  }
  std::unique_ptr<Port> port = registered->open(options);
  options.finish(type);

  port->set_timeout(common.timeout);
  port->set_access(common.access);
  if (common.debug > 0) {
    std::fprintf(stderr, "wiretape: opened %s\n", port->description().c_str());
  }
  if (common.log) {
    common.recording.path = *common.log;
    common.recording.options_text = given;
    common.recording.port_type = type;
    port = detail::record_port(std::move(port), std::move(common.recording));
  }
  return port;
}

namespace detail {

bool replay_speed_applies(std::string_view text) {
  return speed_scales(Options::parse(text));
}

void check_replay_options(std::string_view text) {
  Options options = Options::parse(text);
  const CommonKeys common = take_common_keys(options);
  if (common.type != "replay") {
    throw OptionError("type", "expected the option string of a replay (type=replay), "
                              "not type=" + common.type);
  }
  take_replay_config(options);  // checks every key left
}

}  // namespace detail

}  // namespace wiretape
