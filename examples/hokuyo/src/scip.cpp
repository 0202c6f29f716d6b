#include "hokuyo/scip.hpp"

#include <algorithm>
#include <cstdio>
#include <utility>

namespace hokuyo {
namespace {

constexpr std::size_t max_line_bytes = 512;
// A reply longer than this many lines is not SCIP (a UTM-30LX ME scan of
// 1081 steps is 102 lines).
constexpr std::size_t max_reply_lines = 4096;
constexpr std::uint32_t timestamp_range = 1u << 24;

std::string printable(std::string_view bytes) {
  std::string out;
  for (unsigned char c : bytes) {
    if (c >= 0x20 && c < 0x7f && c != '\\') {
      out += static_cast<char>(c);
    } else {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02x", c);
      out += hex;
    }
  }
  return out;
}

std::string format_number(int value, int digits) {
  std::string text = std::to_string(value);
  if (static_cast<int>(text.size()) < digits)
    text.insert(0, digits - text.size(), '0');
  return text;
}

int chars_per_step(ScanMode mode) {
  switch (mode) {
    case ScanMode::gs:
    case ScanMode::ms:
      return 2;
    case ScanMode::gd:
    case ScanMode::md:
      return 3;
    case ScanMode::me:
      return 6;
  }
  return 3;
}

bool starts_with(std::string_view text, std::string_view prefix) {
  return text.substr(0, prefix.size()) == prefix;
}

bool ends_with(std::string_view text, std::string_view suffix) {
  return text.size() >= suffix.size() &&
         text.substr(text.size() - suffix.size()) == suffix;
}

std::map<std::string, std::string> key_values(const Reply& reply) {
  std::map<std::string, std::string> values;
  for (const std::string& line : reply.lines) {
    const auto colon = line.find(':');
    if (colon == std::string::npos) continue;
    std::string value = line.substr(colon + 1);
    if (!value.empty() && value.back() == ';') value.pop_back();
    values[line.substr(0, colon)] = value;
  }
  return values;
}

const std::string& required(const std::map<std::string, std::string>& values,
                            const std::string& key, const std::string& command) {
  const auto found = values.find(key);
  if (found == values.end())
    throw ProtocolError(command, command + ": reply has no " + key + " line");
  return found->second;
}

long parse_number(const std::string& text, const std::string& key,
                  const std::string& command) {
  if (text.empty() || text.size() > 9 ||
      !std::all_of(text.begin(), text.end(),
                   [](char c) { return c >= '0' && c <= '9'; }))
    throw ProtocolError(command, command + ": " + key + " is not a number: \"" +
                                     printable(text) + "\"");
  return std::stol(text);
}

}  // namespace

// --- encoding ---------------------------------------------------------------

char checksum(std::string_view bytes) {
  unsigned sum = 0;
  for (unsigned char c : bytes) sum += c;
  return static_cast<char>((sum & 0x3f) + 0x30);
}

std::uint32_t decode(std::string_view text) {
  std::uint32_t value = 0;
  for (unsigned char c : text) {
    if (c < 0x30 || c > 0x6f)
      throw std::invalid_argument("invalid SCIP character '" +
                                  printable(std::string(1, c)) + "'");
    value = (value << 6) | (c - 0x30u);
  }
  return value;
}

std::string encode(std::uint32_t value, int digits) {
  std::string out(static_cast<std::size_t>(digits), '0');
  for (int i = digits - 1; i >= 0; --i) {
    out[static_cast<std::size_t>(i)] = static_cast<char>(0x30 + (value & 0x3f));
    value >>= 6;
  }
  return out;
}

bool StatusError::hardware_fault() const {
  if (status_.size() != 2 || status_[0] < '0' || status_[0] > '9' ||
      status_[1] < '0' || status_[1] > '9')
    return false;
  const int value = (status_[0] - '0') * 10 + (status_[1] - '0');
  return value >= 50 && value <= 97;
}

std::string describe_status(std::string_view command, std::string_view status) {
  const std::string_view name = command.substr(0, 2);
  if (status.size() == 2 && status[0] >= '5' && status[0] <= '9' &&
      status[1] >= '0' && status[1] <= '9' && status != "98" && status != "99")
    return "hardware fault";
  if (status == "0A") return "the device could not create the reply";
  if (status == "0B") return "buffer shortage, or the command repeats one in progress";
  if (status == "0C" || status == "0F") return "missing parameters";
  if (status == "0D" || status == "0E") return "command not recognised by the device";
  if (status == "0G" || status == "0H") return "bad string tag";
  if (status == "0I") return "the device is in firmware update mode";
  if (status == "10") return "the laser is off";
  if (status == "98") return "resumed after a laser fault";
  if (name == "BM") {
    if (status == "01") return "laser cannot be turned on (device malfunction)";
    if (status == "02") return "laser already on";
  }
  if (name == "TM") {
    if (status == "01") return "not in time adjust mode";
    if (status == "02") return "already in time adjust mode";
    if (status == "03") return "already out of time adjust mode";
  }
  if (name == "GD" || name == "GS" || name == "MD" || name == "MS" ||
      name == "ME") {
    if (status == "01") return "start step is not a number";
    if (status == "02") return "end step is not a number";
    if (status == "03") return "cluster count is not a number";
    if (status == "04") return "end step out of range";
    if (status == "05") return "end step is before the start step";
    if (status == "06") return "scan interval is not a number";
    if (status == "07") return "scan count is not a number";
  }
  return "error status";
}

ScanMode parse_scan_mode(std::string_view text) {
  if (text == "gd" || text == "GD") return ScanMode::gd;
  if (text == "gs" || text == "GS") return ScanMode::gs;
  if (text == "md" || text == "MD") return ScanMode::md;
  if (text == "ms" || text == "MS") return ScanMode::ms;
  if (text == "me" || text == "ME") return ScanMode::me;
  throw std::invalid_argument("unknown scan mode \"" + std::string(text) +
                              "\" (valid: gd, gs, md, ms, me)");
}

const char* scan_mode_command(ScanMode mode) {
  switch (mode) {
    case ScanMode::gd: return "GD";
    case ScanMode::gs: return "GS";
    case ScanMode::md: return "MD";
    case ScanMode::ms: return "MS";
    case ScanMode::me: return "ME";
  }
  return "GD";
}

// --- driver -----------------------------------------------------------------

Driver::Driver(wiretape::Port& port, DriverOptions options)
    : port_(port), options_(options) {}

void Driver::send(const std::string& command) {
  const std::string line = command + "\n";
  if (port_.write_all(line) != line.size())
    throw ProtocolError(command, command + ": the device did not accept the command in time");
}

std::string Driver::read_line(const std::string& command) {
  std::string line =
      port_.read_until("\n", max_line_bytes, options_.line_timeout);
  if (line.empty())
    throw ProtocolError(command, "no reply to " + command + " within " +
                                     std::to_string(options_.line_timeout.count()) +
                                     " ms");
  if (line.back() != '\n') {
    if (line.size() >= max_line_bytes)
      throw ProtocolError(command, "reply to " + command + ": line longer than " +
                                       std::to_string(max_line_bytes) +
                                       " bytes: \"" + printable(line.substr(0, 40)) +
                                       "...\"");
    throw ProtocolError(command, "reply to " + command +
                                     " stopped in the middle of a line: \"" +
                                     printable(line) + "\"");
  }
  line.pop_back();
  if (!line.empty() && line.back() == '\r') line.pop_back();
  return line;
}

Reply Driver::read_reply(const std::string& command, bool echo_is_stream) {
  Reply reply;
  reply.echo = read_line(command);
  const bool echo_ok = echo_is_stream
                           ? starts_with(reply.echo, command) &&
                                 reply.echo.size() == command.size() + 2
                           : reply.echo == command;
  if (!echo_ok)
    throw ProtocolError(command, "reply to " + command + ": echo is \"" +
                                     printable(reply.echo) + "\", expected \"" +
                                     command + (echo_is_stream ? "NN" : "") + "\"");
  const std::string status_line = read_line(command);
  if (status_line.size() != 3)
    throw ProtocolError(command, "reply to " + command + ": status line \"" +
                                     printable(status_line) +
                                     "\" is not two characters and a sum");
  reply.status = status_line.substr(0, 2);
  if (checksum(reply.status) != status_line[2])
    throw ProtocolError(command, "reply to " + command + ": wrong sum on status \"" +
                                     printable(status_line) + "\" (expected '" +
                                     checksum(reply.status) + "')");
  for (;;) {
    std::string line = read_line(command);
    if (line.empty()) break;
    if (reply.lines.size() >= max_reply_lines)
      throw ProtocolError(command, "reply to " + command + ": more than " +
                                       std::to_string(max_reply_lines) +
                                       " lines without the closing empty line");
    const std::size_t line_number = reply.lines.size() + 3;
    if (line.size() < 2)
      throw ProtocolError(command, "reply to " + command + ", line " +
                                       std::to_string(line_number) + ": \"" +
                                       printable(line) + "\" has no sum");
    const char sum = line.back();
    std::string data = line.substr(0, line.size() - 1);
    if (checksum(data) != sum) {
      // Parameter lines (VV, PP, II) put ';' before the sum and leave it out.
      if (data.back() == ';' &&
          checksum(std::string_view(data).substr(0, data.size() - 1)) == sum) {
        data.pop_back();
      } else {
        throw ProtocolError(command, "reply to " + command + ", line " +
                                         std::to_string(line_number) +
                                         ": wrong sum in \"" + printable(line) +
                                         "\" (expected '" + checksum(data) + "')");
      }
    }
    reply.lines.push_back(std::move(data));
  }
  return reply;
}

void Driver::expect_status(const Reply& reply,
                           std::initializer_list<const char*> ok) {
  for (const char* status : ok)
    if (reply.status == status) return;
  throw StatusError(reply.echo, reply.status,
                    reply.echo + ": device answered status " + reply.status +
                        " (" + describe_status(reply.echo, reply.status) + ")");
}

Reply Driver::transact(const std::string& command) {
  if (streaming_)
    throw ProtocolError(command, command + ": a scan stream is running; stop it first");
  send(command);
  return read_reply(command, false);
}

VersionInfo Driver::version() {
  const Reply reply = transact("VV");
  expect_status(reply, {"00"});
  const auto values = key_values(reply);
  VersionInfo info;
  info.vendor = required(values, "VEND", "VV");
  info.product = required(values, "PROD", "VV");
  info.firmware = required(values, "FIRM", "VV");
  info.protocol = required(values, "PROT", "VV");
  info.serial = required(values, "SERI", "VV");
  return info;
}

void Driver::drain_until_quiet(std::chrono::milliseconds quiet,
                               std::chrono::milliseconds limit) {
  const auto end = std::chrono::steady_clock::now() + limit;
  char scratch[512];
  while (std::chrono::steady_clock::now() < end) {
    if (port_.read(scratch, sizeof scratch, quiet) == 0) return;
  }
}

VersionInfo Driver::open() {
  const auto saved = options_.line_timeout;
  options_.line_timeout = options_.probe_timeout;
  struct Restore {
    DriverOptions& options;
    std::chrono::milliseconds line_timeout;
    ~Restore() { options.line_timeout = line_timeout; }
  } restore{options_, saved};
  try {
    return version();
  } catch (const ProtocolError&) {
  }
  // No valid reply. A device left streaming by an earlier program fills the
  // line with scans: stop it, let the line go quiet, and ask again.
  drain_until_quiet(std::chrono::milliseconds(100), options_.probe_timeout);
  send("QT");
  drain_until_quiet(std::chrono::milliseconds(100), options_.probe_timeout);
  try {
    return version();
  } catch (const ProtocolError&) {
  }
  // Still nothing valid: a URG-04LX powers on speaking SCIP 1.1; ask it to
  // switch. A SCIP 1.1 device answers "SCIP2.0", "0", ""; one already in
  // 2.0 answers with a 2.0 status. Either way the next VV tells.
  drain_until_quiet(std::chrono::milliseconds(100), options_.probe_timeout);
  send("SCIP2.0");
  const std::string echo = read_line("SCIP2.0");
  if (echo != "SCIP2.0")
    throw ProtocolError("SCIP2.0", "no valid reply to VV, and the reply to SCIP2.0 "
                                   "echoes \"" + printable(echo) + "\"");
  for (int lines = 0; !read_line("SCIP2.0").empty(); ++lines) {
    if (lines > 8)
      throw ProtocolError("SCIP2.0", "the reply to SCIP2.0 does not end");
  }
  switched_from_scip1_ = true;
  return version();
}

SensorParameters Driver::parameters() {
  const Reply reply = transact("PP");
  expect_status(reply, {"00"});
  const auto values = key_values(reply);
  SensorParameters params;
  params.model = required(values, "MODL", "PP");
  const auto paren = params.model.find('(');
  if (paren != std::string::npos) params.model.resize(paren);
  params.min_range_mm = static_cast<unsigned>(parse_number(required(values, "DMIN", "PP"), "DMIN", "PP"));
  params.max_range_mm = static_cast<unsigned>(parse_number(required(values, "DMAX", "PP"), "DMAX", "PP"));
  params.resolution = static_cast<unsigned>(parse_number(required(values, "ARES", "PP"), "ARES", "PP"));
  params.first_step = static_cast<int>(parse_number(required(values, "AMIN", "PP"), "AMIN", "PP"));
  params.last_step = static_cast<int>(parse_number(required(values, "AMAX", "PP"), "AMAX", "PP"));
  params.front_step = static_cast<int>(parse_number(required(values, "AFRT", "PP"), "AFRT", "PP"));
  params.scan_rpm = static_cast<unsigned>(parse_number(required(values, "SCAN", "PP"), "SCAN", "PP"));
  if (params.first_step > params.last_step)
    throw ProtocolError("PP", "PP: AMIN " + std::to_string(params.first_step) +
                                  " is after AMAX " + std::to_string(params.last_step));
  return params;
}

std::map<std::string, std::string> Driver::state() {
  const Reply reply = transact("II");
  expect_status(reply, {"00"});
  return key_values(reply);
}

void Driver::laser_on() { expect_status(transact("BM"), {"00", "02"}); }

void Driver::laser_off() {
  if (streaming_) {
    stop_stream();
    return;
  }
  expect_status(transact("QT"), {"00"});
}

void Driver::reset() { expect_status(transact("RS"), {"00"}); }

void Driver::enter_time_mode() { expect_status(transact("TM0"), {"00", "02"}); }

std::uint32_t Driver::device_time_ms() {
  const Reply reply = transact("TM1");
  expect_status(reply, {"00"});
  if (reply.lines.size() != 1 || reply.lines[0].size() != 4)
    throw ProtocolError("TM1", "TM1: expected one 4-character time line");
  try {
    return decode(reply.lines[0]);
  } catch (const std::invalid_argument& error) {
    throw ProtocolError("TM1", std::string("TM1: ") + error.what());
  }
}

void Driver::leave_time_mode() { expect_status(transact("TM2"), {"00", "03"}); }

std::uint64_t Driver::unwrap(std::uint32_t raw) {
  // The counter wraps every 2^24 ms (4.66 h); a drop of more than half the
  // range is a wrap, a small drop is the device's own jitter.
  if (have_timestamp_ && raw < last_timestamp_ &&
      last_timestamp_ - raw > timestamp_range / 2)
    ++timestamp_wraps_;
  have_timestamp_ = true;
  last_timestamp_ = raw;
  return timestamp_wraps_ * timestamp_range + raw;
}

Scan Driver::decode_scan(const std::string& command, const Reply& reply,
                         ScanMode mode, int first, int last, int cluster,
                         std::size_t first_line) {
  if (reply.lines.size() <= first_line || reply.lines[first_line].size() != 4)
    throw ProtocolError(command, "reply to " + command +
                                     ": missing the 4-character timestamp line");
  Scan scan;
  scan.first = first;
  scan.last = last;
  scan.cluster = cluster;
  std::string data;
  for (std::size_t i = first_line + 1; i < reply.lines.size(); ++i)
    data += reply.lines[i];
  const std::size_t steps =
      static_cast<std::size_t>((last - first) / cluster + 1);
  const std::size_t width = static_cast<std::size_t>(chars_per_step(mode));
  if (data.size() != steps * width)
    throw ProtocolError(command, "reply to " + command + ": " +
                                     std::to_string(data.size()) +
                                     " data characters, expected " +
                                     std::to_string(steps * width) + " (" +
                                     std::to_string(steps) + " steps of " +
                                     std::to_string(width) + ")");
  try {
    scan.timestamp_ms = decode(reply.lines[first_line]);
    scan.ranges.reserve(steps);
    const std::size_t range_width = mode == ScanMode::me ? 3 : width;
    for (std::size_t i = 0; i < steps; ++i) {
      const std::string_view step = std::string_view(data).substr(i * width, width);
      scan.ranges.push_back(decode(step.substr(0, range_width)));
      if (mode == ScanMode::me) scan.intensities.push_back(decode(step.substr(3, 3)));
    }
  } catch (const std::invalid_argument& error) {
    throw ProtocolError(command, "reply to " + command + ": " + error.what());
  }
  scan.timestamp_unwrapped_ms = unwrap(scan.timestamp_ms);
  return scan;
}

Scan Driver::get_scan(ScanMode mode, int first, int last, int cluster) {
  if (mode != ScanMode::gd && mode != ScanMode::gs)
    throw std::invalid_argument("get_scan takes GD or GS; use start_stream for streams");
  const int asked_first = options_.inject_bug ? first + 1 : first;
  const std::string command = std::string(scan_mode_command(mode)) +
                              format_number(asked_first, 4) +
                              format_number(last, 4) + format_number(cluster, 2);
  const Reply reply = transact(command);
  expect_status(reply, {"00"});
  return decode_scan(command, reply, mode, asked_first, last, cluster, 0);
}

void Driver::start_stream(ScanMode mode, int first, int last, int cluster,
                          int interval, int count) {
  if (mode != ScanMode::md && mode != ScanMode::ms && mode != ScanMode::me)
    throw std::invalid_argument("start_stream takes MD, MS or ME");
  if (count < 0 || count > 99)
    throw std::invalid_argument("scan count must be 0..99 (0: until stopped)");
  if (interval < 0 || interval > 9)
    throw std::invalid_argument("scan interval must be 0..9");
  const std::string prefix = std::string(scan_mode_command(mode)) +
                             format_number(first, 4) + format_number(last, 4) +
                             format_number(cluster, 2) + std::to_string(interval);
  const std::string command = prefix + format_number(count, 2);
  expect_status(transact(command), {"00"});
  streaming_ = true;
  stream_command_ = prefix;
  stream_mode_ = mode;
  stream_first_ = first;
  stream_last_ = last;
  stream_cluster_ = cluster;
  stream_count_ = count;
  stream_expected_remaining_ = count == 0 ? 0 : count - 1;
}

Scan Driver::read_stream_scan() {
  if (!streaming_)
    throw ProtocolError(stream_command_, "no scan stream is running");
  const Reply reply = read_reply(stream_command_, true);
  const std::string counter = reply.echo.substr(stream_command_.size());
  int remaining = -1;
  if (counter.size() == 2 && counter[0] >= '0' && counter[0] <= '9' &&
      counter[1] >= '0' && counter[1] <= '9')
    remaining = (counter[0] - '0') * 10 + (counter[1] - '0');
  if (remaining != stream_expected_remaining_)
    throw ProtocolError(stream_command_,
                        "stream " + stream_command_ + ": remaining-scan counter \"" +
                            printable(counter) + "\", expected " +
                            format_number(stream_expected_remaining_, 2));
  if (reply.status != "99") {
    streaming_ = false;
    expect_status(reply, {"99"});
  }
  Scan scan = decode_scan(reply.echo, reply, stream_mode_, stream_first_,
                          stream_last_, stream_cluster_, 0);
  scan.remaining = remaining;
  if (stream_count_ != 0) {
    if (remaining == 0)
      streaming_ = false;
    else
      --stream_expected_remaining_;
  }
  return scan;
}

void Driver::stop_stream() {
  recover();
}

void Driver::recover() {
  streaming_ = false;
  send("QT");
  // Everything up to the QT echo is the rest of an interrupted reply or
  // scans still in flight; the QT reply ends with an empty line.
  const auto deadline = std::chrono::steady_clock::now() + options_.line_timeout * 5;
  bool seen_echo = false;
  while (std::chrono::steady_clock::now() < deadline) {
    std::string line =
        port_.read_until("\n", max_line_bytes, options_.line_timeout);
    if (line.empty())
      throw ProtocolError("QT", "recovering: the device did not answer QT within " +
                                    std::to_string(options_.line_timeout.count()) + " ms");
    if (line.back() != '\n') continue;
    line.pop_back();
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (!seen_echo) {
      seen_echo = ends_with(line, "QT");
      continue;
    }
    if (line.empty()) {
      // Let the line go quiet, dropping anything a slow device still sent.
      drain_until_quiet(std::chrono::milliseconds(50), options_.line_timeout);
      return;
    }
  }
  throw ProtocolError("QT", "recovering: no complete QT reply within " +
                                std::to_string((options_.line_timeout * 5).count()) + " ms");
}

}  // namespace hokuyo
