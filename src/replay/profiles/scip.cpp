// The `scip` profile: Hokuyo laser scanners speaking SCIP 2.0 (and the
// SCIP 1.1 switch `SCIP2.0`).
//
// A command (tx) is one line: the host ends it with LF, CR or CR LF. A reply
// (rx) is the echo line, the status line, data lines and an empty line: it
// ends at the first empty line (LF LF; a line of only CR counts as empty).
// An LF where a reply would begin is a frame of its own. MD/MS/ME scans send
// one reply per scan to a single command, so one request frame is followed by
// several response frames.
#include <algorithm>
#include <array>
#include <utility>

#include "replay/profiles/builtin.hpp"
#include "util/hex.hpp"

namespace wiretape::detail {

namespace {

constexpr char lf = '\n';
constexpr char cr = '\r';

struct CommandMeaning {
  std::string_view code;
  std::string_view meaning;
};

// The meanings `wiretape show` prints; the text is kept stable because
// scripts read show's output.
constexpr std::array<CommandMeaning, 18> commands = {{
    {"VV", "version information"},
    {"PP", "sensor parameters"},
    {"II", "sensor state"},
    {"BM", "laser on"},
    {"QT", "laser off"},
    {"RS", "reset"},
    {"RT", "partial reset"},
    {"TM", "time synchronisation"},
    {"CR", "motor speed"},
    {"SS", "bit rate"},
    {"HS", "high sensitivity"},
    {"GD", "single scan (3-character ranges)"},
    {"GS", "single scan (2-character ranges)"},
    {"GE", "single scan with intensities"},
    {"MD", "continuous scans (3-character ranges)"},
    {"MS", "continuous scans (2-character ranges)"},
    {"ME", "continuous scans with intensities"},
    {"SC", "SCIP 1.1 switch"},
}};

constexpr std::string_view scip2_switch = "SCIP2.0";

// Bytes as text for names: ASCII kept as it is, every other byte as U+FFFD
// (UTF-8), as a decoder that replaces what is not ASCII would give.
std::string ascii_or_replacement(std::string_view bytes) {
  std::string text;
  for (unsigned char byte : bytes) {
    if (byte < 0x80) {
      text += static_cast<char>(byte);
    } else {
      text += "\xEF\xBF\xBD";
    }
  }
  return text;
}

std::string_view first_line(std::string_view frame) {
  return frame.substr(0, frame.find(lf));
}

bool starts_with(std::string_view text, std::string_view prefix) {
  return text.substr(0, prefix.size()) == prefix;
}

// The command code of a frame whose first line is `echo`: "SCIP2.0" for the
// switch, else its first two bytes.
std::string command_code(std::string_view echo) {
  if (starts_with(echo, scip2_switch)) return std::string(scip2_switch);
  return ascii_or_replacement(echo.substr(0, 2));
}

std::string_view command_meaning(std::string_view code) {
  if (code == scip2_switch) return "switch to SCIP 2.0";
  for (const CommandMeaning& command : commands) {
    if (command.code == code) return command.meaning;
  }
  return "unknown command";
}

// SCIP 2.0's line sum: the low six bits of the bytes' sum, plus 0x30.
char line_sum(std::string_view bytes) {
  unsigned sum = 0;
  for (unsigned char byte : bytes) sum += byte;
  return static_cast<char>((sum & 0x3F) + 0x30);
}

// Parameter lines (replies to VV, PP and II: "SERI:H0706400;F") end with a
// ';' that their sum leaves out; every other line's sum covers all of it.
bool is_parameter_reply(std::string_view code) {
  return code == "VV" || code == "PP" || code == "II";
}

std::string pad_right(std::string text, std::size_t width) {
  if (text.size() < width) text.append(width - text.size(), ' ');
  return text;
}

// Frames are cut byte by byte so that any split of the stream gives the same
// frames; the size limit keeps a stream without line ends bounded.
class ScipCommandFramer final : public BufferingFramer {
 public:
  void feed(std::string_view bytes, std::vector<Frame>& frames) override {
    for (char byte : bytes) {
      // A CR ends a command; an LF right after it belongs to the same end.
      if (after_cr_) {
        after_cr_ = false;
        if (byte == lf) {
          buffer_ += byte;
          cut(FrameEnd::delimited, frames);
          continue;
        }
        cut(FrameEnd::delimited, frames);
      }
      buffer_ += byte;
      if (byte == lf) {
        cut(FrameEnd::delimited, frames);
      } else if (buffer_.size() >= max_frame_bytes) {
        cut(FrameEnd::size_limit, frames);
      } else if (byte == cr) {
        after_cr_ = true;
      }
    }
  }

 private:
  // A command ended by a bare CR is complete; anything else was cut short.
  FrameEnd tail_end() const override {
    return after_cr_ ? FrameEnd::delimited : FrameEnd::stream_end;
  }
  void forget_frame() override { after_cr_ = false; }

  bool after_cr_ = false;  // the kept command ends with a CR
};

class ScipReplyFramer final : public BufferingFramer {
 public:
  void feed(std::string_view bytes, std::vector<Frame>& frames) override {
    for (char byte : bytes) {
      buffer_ += byte;
      if (byte == lf) {
        std::string_view line(buffer_);
        line = line.substr(line_start_, buffer_.size() - 1 - line_start_);
        if (line.empty() || line == "\r") {
          cut(FrameEnd::delimited, frames);
        } else {
          line_start_ = buffer_.size();
        }
      } else if (buffer_.size() >= max_frame_bytes) {
        cut(FrameEnd::size_limit, frames);
      }
    }
  }

 private:
  void forget_frame() override { line_start_ = 0; }

  std::size_t line_start_ = 0;  // where the line being received begins
};

class ScipProfile final : public Profile {
 public:
  std::string_view name() const override { return "scip"; }

  std::string_view summary() const override {
    return "Hokuyo laser scanners, SCIP 2.0 (and the SCIP 1.1 switch)";
  }

  std::unique_ptr<Framer> make_framer(StreamDirection direction) const override {
    if (direction == StreamDirection::tx) return std::make_unique<ScipCommandFramer>();
    return std::make_unique<ScipReplyFramer>();
  }

  // The whole command line, parameters and string tag included, without its
  // line end: a driver ending commands with CR LF matches a recording made
  // with LF.
  std::string match_key(std::string_view request) const override {
    if (!request.empty() && request.back() == lf) request.remove_suffix(1);
    if (!request.empty() && request.back() == cr) request.remove_suffix(1);
    return std::string(request);
  }

  // A reply's lines after the echo each end with their sum (the status
  // line too). A line whose sum is right is kept as it is (a parameter
  // line's under either rule: drivers accept both); commands carry no sum.
  std::string recompute_checksums(StreamDirection direction,
                                  std::string_view frame) const override {
    std::string fixed(frame);
    if (direction == StreamDirection::tx) return fixed;
    const bool parameters = is_parameter_reply(command_code(first_line(frame)));
    std::size_t start = frame.find(lf);
    while (start != std::string_view::npos && start + 1 < fixed.size()) {
      const std::size_t line_start = start + 1;
      const std::size_t end = fixed.find(lf, line_start);
      if (end == std::string::npos) break;  // a line cut short has no sum yet
      start = end;
      std::string_view line = std::string_view(fixed).substr(line_start, end - line_start);
      if (!line.empty() && line.back() == cr) line.remove_suffix(1);
      if (line.size() < 2) continue;  // an empty line, or SCIP 1.1's one-byte status
      const std::string_view data = line.substr(0, line.size() - 1);
      const char stored = line.back();
      const bool semicolon = data.back() == ';';
      const bool leaves_out_semicolon = parameters && semicolon;
      if (stored == line_sum(data) ||
          (leaves_out_semicolon && stored == line_sum(data.substr(0, data.size() - 1)))) {
        continue;
      }
      fixed[line_start + data.size()] =
          line_sum(leaves_out_semicolon ? data.substr(0, data.size() - 1) : data);
    }
    return fixed;
  }

  std::string frame_name(StreamDirection, std::string_view frame) const override {
    return command_code(first_line(frame));
  }

  // A command: the line as text, padded to 24 columns, then its code and
  // meaning. A reply: its echo line, the command it answers, its status and
  // how many data lines and bytes it holds.
  std::string describe(StreamDirection direction, std::string_view frame) const override {
    const std::string_view echo = first_line(frame);
    const std::string code = command_code(echo);
    const std::string meaning(command_meaning(code));
    if (direction == StreamDirection::tx) {
      std::string_view line = frame;
      while (!line.empty() && line.back() == lf) line.remove_suffix(1);
      return pad_right(escape_bytes(line, 40), 24) + " " + code + ": " + meaning;
    }
    std::string status = "??";
    std::size_t data_lines = 0;
    if (echo.size() < frame.size()) {
      std::string_view rest = frame.substr(echo.size() + 1);
      const std::string_view status_line = first_line(rest);
      status = ascii_or_replacement(status_line.substr(0, 2));
      rest.remove_prefix(std::min(rest.size(), status_line.size() + 1));
      while (!rest.empty()) {
        const std::string_view line = first_line(rest);
        if (!line.empty()) ++data_lines;
        rest.remove_prefix(std::min(rest.size(), line.size() + 1));
      }
    }
    const std::string status_text = status == "00"   ? "ok"
                                    : status == "99" ? "scan data"
                                                     : "status";
    return pad_right(escape_bytes(echo, 24), 24) + " reply to " + code + " (" + meaning +
           "): " + status_text + " " + status + ", " + std::to_string(data_lines) +
           " data lines, " + std::to_string(frame.size()) + " bytes";
  }
};

}  // namespace

std::shared_ptr<const Profile> make_scip_profile() { return std::make_shared<ScipProfile>(); }

}  // namespace wiretape::detail
