// The key table: every key of every port type, once (DESIGN.md section 17,
// "Options"). docs/options.md's tables and the CLI's mirrored flags are
// tested against it (tests/python/bindings/test_option_table.py).
#include <algorithm>
#include <cctype>
#include <limits>
#include <string>
#include <utility>

#include "wiretape/options.hpp"
#include "wiretape/port.hpp"

namespace wiretape {

namespace {

using Types = std::vector<std::string_view>;

// A row under construction: OptionKey's fields named where they are set.
class Row {
 public:
  Row(std::string_view name, Types types, OptionType type, std::string_view help) {
    key_.name = name;
    key_.port_types = std::move(types);
    key_.type = type;
    key_.help = help;
  }
  Row& fallback(std::string_view value) {
    key_.default_value = value;
    return *this;
  }
  Row& required() {
    key_.required = true;
    return *this;
  }
  Row& prefix() {
    key_.prefix = true;
    return *this;
  }
  Row& choices(std::vector<std::string_view> values) {
    key_.choices = std::move(values);
    return *this;
  }
  Row& integers(std::int64_t min, std::int64_t max) {
    key_.min_integer = min;
    key_.max_integer = max;
    return *this;
  }
  Row& numbers(double min, double max) {
    key_.min_number = min;
    key_.max_number = max;
    return *this;
  }
  Row& alias_of(std::string_view canonical) {
    key_.alias_of = canonical;
    return *this;
  }
  Row& flag(std::string_view cli_flag) {
    key_.flag = cli_flag;
    return *this;
  }
  operator OptionKey() const { return key_; }

 private:
  OptionKey key_;
};

constexpr auto boolean = OptionType::boolean;
constexpr auto integer = OptionType::integer;
constexpr auto number = OptionType::number;
constexpr auto choice = OptionType::choice;
constexpr auto text = OptionType::text;
constexpr auto path = OptionType::path;

constexpr std::int64_t int64_max = std::numeric_limits<std::int64_t>::max();

std::vector<OptionKey> build_table() {
  const Types& every_type = port_types();
  const Types serial = {"serial"};
  // A line exported over RFC 2217 is set like a local one.
  const Types serial_lines = {"serial", "rfc2217"};
  const Types rfc2217 = {"rfc2217"};
  const Types tcp = {"tcp"};
  const Types udp = {"udp"};
  const Types replay = {"replay"};
  const Types logging_types = {"seriallog", "tcplog", "udplog"};
  // What `type=` accepts: the types, then flexiport's spellings of them.
  Types type_names = every_type;
  type_names.push_back("logreader");
  type_names.insert(type_names.end(), logging_types.begin(), logging_types.end());
  return {
      // Common keys.
      Row("type", every_type, choice, "the port type").required().choices(type_names),
      Row("timeout", every_type, OptionType::seconds,
          "how long a call waits when given no timeout of its own")
          .fallback("-1")
          .numbers(0, 1e9),
      Row("access", every_type, choice, "reading, writing or both")
          .fallback("readwrite")
          .choices({"readwrite", "readonly", "writeonly"}),
      Row("readonly", every_type, boolean, "flexiport's spelling of access=readonly")
          .fallback("false"),
      Row("writeonly", every_type, boolean, "flexiport's spelling of access=writeonly")
          .fallback("false"),
      Row("readwrite", every_type, boolean, "flexiport's spelling of access=readwrite")
          .fallback("false"),
      Row("log", every_type, path, "record the port into this .wtape session file"),
      Row("flush_ms", every_type, integer,
          "with log: at most this much recording is lost if the process is killed")
          .fallback("100")
          .integers(1, 3'600'000),
      Row("fsync", every_type, boolean, "with log: fsync after each flush").fallback("false"),
      Row("compress", every_type, choice,
          "with log: zstd stores the records in compressed chunks (format 2.0)")
          .fallback("none")
          .choices({"none", "zstd"}),
      Row("log_errors", every_type, choice,
          "with log: a recording failure is raised once, or only printed")
          .fallback("raise")
          .choices({"raise", "warn"}),
      Row("meta_", every_type, text, "with log: free metadata KEY in the session header")
          .prefix(),
      Row("debug", every_type, integer, "diagnostics on stderr").fallback("0").integers(0, 3),

      // type=serial
      Row("device", serial, path, "the serial device").required(),
      Row("baud", serial_lines, integer, "the line rate").fallback("9600").integers(1, 100'000'000),
      Row("databits", serial_lines, integer, "data bits").fallback("8").integers(5, 8),
      Row("stopbits", serial_lines, integer, "stop bits").fallback("1").integers(1, 2),
      Row("parity", serial_lines, choice, "parity")
          .fallback(to_string(Parity::none))
          .choices({to_string(Parity::none), to_string(Parity::even), to_string(Parity::odd),
                    to_string(Parity::mark), to_string(Parity::space)}),
      Row("flow", serial_lines, choice, "flow control")
          .fallback(to_string(FlowControl::none))
          .choices({to_string(FlowControl::none), to_string(FlowControl::rtscts),
                    to_string(FlowControl::xonxoff)}),
      Row("hwflowctrl", serial, boolean,
          "flexiport's spelling: true = flow=rtscts, false = flow=none"),
      Row("exclusive", serial, boolean, "lock the device against other programs")
          .fallback("true"),

      // type=tcp
      Row("host", tcp, text, "where to connect, or the address to listen on")
          .fallback("127.0.0.1"),
      Row("ip", tcp, text, "flexiport's name for host").alias_of("host"),
      Row("port", tcp, integer, "the TCP port").required().integers(1, 65535),
      Row("listen", tcp, boolean, "wait for one client instead of connecting")
          .fallback("false"),
      Row("nodelay", tcp, boolean, "TCP_NODELAY").fallback("true"),

      // type=rfc2217 (and the line keys of type=serial above)
      Row("host", rfc2217, text, "the RFC 2217 server (ser2net, a labgrid exporter)")
          .fallback("127.0.0.1"),
      Row("port", rfc2217, integer, "the server's TCP port").required().integers(1, 65535),
      Row("answer_timeout", rfc2217, OptionType::seconds,
          "how long the server has to connect, agree COM-PORT-OPTION and answer each setting")
          .fallback("5")
          .numbers(0, 1e9),

      // type=udp
      Row("host", udp, text, "destination of written datagrams, and with port the only sender read")
          .fallback("127.0.0.1"),
      Row("port", udp, integer, "destination port; 0: the last sender")
          .fallback("0")
          .integers(0, 65535),
      Row("bind_host", udp, text, "local address to receive on").fallback("0.0.0.0"),
      Row("bind_port", udp, integer, "local port; 0 picks a free one")
          .fallback("0")
          .integers(0, 65535),
      Row("dest_ip", udp, text, "flexiport's name for host").alias_of("host"),
      Row("dest_port", udp, integer, "flexiport's name for port")
          .alias_of("port")
          .integers(0, 65535),
      Row("recv_ip", udp, text, "flexiport's name for bind_host").alias_of("bind_host"),
      Row("recv_port", udp, integer, "flexiport's name for bind_port")
          .alias_of("bind_port")
          .integers(0, 65535),

      // type=pty
      Row("link", {"pty"}, path, "a symbolic link to the terminal"),

      // type=replay
      Row("file", replay, path, "the session: a .wtape, or a flexiport name.log").required(),
      Row("timing", replay, choice, "when recorded replies are released")
          .fallback("causal")
          .choices({"none", "session", "causal"})
          .flag("--timing"),
      Row("ignoretimes", replay, boolean, "flexiport: true = timing=none").fallback("false"),
      Row("speed", replay, number, "rate multiplier of the clock")
          .fallback("1.0")
          .numbers(1e-6, 1e6)
          .flag("--speed"),
      Row("check", replay, choice, "what is compared against the recording")
          .fallback("data")
          .choices({"off", "data", "timing"})
          .flag("--check"),
      Row("strictness", replay, integer, "flexiport: 0/1/2 = check=off/data/timing")
          .integers(0, 2),
      Row("tolerance", replay, number, "with check=timing: the tolerance in milliseconds")
          .fallback("100")
          .numbers(0, 1e9)
          .flag("--tolerance"),
      Row("jitter", replay, integer, "flexiport: the tolerance in microseconds")
          .integers(0, int64_max / 1000),
      Row("match", replay, choice, "one stream, or requests matched in any order")
          .fallback("sequence")
          .choices({"sequence", "request"})
          .flag("--match"),
      Row("unmatched", replay, choice, "with match=request: bytes matching no request")
          .fallback("error")
          .choices({"error", "silent"})
          .flag("--unmatched"),
      Row("repeat", replay, choice, "with match=request: used-up exchanges")
          .fallback("none")
          .choices({"none", "last", "cycle"})
          .flag("--repeat"),
      Row("profile", replay, text, "a protocol profile: requests framed and matched by key")
          .flag("--profile"),
      Row("framing", replay, text, "a declared profile's framing"),
      Row("ignore", replay, text, "with framing: bytes left out of the key"),
      Row("echo", replay, text, "with framing: fields copied from the request"),
      Row("checksum", replay, text, "with framing: the checksum fixed in responses"),
      Row("gap", replay, number,
          "with match=request: ms of quiet before a shorter complete request is taken")
          .fallback("50")
          .numbers(0, 1e9)
          .flag("--gap"),
      Row("flush_wait", replay, number,
          "with match=sequence: ms a recorded client flush the client has not made may hold rx "
          "it is entitled to")
          .fallback("200")
          .numbers(0, 1e9)
          .flag("--flush-wait"),
      Row("unused", replay, choice, "recorded data never consumed at close")
          .fallback("warn")
          .choices({"ignore", "warn", "error"})
          .flag("--unused"),
      Row("at_end", replay, choice, "after the last record")
          .fallback("silent")
          .choices({"silent", "closed"})
          .flag("--at-end"),
      Row("channel", replay, text,
          "the channel to replay, in a session of several ports (required there)"),
      Row("faults", replay, text, "injected faults, KIND@WHERE[;...]").flag("--fault"),
      Row("seed", replay, integer, "with faults: seeds their random choices")
          .fallback("0")
          .integers(0, int64_max)
          .flag("--seed"),

      // flexiport's logging types: the named port, recorded.
      Row("file", logging_types, path, "flexiport's name for log").required().alias_of("log"),
  };
}

// Edit distance with adjacent swaps counted as one edit (optimal string
// alignment): "buad" is one edit from "baud".
std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::vector<std::size_t>> d(a.size() + 1, std::vector<std::size_t>(b.size() + 1));
  for (std::size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (std::size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t cost = a[i - 1] == b[j - 1] ? 0 : 1;
      d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + cost});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) {
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
      }
    }
  }
  return d[a.size()][b.size()];
}

}  // namespace

const char* to_string(OptionType type) noexcept {
  switch (type) {
    case OptionType::boolean: return "boolean";
    case OptionType::integer: return "integer";
    case OptionType::number: return "number";
    case OptionType::seconds: return "seconds";
    case OptionType::choice: return "choice";
    case OptionType::path: return "path";
    case OptionType::text: break;
  }
  return "text";
}

bool OptionKey::applies_to(std::string_view port_type) const {
  return std::find(port_types.begin(), port_types.end(), port_type) != port_types.end();
}

const std::vector<OptionKey>& option_keys() {
  static const std::vector<OptionKey> table = build_table();
  return table;
}

// The names the rows above are keyed by. What each type is (constructor,
// capabilities, aliases) is the registry's, above the port folders
// (src/open/port_types.cpp); tests/cpp/open/port_types_test.cpp holds these
// names and the registry's equal.
const std::vector<std::string_view>& port_types() {
  static const std::vector<std::string_view> types = {"serial", "tcp",    "udp",    "pty",
                                                      "loopback", "replay", "rfc2217"};
  return types;
}

const OptionKey* find_option_key(std::string_view name, std::string_view port_type) {
  for (const OptionKey& key : option_keys()) {
    if (!key.applies_to(port_type)) continue;
    const bool named = key.prefix ? name.size() > key.name.size() &&
                                        name.substr(0, key.name.size()) == key.name
                                  : name == key.name;
    if (named) return &key;
  }
  return nullptr;
}

std::optional<std::string> suggest_key(std::string_view name, std::string_view port_type) {
  std::vector<std::string> candidates;
  for (const OptionKey& key : option_keys()) {
    if (key.prefix || !key.applies_to(port_type) || key.name == name) continue;
    candidates.emplace_back(key.name);
  }
  return nearest_name(name, candidates);
}

std::optional<std::string> nearest_name(std::string_view name,
                                        const std::vector<std::string>& candidates) {
  // Two edits ("bod" for "baud"), one for a name of two letters, which two
  // edits would turn into any other. Case is ignored: BAUD is baud.
  const std::size_t allowed = name.size() <= 2 ? 1 : 2;
  const auto folded_text = [](std::string_view text) {
    std::string folded(text);
    std::transform(folded.begin(), folded.end(), folded.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return folded;
  };
  const std::string folded = folded_text(name);
  // Of equally near names, the one that starts as the name does ("bod" is
  // two edits from both "baud" and "log").
  auto common_start = [&](std::string_view candidate) {
    std::size_t n = 0;
    while (n < candidate.size() && n < folded.size() && candidate[n] == folded[n]) ++n;
    return n;
  };
  std::optional<std::string> best;
  std::size_t best_distance = allowed + 1;
  std::size_t best_start = 0;
  for (const std::string& candidate : candidates) {
    if (candidate == name) continue;
    const std::string folded_candidate = folded_text(candidate);
    const std::size_t distance = edit_distance(folded, folded_candidate);
    const std::size_t start = common_start(folded_candidate);
    if (distance < best_distance || (distance == best_distance && start > best_start)) {
      best_distance = distance;
      best_start = start;
      best = candidate;
    }
  }
  return best;
}

}  // namespace wiretape
