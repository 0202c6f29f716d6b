// The bench's planted driver (planted_scip.hpp): examples/hokuyo/src/scip.cpp's
// decoding, cut down to the MD stream path, with its eight bugs. Where a bug
// would be undefined behaviour that a build without sanitizers may survive
// (an overflow, a read past a buffer), the planted check just before it
// aborts as a sanitizer would, naming the bug; the division by zero is real.
#include "planted_scip.hpp"

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <utility>

namespace planted {
namespace {

constexpr std::size_t max_line_bytes = 512;
constexpr std::size_t max_reply_lines = 4096;

[[noreturn]] void crash(const char* bug, const std::string& detail) {
  std::fprintf(stderr, "planted bug %s: %s\n", bug, detail.c_str());
  std::fflush(stderr);
  std::abort();
}

char checksum(const std::string& bytes) {
  unsigned sum = 0;
  for (unsigned char c : bytes) sum += c;
  return static_cast<char>((sum & 0x3f) + 0x30);
}

std::uint32_t decode(const char* text, std::size_t digits) {
  std::uint32_t value = 0;
  for (std::size_t i = 0; i < digits; ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (c < 0x30 || c > 0x6f) throw ProtocolError("invalid SCIP character in scan data");
    value = (value << 6) | (c - 0x30u);
  }
  return value;
}

// The echo's numbers, read as the digits they should be.
int echo_number(const std::string& echo, std::size_t at, std::size_t digits) {
  int value = 0;
  for (std::size_t i = 0; i < digits; ++i) value = value * 10 + (echo[at + i] - '0');
  return value;
}

std::string format_number(int value, int digits) {
  std::string text = std::to_string(value);
  if (static_cast<int>(text.size()) < digits) text.insert(0, digits - text.size(), '0');
  return text;
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

// A data line's sum checked and removed (parameter lines put a ';' before
// the sum that the sum leaves out); false: the sum is wrong.
bool strip_sum(std::string& line) {
  const char sum = line.back();
  line.pop_back();
  if (checksum(line) == sum) return true;
  if (!line.empty() && line.back() == ';' && checksum(line.substr(0, line.size() - 1)) == sum) {
    line.pop_back();
    return true;
  }
  return false;
}

}  // namespace

Driver::Driver(wiretape::Port& port, std::chrono::milliseconds line_timeout)
    : port_(port), line_timeout_(line_timeout) {}

std::string Driver::read_line() {
  std::string line = port_.read_until("\n", max_line_bytes, line_timeout_);
  if (line.empty()) throw ProtocolError("no reply within the line timeout");
  if (line.back() != '\n') throw ProtocolError("a reply stopped in the middle of a line");
  line.pop_back();
  if (!line.empty() && line.back() == '\r') line.pop_back();
  return line;
}

Reply Driver::read_reply(const std::string& command, bool stream) {
  Reply reply;
  reply.echo = read_line();
  if (stream) {
    // Bug echo-length-off-by-one: the check lets through an echo as long
    // as the buffer, which has no room left for the NUL.
    char echo_copy[16];
    if (reply.echo.size() > sizeof echo_copy)
      throw ProtocolError("stream echo longer than " + std::to_string(sizeof echo_copy));
    if (reply.echo.size() >= sizeof echo_copy)
      crash("echo-length-off-by-one",
            "stream echo of " + std::to_string(reply.echo.size()) + " bytes copied with its NUL into " +
                std::to_string(sizeof echo_copy));
    std::memcpy(echo_copy, reply.echo.c_str(), reply.echo.size() + 1);
    if (reply.echo.size() != command.size() + 2 || reply.echo.compare(0, 2, command, 0, 2) != 0)
      throw ProtocolError("stream echo \"" + reply.echo + "\" is not " + command + "NN");
  } else if (reply.echo != command) {
    throw ProtocolError("reply to " + command + ": echo is \"" + reply.echo + "\"");
  }
  const std::string status_line = read_line();
  if (status_line.size() != 3) throw ProtocolError("reply to " + command + ": status line is not 3 bytes");
  reply.status = status_line.substr(0, 2);
  if (checksum(reply.status) != status_line[2])
    throw ProtocolError("reply to " + command + ": wrong sum on the status");
  return reply;
}

Reply Driver::transact(const std::string& command) {
  const std::string line = command + "\n";
  if (port_.write_all(line) != line.size()) throw ProtocolError(command + ": not accepted in time");
  Reply reply = read_reply(command, false);
  for (;;) {
    std::string line = read_line();
    if (line.empty()) break;
    if (reply.lines.size() >= max_reply_lines) throw ProtocolError(command + ": reply does not end");
    if (line.size() < 2) throw ProtocolError(command + ": a line has no sum");
    if (!strip_sum(line)) throw ProtocolError(command + ": wrong sum on a line");
    reply.lines.push_back(std::move(line));
  }
  return reply;
}

void Driver::expect_status(const Reply& reply, const char* ok) {
  if (reply.status == ok) return;
  // Bug status-table-index: the status's two characters index the table
  // as if they were digits.
  static const char* const status_names[100] = {
      nullptr, "start step is not a number", "end step is not a number",
      "cluster count is not a number", "end step out of range"};
  const int index = (reply.status[0] - '0') * 10 + (reply.status[1] - '0');
  if (index < 0 || index >= 100)
    crash("status-table-index", "status index " + std::to_string(index) + " outside the table of 100");
  const char* name = status_names[index];
  throw ProtocolError(reply.echo + ": device answered status " + reply.status + " (" +
                      (name ? name : "error status") + ")");
}

std::map<std::string, std::string> Driver::version() {
  const Reply reply = transact("VV");
  expect_status(reply, "00");
  return key_values(reply);
}

std::map<std::string, std::string> Driver::parameters() {
  const Reply reply = transact("PP");
  expect_status(reply, "00");
  return key_values(reply);
}

std::map<std::string, std::string> Driver::state() {
  if (port_.write_all("II\n") != 3) throw ProtocolError("II: not accepted in time");
  Reply reply = read_reply("II", false);
  expect_status(reply, "00");
  // Bug frame-ends-early: the rest of the reply is taken from one read, as
  // if a reply never came in two; the copy up to find("\n\n") of a block
  // without the empty line is a copy of npos bytes.
  char block[4096];
  const std::size_t got = port_.read(block, sizeof block, line_timeout_);
  const std::string rest(block, got);
  const std::size_t end = rest.find("\n\n");
  if (end == std::string::npos)
    crash("frame-ends-early", "II: one read gave " + std::to_string(got) +
                                  " bytes without the reply's empty line");
  std::size_t start = 0;
  while (start <= end) {
    const std::size_t stop = rest.find('\n', start);
    std::string line = rest.substr(start, stop - start);
    start = stop + 1;
    if (line.size() < 2 || !strip_sum(line)) throw ProtocolError("II: a line has a wrong sum");
    reply.lines.push_back(std::move(line));
  }
  return key_values(reply);
}

void Driver::laser_on() {
  const Reply reply = transact("BM");
  // Bug status-unhandled: the statuses this firmware was seen to send, and
  // no default.
  const int code = (reply.status[0] - '0') * 10 + (reply.status[1] - '0');
  switch (code) {
    case 0:
    case 2:  // already on
      return;
    case 1:
      throw ProtocolError("BM: the laser cannot be turned on");
    case 10:
      throw ProtocolError("BM: the laser is off (a fault)");
  }
  crash("status-unhandled", "BM: status code " + std::to_string(code) + " reached the end of the switch");
}

void Driver::start_stream(int first, int last, int cluster, int count) {
  const std::string prefix =
      "MD" + format_number(first, 4) + format_number(last, 4) + format_number(cluster, 2) + "0";
  const Reply reply = transact(prefix + format_number(count, 2));
  expect_status(reply, "00");
  stream_command_ = prefix;
  stream_expected_remaining_ = count - 1;
}

Scan Driver::read_stream_scan() {
  Reply reply = read_reply(stream_command_, true);
  const std::string counter = reply.echo.substr(stream_command_.size());
  const int remaining = echo_number(reply.echo, stream_command_.size(), 2);
  if (remaining != stream_expected_remaining_)
    throw ProtocolError("stream: remaining-scan counter \"" + counter + "\", expected " +
                        std::to_string(stream_expected_remaining_));
  expect_status(reply, "99");
  // Bug missing-terminator: a scan's lines are read until the empty line;
  // a silence is taken for a slow device and waited out, forever.
  std::string pending;
  for (;;) {
    std::string piece = port_.read_until("\n", max_line_bytes, line_timeout_);
    if (piece.empty() || piece.back() != '\n') {
      pending += piece;
      continue;
    }
    std::string line = pending + piece;
    pending.clear();
    line.pop_back();
    if (line.empty()) break;
    if (reply.lines.size() >= max_reply_lines) throw ProtocolError("scan: reply does not end");
    if (line.size() < 2 || !strip_sum(line)) throw ProtocolError("scan: wrong sum on a line");
    reply.lines.push_back(std::move(line));
  }
  Scan scan = decode_scan(reply);
  scan.remaining = remaining;
  --stream_expected_remaining_;
  return scan;
}

Scan Driver::decode_scan(const Reply& reply) {
  if (reply.lines.empty() || reply.lines[0].size() != 4)
    throw ProtocolError("scan: missing the 4-character timestamp line");
  Scan scan;
  scan.timestamp_ms = decode(reply.lines[0].data(), 4);
  std::string data;
  for (std::size_t i = 1; i < reply.lines.size(); ++i) data += reply.lines[i];
  // The steps are the echo's, as the device says it sent them.
  const int first = echo_number(reply.echo, 2, 4);
  const int last = echo_number(reply.echo, 6, 4);
  // Bug cluster-division: the echo's cluster divides, zero or not.
  const volatile int cluster = echo_number(reply.echo, 10, 2);
  const int steps = (last - first) / cluster + 1;
  // Bug count-unchecked: steps × 3 characters are decoded from the data,
  // however many the data holds.
  for (int i = 0; i < steps; ++i) {
    const std::size_t at = static_cast<std::size_t>(i) * 3;
    if (at + 3 > data.size())
      crash("count-unchecked", "step " + std::to_string(i) + " of " + std::to_string(steps) +
                                   " read past the scan's " + std::to_string(data.size()) +
                                   " data bytes");
    const std::uint32_t range = decode(data.data() + at, 3);
    // Bug range-overflow: ranges are kept in sixteenths of a millimetre in
    // 16 bits, enough for the URG-04LX's 4 m, not for what 18 bits can say.
    const std::uint32_t sixteenths = range * 16;
    if (sixteenths > 0xffff)
      crash("range-overflow", "range " + std::to_string(range) + " mm in sixteenths overflows 16 bits");
    scan.ranges.push_back(static_cast<std::uint16_t>(sixteenths));
  }
  return scan;
}

}  // namespace planted
