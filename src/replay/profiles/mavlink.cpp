// The `mavlink` profile: MAVLink v1 (0xFE) and v2 (0xFD) packets, both
// directions. The key leaves out the sequence number, the CRC and a v2
// signature: a client's counters differ from the recording's. Bytes before
// a start marker are a broken frame (garbage); a packet whose CRC does not
// match (for the messages whose CRC_EXTRA this profile knows) is broken too.
// Responses are served unchanged: the vehicle's own sequence numbers and
// CRCs stay valid.
#include <cstdio>
#include <string>

#include "replay/profiles/builtin.hpp"
#include "replay/profiles/checksums.hpp"
#include "util/hex.hpp"

namespace wiretape::detail {

namespace {

constexpr unsigned char v1_magic = 0xFE;
constexpr unsigned char v2_magic = 0xFD;
constexpr std::size_t signature_size = 13;

std::uint8_t u8(std::string_view frame, std::size_t at) {
  return static_cast<std::uint8_t>(frame[at]);
}

struct MessageInfo {
  std::uint32_t id;
  std::uint8_t crc_extra;
  const char* name;
};

// The common dialect's messages a ground station and an autopilot exchange
// most; others frame and match as well, only their CRC is not checked.
constexpr MessageInfo messages[] = {
    {0, 50, "HEARTBEAT"},
    {1, 124, "SYS_STATUS"},
    {2, 137, "SYSTEM_TIME"},
    {4, 237, "PING"},
    {11, 89, "SET_MODE"},
    {20, 214, "PARAM_REQUEST_READ"},
    {21, 159, "PARAM_REQUEST_LIST"},
    {22, 220, "PARAM_VALUE"},
    {23, 168, "PARAM_SET"},
    {24, 24, "GPS_RAW_INT"},
    {30, 39, "ATTITUDE"},
    {33, 104, "GLOBAL_POSITION_INT"},
    {43, 132, "MISSION_REQUEST_LIST"},
    {44, 221, "MISSION_COUNT"},
    {66, 148, "REQUEST_DATA_STREAM"},
    {74, 20, "VFR_HUD"},
    {76, 152, "COMMAND_LONG"},
    {77, 143, "COMMAND_ACK"},
    {111, 34, "TIMESYNC"},
    {148, 178, "AUTOPILOT_VERSION"},
    {253, 83, "STATUSTEXT"},
};

const MessageInfo* find_message(std::uint32_t id) {
  for (const MessageInfo& info : messages) {
    if (info.id == id) return &info;
  }
  return nullptr;
}

bool is_v2(std::string_view frame) { return !frame.empty() && u8(frame, 0) == v2_magic; }
std::size_t header_size(std::string_view frame) { return is_v2(frame) ? 10 : 6; }

std::uint32_t message_id(std::string_view frame) {
  if (is_v2(frame)) {
    return frame.size() < 10 ? 0
                             : u8(frame, 7) | (u8(frame, 8) << 8) |
                                   (static_cast<std::uint32_t>(u8(frame, 9)) << 16);
  }
  return frame.size() < 6 ? 0 : u8(frame, 5);
}

class MavlinkFramer final : public BufferingFramer {
 public:
  void feed(std::string_view bytes, std::vector<Frame>& frames) override {
    for (char byte : bytes) {
      const auto value = static_cast<unsigned char>(byte);
      if (buffer_.empty() || in_garbage_) {
        if (value == v1_magic || value == v2_magic) {
          if (in_garbage_) {
            cut(FrameEnd::broken, frames, "garbage: bytes before a MAVLink start marker");
          }
        } else {
          in_garbage_ = true;
          buffer_ += byte;
          if (buffer_.size() >= 280) {
            cut(FrameEnd::broken, frames, "garbage: bytes before a MAVLink start marker");
          }
          continue;
        }
      }
      buffer_ += byte;
      if (buffer_.size() == 3 && is_v2(buffer_)) {
        size_ = 12 + u8(buffer_, 1) + ((u8(buffer_, 2) & 1) ? signature_size : 0);
      } else if (buffer_.size() == 2 && !is_v2(buffer_)) {
        size_ = 8 + u8(buffer_, 1);
      }
      if (size_ != 0 && buffer_.size() == size_) finish_packet(frames);
    }
  }

 private:
  void finish_packet(std::vector<Frame>& frames) {
    const std::size_t length = u8(buffer_, 1);
    const std::size_t end = header_size(buffer_) + length;
    if (const MessageInfo* info = find_message(message_id(buffer_))) {
      std::uint16_t crc = crc16_x25(std::string_view(buffer_).substr(1, end - 1));
      const char extra = static_cast<char>(info->crc_extra);
      crc = crc16_x25(std::string_view(&extra, 1), crc);
      const unsigned stored = u8(buffer_, end) | (u8(buffer_, end + 1) << 8);
      if (stored != crc) {
        char problem[96];
        std::snprintf(problem, sizeof problem, "bad CRC 0x%04x in %s, computed 0x%04x", stored,
                      info->name, static_cast<unsigned>(crc));
        cut(FrameEnd::broken, frames, problem);
        return;
      }
    }
    cut(FrameEnd::delimited, frames);
  }
  void forget_frame() override {
    size_ = 0;
    in_garbage_ = false;
  }

  std::size_t size_ = 0;
  bool in_garbage_ = false;
};

class MavlinkProfile final : public Profile {
 public:
  std::string_view name() const override { return "mavlink"; }
  std::string_view summary() const override {
    return "MAVLink v1 and v2 packets; sequence number, CRC and signature left out of the key";
  }
  std::unique_ptr<Framer> make_framer(StreamDirection) const override {
    return std::make_unique<MavlinkFramer>();
  }
  std::string match_key(std::string_view frame) const override {
    if (frame.size() < 8) return std::string(frame);
    const std::size_t seq = is_v2(frame) ? 4 : 2;
    const std::size_t end =
        std::min(frame.size(), header_size(frame) + static_cast<std::size_t>(u8(frame, 1)));
    std::string key(frame.substr(0, seq));
    key.append(frame.substr(seq + 1, end - seq - 1));
    return key;
  }
  // The CRC of a whole packet whose message's CRC_EXTRA this profile knows.
  // A v2 signature is left as it is: it needs the link's secret key.
  std::string recompute_checksums(StreamDirection, std::string_view frame) const override {
    std::string fixed(frame);
    if (frame.size() < 8 || (u8(frame, 0) != v1_magic && u8(frame, 0) != v2_magic)) {
      return fixed;
    }
    const std::size_t end = header_size(frame) + u8(frame, 1);
    const bool signed_packet = is_v2(frame) && (u8(frame, 2) & 1);
    if (frame.size() != end + 2 + (signed_packet ? signature_size : 0)) return fixed;
    const MessageInfo* info = find_message(message_id(frame));
    if (info == nullptr) return fixed;
    std::uint16_t crc = crc16_x25(frame.substr(1, end - 1));
    const char extra = static_cast<char>(info->crc_extra);
    crc = crc16_x25(std::string_view(&extra, 1), crc);
    fixed[end] = static_cast<char>(crc & 0xFF);
    fixed[end + 1] = static_cast<char>(crc >> 8);
    return fixed;
  }
  std::string frame_name(StreamDirection, std::string_view frame) const override {
    if (frame.size() < 6 || (u8(frame, 0) != v1_magic && u8(frame, 0) != v2_magic)) {
      return "(not MAVLink)";
    }
    const std::uint32_t id = message_id(frame);
    if (const MessageInfo* info = find_message(id)) return info->name;
    return "MESSAGE_" + std::to_string(id);
  }
  std::string describe(StreamDirection direction, std::string_view frame) const override {
    if (frame.size() < 8) return "short MAVLink packet: " + escape_bytes(frame);
    char text[128];
    const std::size_t sys = is_v2(frame) ? 5 : 3;
    std::snprintf(text, sizeof text, "v%d %s seq %u sys %u comp %u, %u payload bytes",
                  is_v2(frame) ? 2 : 1, frame_name(direction, frame).c_str(),
                  u8(frame, sys - 1), u8(frame, sys), u8(frame, sys + 1), u8(frame, 1));
    return text;
  }
  std::string field_name(StreamDirection, std::string_view frame,
                         std::size_t offset) const override {
    if (offset == 0) return "start marker";
    if (offset == 1) return "payload length";
    const bool v2 = is_v2(frame);
    const std::size_t end = header_size(frame) + (frame.size() > 1 ? u8(frame, 1) : 0);
    if (v2 && offset == 2) return "incompatibility flags";
    if (v2 && offset == 3) return "compatibility flags";
    const std::size_t seq = v2 ? 4 : 2;
    if (offset == seq) return "sequence";
    if (offset == seq + 1) return "system id";
    if (offset == seq + 2) return "component id";
    if (offset < header_size(frame)) return "message id";
    if (offset < end) return "payload";
    if (offset < end + 2) return "CRC";
    return "signature";
  }
};

}  // namespace

std::shared_ptr<const Profile> make_mavlink_profile() {
  return std::make_shared<MavlinkProfile>();
}

}  // namespace wiretape::detail
