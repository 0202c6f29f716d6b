// The `modbus-tcp` and `modbus-rtu` profiles.
//
// Modbus TCP frames are an MBAP header (transaction id, protocol id 0,
// length of what follows, unit id) and a PDU (function code, data). The
// transaction id is the client's counter: the match key leaves it out, and a
// served response takes the client's. A length below 2 or above 254, or a
// protocol id other than 0, is a broken frame (the header is cut off as
// one, and framing goes on after it).
//
// Modbus RTU frames (unit id, function code, data, CRC-16 low byte first)
// have no length field: the framer knows each public function code's layout
// in each direction. A bad CRC makes a broken frame; a function code it
// does not know makes the byte a broken frame of its own (garbage), so that
// framing finds its way back. The key leaves the CRC out.
#include <cstdio>
#include <string>

#include "replay/profiles/builtin.hpp"
#include "replay/profiles/checksums.hpp"
#include "util/hex.hpp"

namespace wiretape::detail {

namespace {

std::uint8_t u8(std::string_view frame, std::size_t at) {
  return static_cast<std::uint8_t>(frame[at]);
}
unsigned be16(std::string_view frame, std::size_t at) {
  return (static_cast<unsigned>(u8(frame, at)) << 8) | u8(frame, at + 1);
}

const char* function_name(unsigned code) {
  switch (code & 0x7F) {
    case 1: return "read coils";
    case 2: return "read discrete inputs";
    case 3: return "read holding registers";
    case 4: return "read input registers";
    case 5: return "write single coil";
    case 6: return "write single register";
    case 7: return "read exception status";
    case 8: return "diagnostics";
    case 15: return "write multiple coils";
    case 16: return "write multiple registers";
    case 17: return "report server id";
    case 22: return "mask write register";
    case 23: return "read/write multiple registers";
    case 43: return "encapsulated interface";
    default: return "function";
  }
}

// "read holding registers (3) address 0 count 10" from a PDU.
std::string describe_pdu(StreamDirection direction, std::string_view pdu) {
  if (pdu.empty()) return "(no PDU)";
  const unsigned code = u8(pdu, 0);
  char text[160];
  if (code & 0x80) {
    std::snprintf(text, sizeof text, "exception to %s (%u): code %u", function_name(code),
                  code & 0x7F, pdu.size() > 1 ? u8(pdu, 1) : 0);
    return text;
  }
  const bool addressed = code == 1 || code == 2 || code == 3 || code == 4 || code == 5 ||
                         code == 6 || code == 15 || code == 16;
  if (direction == StreamDirection::tx && addressed && pdu.size() >= 5) {
    std::snprintf(text, sizeof text, "%s (%u) address %u %s %u", function_name(code), code,
                  be16(pdu, 1), (code == 5 || code == 6) ? "value" : "count", be16(pdu, 3));
    return text;
  }
  if (direction == StreamDirection::rx && code <= 4 && pdu.size() >= 2) {
    std::snprintf(text, sizeof text, "%s (%u) reply, %u bytes", function_name(code), code,
                  u8(pdu, 1));
    return text;
  }
  std::snprintf(text, sizeof text, "%s (%u)", function_name(code), code);
  return text;
}

std::string pdu_field(StreamDirection direction, std::string_view pdu, std::size_t offset) {
  if (offset == 0) return "function code";
  const unsigned code = pdu.empty() ? 0 : u8(pdu, 0);
  if (direction == StreamDirection::tx && code >= 1 && code <= 16) {
    if (offset <= 2) return "address";
    if (offset <= 4) return (code == 5 || code == 6) ? "value" : "count";
  }
  return "data";
}

// --- TCP --------------------------------------------------------------------

constexpr std::size_t mbap_size = 7;

class MbapFramer final : public BufferingFramer {
 public:
  void feed(std::string_view bytes, std::vector<Frame>& frames) override {
    for (char byte : bytes) {
      buffer_ += byte;
      if (buffer_.size() == 6) {
        length_ = be16(buffer_, 4);
        if (be16(buffer_, 2) != 0) {
          cut(FrameEnd::broken, frames,
              "protocol id " + std::to_string(be16(buffer_, 2)) + " is not Modbus (0)");
        } else if (length_ < 2 || length_ > 254) {
          cut(FrameEnd::broken, frames,
              "bad length " + std::to_string(length_) + " (Modbus TCP allows 2..254)");
        }
        continue;
      }
      if (buffer_.size() > 6 && buffer_.size() == 6 + length_) cut(FrameEnd::delimited, frames);
    }
  }

 private:
  void forget_frame() override { length_ = 0; }
  std::size_t length_ = 0;
};

class ModbusTcpProfile final : public Profile {
 public:
  std::string_view name() const override { return "modbus-tcp"; }
  std::string_view summary() const override {
    return "Modbus TCP (MBAP header + PDU); the transaction id is left out of the key "
           "and taken from the client's request";
  }
  std::unique_ptr<Framer> make_framer(StreamDirection) const override {
    return std::make_unique<MbapFramer>();
  }
  std::string match_key(std::string_view request) const override {
    return std::string(request.substr(std::min<std::size_t>(2, request.size())));
  }
  bool fixes_responses() const override { return true; }
  std::string fix_response(std::string_view, std::string_view actual_request,
                           std::string_view response) const override {
    std::string fixed(response);
    if (fixed.size() >= 2 && actual_request.size() >= 2) {
      fixed[0] = actual_request[0];
      fixed[1] = actual_request[1];
    }
    return fixed;
  }
  std::string frame_name(StreamDirection, std::string_view frame) const override {
    if (frame.size() < 8) return "(short frame)";
    const unsigned code = u8(frame, 7);
    return std::string(code & 0x80 ? "exception " : "") + function_name(code);
  }
  std::string describe(StreamDirection direction, std::string_view frame) const override {
    if (frame.size() < mbap_size + 1) return "short Modbus TCP frame: " + escape_bytes(frame);
    char head[64];
    std::snprintf(head, sizeof head, "tid %u unit %u: ", be16(frame, 0), u8(frame, 6));
    return head + describe_pdu(direction, frame.substr(mbap_size));
  }
  std::string field_name(StreamDirection direction, std::string_view frame,
                         std::size_t offset) const override {
    if (offset < 2) return "transaction id";
    if (offset < 4) return "protocol id";
    if (offset < 6) return "length";
    if (offset == 6) return "unit id";
    return pdu_field(direction, frame.substr(std::min(mbap_size, frame.size())),
                     offset - mbap_size);
  }
};

// --- RTU --------------------------------------------------------------------

// The size of a frame whose first `have` bytes are known, 0 if not known yet,
// or nullopt when the function code is not one the framer knows.
std::optional<std::size_t> rtu_size(StreamDirection direction, std::string_view frame) {
  if (frame.size() < 2) return 0;
  const unsigned code = u8(frame, 1);
  if (code & 0x80) return 5;
  switch (code) {
    case 1: case 2: case 3: case 4:
      if (direction == StreamDirection::tx) return 8;
      return frame.size() < 3 ? 0 : 5 + static_cast<std::size_t>(u8(frame, 2));
    case 5: case 6: return 8;
    case 7: return direction == StreamDirection::tx ? 4 : 5;
    case 15: case 16:
      if (direction == StreamDirection::rx) return 8;
      return frame.size() < 7 ? 0 : 9 + static_cast<std::size_t>(u8(frame, 6));
    case 23:
      if (direction == StreamDirection::rx) {
        return frame.size() < 3 ? 0 : 5 + static_cast<std::size_t>(u8(frame, 2));
      }
      return frame.size() < 11 ? 0 : 13 + static_cast<std::size_t>(u8(frame, 10));
    default: return std::nullopt;
  }
}

class RtuFramer final : public BufferingFramer {
 public:
  explicit RtuFramer(StreamDirection direction) : direction_(direction) {}

  void feed(std::string_view bytes, std::vector<Frame>& frames) override {
    for (char byte : bytes) {
      buffer_ += byte;
      const std::optional<std::size_t> size = rtu_size(direction_, buffer_);
      if (!size) {
        // Not a frame: the unit id byte alone is garbage; go on after it.
        const std::string rest = buffer_.substr(1);
        buffer_.resize(1);
        cut(FrameEnd::broken, frames, "garbage: no Modbus RTU frame begins here");
        feed(rest, frames);
        continue;
      }
      if (*size == 0 || buffer_.size() < *size) continue;
      const std::string_view body = std::string_view(buffer_).substr(0, *size - 2);
      const unsigned stored = u8(buffer_, *size - 2) | (u8(buffer_, *size - 1) << 8);
      const unsigned computed = crc16_modbus(body);
      if (stored != computed) {
        char problem[80];
        std::snprintf(problem, sizeof problem, "bad CRC 0x%04x, computed 0x%04x", stored,
                      computed);
        cut(FrameEnd::broken, frames, problem);
      } else {
        cut(FrameEnd::delimited, frames);
      }
    }
  }

 private:
  StreamDirection direction_;
};

class ModbusRtuProfile final : public Profile {
 public:
  std::string_view name() const override { return "modbus-rtu"; }
  std::string_view summary() const override {
    return "Modbus RTU (unit id, PDU, CRC-16); the CRC is checked and left out of the key";
  }
  std::unique_ptr<Framer> make_framer(StreamDirection direction) const override {
    return std::make_unique<RtuFramer>(direction);
  }
  std::string match_key(std::string_view request) const override {
    return std::string(request.substr(0, request.size() >= 2 ? request.size() - 2 : 0));
  }
  // The CRC of a frame whose function code gives its size: garbage and a
  // frame cut short are left as they are.
  std::string recompute_checksums(StreamDirection direction,
                                  std::string_view frame) const override {
    std::string fixed(frame);
    const std::optional<std::size_t> size = rtu_size(direction, frame);
    if (!size || *size != frame.size() || frame.size() < 4) return fixed;
    const std::uint16_t crc = crc16_modbus(frame.substr(0, frame.size() - 2));
    fixed[fixed.size() - 2] = static_cast<char>(crc & 0xFF);
    fixed[fixed.size() - 1] = static_cast<char>(crc >> 8);
    return fixed;
  }
  std::string frame_name(StreamDirection, std::string_view frame) const override {
    if (frame.size() < 2) return "(short frame)";
    const unsigned code = u8(frame, 1);
    return std::string(code & 0x80 ? "exception " : "") + function_name(code);
  }
  std::string describe(StreamDirection direction, std::string_view frame) const override {
    if (frame.size() < 4) return "short Modbus RTU frame: " + escape_bytes(frame);
    char head[32];
    std::snprintf(head, sizeof head, "unit %u: ", u8(frame, 0));
    return head + describe_pdu(direction, frame.substr(1, frame.size() - 3));
  }
  std::string field_name(StreamDirection direction, std::string_view frame,
                         std::size_t offset) const override {
    if (offset == 0) return "unit id";
    if (frame.size() >= 2 && offset >= frame.size() - 2) return "CRC";
    return pdu_field(direction, frame.substr(1), offset - 1);
  }
};

}  // namespace

std::shared_ptr<const Profile> make_modbus_tcp_profile() {
  return std::make_shared<ModbusTcpProfile>();
}
std::shared_ptr<const Profile> make_modbus_rtu_profile() {
  return std::make_shared<ModbusRtuProfile>();
}

}  // namespace wiretape::detail
