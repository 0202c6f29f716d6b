// The `slcan` profile: the serial-line CAN adapters' (LAWICEL) ASCII
// protocol. A command or reply ends with CR; a BEL (0x07) is an error reply
// of its own. The key is the frame without its CR.
#include <string>

#include "replay/profiles/builtin.hpp"
#include "util/hex.hpp"

namespace wiretape::detail {

namespace {

class SlcanFramer final : public BufferingFramer {
 public:
  void feed(std::string_view bytes, std::vector<Frame>& frames) override {
    for (char byte : bytes) {
      buffer_ += byte;
      if (byte == '\r' || byte == '\a') {
        cut(FrameEnd::delimited, frames);
      } else if (buffer_.size() >= 64) {
        // The longest slcan frame (T, 8 id digits, length, 16 data digits,
        // a time stamp) is well below this.
        cut(FrameEnd::size_limit, frames, "no CR in 64 bytes: not slcan");
      }
    }
  }
};

const char* command_name(char code) {
  switch (code) {
    case 'O': return "open channel";
    case 'L': return "open listen-only";
    case 'C': return "close channel";
    case 'S': return "set bit rate";
    case 's': return "set bit timing";
    case 't': return "standard frame";
    case 'T': return "extended frame";
    case 'r': return "standard remote frame";
    case 'R': return "extended remote frame";
    case 'F': return "read status flags";
    case 'V': return "version";
    case 'v': return "firmware version";
    case 'N': return "serial number";
    case 'Z': return "time stamps";
    case 'M': return "acceptance code";
    case 'm': return "acceptance mask";
    case '\r': return "ok";
    case '\a': return "error";
    case 'z': return "frame sent";
    default: return "command";
  }
}

class SlcanProfile final : public Profile {
 public:
  std::string_view name() const override { return "slcan"; }
  std::string_view summary() const override {
    return "serial-line CAN (LAWICEL): commands and replies ending with CR, BEL for errors";
  }
  std::unique_ptr<Framer> make_framer(StreamDirection) const override {
    return std::make_unique<SlcanFramer>();
  }
  std::string match_key(std::string_view request) const override {
    if (!request.empty() && request.back() == '\r') request.remove_suffix(1);
    return std::string(request);
  }
  std::string frame_name(StreamDirection, std::string_view frame) const override {
    return frame.empty() ? "(empty)" : command_name(frame[0]);
  }
  std::string describe(StreamDirection direction, std::string_view frame) const override {
    return frame_name(direction, frame) + ": " + escape_bytes(frame, 64);
  }
  std::string field_name(StreamDirection, std::string_view frame,
                         std::size_t offset) const override {
    if (offset == 0) return "command";
    if (frame.empty()) return {};
    const char code = frame[0];
    if (code == 't' || code == 'r') {
      if (offset <= 3) return "identifier";
      if (offset == 4) return "length";
      return "data";
    }
    if (code == 'T' || code == 'R') {
      if (offset <= 8) return "identifier";
      if (offset == 9) return "length";
      return "data";
    }
    return "argument";
  }
};

}  // namespace

std::shared_ptr<const Profile> make_slcan_profile() { return std::make_shared<SlcanProfile>(); }

}  // namespace wiretape::detail
