#include "bridge/rfc2217.hpp"

#include <optional>

namespace wiretape::detail::rfc2217 {

namespace {

void append_escaped(std::string& out, std::uint8_t byte) {
  out.push_back(static_cast<char>(byte));
  if (byte == telnet::iac) out.push_back(static_cast<char>(byte));
}

void append_option(std::string& out, std::uint8_t command, std::uint8_t option) {
  out.push_back(static_cast<char>(telnet::iac));
  out.push_back(static_cast<char>(command));
  out.push_back(static_cast<char>(option));
}

}  // namespace

int ServerSession::option_index(std::uint8_t option) {
  switch (option) {
    case telnet::binary: return kBinary;
    case telnet::sga: return kSga;
    case telnet::com_port: return kComPort;
    default: return -1;
  }
}

std::string ServerSession::greeting() {
  std::string out;
  // Only BINARY is offered: a client that sees an offer of SGA or
  // COM-PORT-OPTION before it sent its own requests (pyserial) takes the
  // option as agreed and never asks, so those are left to the client.
  for (std::uint8_t option : {telnet::binary}) {
    const int index = option_index(option);
    if (!we_[index] && !we_offered_[index]) {
      we_offered_[index] = true;
      append_option(out, telnet::will, option);
    }
  }
  if (!they_[kBinary] && !they_offered_[kBinary]) {
    they_offered_[kBinary] = true;
    append_option(out, telnet::do_, telnet::binary);
  }
  return out;
}

void ServerSession::escape(const void* data, std::size_t size, std::string& out) {
  const auto* bytes = static_cast<const std::uint8_t*>(data);
  out.reserve(out.size() + size);
  for (std::size_t i = 0; i < size; ++i) append_escaped(out, bytes[i]);
}

void ServerSession::receive(const void* data, std::size_t size,
                            std::string& to_device, std::string& to_client) {
  const auto* bytes = static_cast<const std::uint8_t*>(data);
  for (std::size_t i = 0; i < size; ++i) {
    const std::uint8_t byte = bytes[i];
    switch (state_) {
      case State::data:
        if (byte == telnet::iac) {
          state_ = State::iac;
        } else {
          // Runs of plain data are copied in one piece.
          std::size_t end = i + 1;
          while (end < size && bytes[end] != telnet::iac) ++end;
          to_device.append(reinterpret_cast<const char*>(bytes + i), end - i);
          i = end - 1;
        }
        break;
      case State::iac:
        if (byte == telnet::iac) {
          to_device.push_back(static_cast<char>(byte));
          state_ = State::data;
        } else if (byte >= telnet::will && byte <= telnet::dont) {
          negotiation_command_ = byte;
          state_ = State::negotiate;
        } else if (byte == telnet::sb) {
          sub_.clear();
          sub_overflow_ = false;
          state_ = State::subnegotiation;
        } else {
          // NOP, AYT, BRK, GA, a stray SE...: nothing to do for a serial
          // line.
          state_ = State::data;
        }
        break;
      case State::negotiate:
        negotiate(negotiation_command_, byte, to_client);
        state_ = State::data;
        break;
      case State::subnegotiation:
        if (byte == telnet::iac) {
          state_ = State::subnegotiation_iac;
        } else if (sub_.size() < kMaxSubnegotiation) {
          sub_.push_back(static_cast<char>(byte));
        } else {
          sub_overflow_ = true;
        }
        break;
      case State::subnegotiation_iac:
        if (byte == telnet::iac) {
          if (sub_.size() < kMaxSubnegotiation) {
            sub_.push_back(static_cast<char>(byte));
          } else {
            sub_overflow_ = true;
          }
          state_ = State::subnegotiation;
        } else if (byte == telnet::se) {
          if (!sub_overflow_) subnegotiation(to_client);
          sub_.clear();
          state_ = State::data;
        } else {
          // IAC <command> inside a subnegotiation: the client broke off;
          // drop what it started and take the command.
          sub_.clear();
          state_ = State::iac;
          --i;
        }
        break;
    }
  }
}

void ServerSession::negotiate(std::uint8_t command, std::uint8_t option,
                              std::string& out) {
  const int index = option_index(option);
  switch (command) {
    case telnet::will:  // the client offers to use `option` on its side
      if (index < 0) {
        append_option(out, telnet::dont, option);
      } else if (!they_[index]) {
        they_[index] = true;
        if (!they_offered_[index]) append_option(out, telnet::do_, option);
        they_offered_[index] = false;
      }
      break;
    case telnet::wont:
      if (index >= 0 && they_[index]) {
        they_[index] = false;
        append_option(out, telnet::dont, option);
      }
      if (index >= 0) they_offered_[index] = false;
      break;
    case telnet::do_:  // the client asks us to use `option`
      if (index < 0) {
        append_option(out, telnet::wont, option);
      } else if (!we_[index]) {
        we_[index] = true;
        if (!we_offered_[index]) append_option(out, telnet::will, option);
        we_offered_[index] = false;
      }
      break;
    case telnet::dont:
      if (index >= 0 && we_[index]) {
        we_[index] = false;
        append_option(out, telnet::wont, option);
      }
      if (index >= 0) we_offered_[index] = false;
      break;
    default:
      break;
  }
  maybe_announce(out);
}

void ServerSession::maybe_announce(std::string& out) {
  // pyserial reads the modem lines from the last notification; give it one
  // as soon as the option is agreed.
  if (!announced_ && com_port_active()) {
    announced_ = true;
    reply(notify_modemstate, std::string(1, static_cast<char>(port_.modem_state())), out);
  }
}

std::string ServerSession::modem_state_notification() {
  std::string out;
  if (com_port_active()) {
    reply(notify_modemstate,
          std::string(1, static_cast<char>(port_.modem_state() & modemstate_mask_)),
          out);
  }
  return out;
}

void ServerSession::reply(std::uint8_t command, const std::string& value,
                          std::string& out) {
  out.push_back(static_cast<char>(telnet::iac));
  out.push_back(static_cast<char>(telnet::sb));
  out.push_back(static_cast<char>(telnet::com_port));
  append_escaped(out, static_cast<std::uint8_t>(command + server_reply_offset));
  escape(value.data(), value.size(), out);
  out.push_back(static_cast<char>(telnet::iac));
  out.push_back(static_cast<char>(telnet::se));
}

void ServerSession::subnegotiation(std::string& out) {
  if (sub_.size() < 2 ||
      static_cast<std::uint8_t>(sub_[0]) != telnet::com_port) {
    return;  // another option's subnegotiation, or empty: ignored
  }
  const auto command = static_cast<std::uint8_t>(sub_[1]);
  const std::string value = sub_.substr(2);
  const auto byte_value = [&]() -> std::optional<std::uint8_t> {
    if (value.size() != 1) return std::nullopt;
    return static_cast<std::uint8_t>(value[0]);
  };
  const auto one = [](std::uint8_t v) { return std::string(1, static_cast<char>(v)); };
  switch (command) {
    case set_baudrate: {
      if (value.size() != 4) return;
      std::uint32_t baud = 0;
      for (char c : value) baud = (baud << 8) | static_cast<std::uint8_t>(c);
      const std::uint32_t now = port_.set_baud(baud);
      std::string answer(4, '\0');
      for (int i = 0; i < 4; ++i) {
        answer[static_cast<std::size_t>(i)] = static_cast<char>((now >> (8 * (3 - i))) & 0xff);
      }
      reply(command, answer, out);
      return;
    }
    case set_datasize:
      if (auto v = byte_value()) reply(command, one(port_.set_data_size(*v)), out);
      return;
    case set_parity:
      if (auto v = byte_value()) reply(command, one(port_.set_parity(*v)), out);
      return;
    case set_stopsize:
      if (auto v = byte_value()) reply(command, one(port_.set_stop_size(*v)), out);
      return;
    case set_control:
      if (auto v = byte_value()) reply(command, one(port_.set_control(*v)), out);
      return;
    // A client that asks gets the whole state; the masks filter only what
    // the server sends unasked.
    case notify_linestate:
      reply(command, one(port_.line_state()), out);
      return;
    case notify_modemstate:
      reply(command, one(port_.modem_state()), out);
      return;
    case flowcontrol_suspend:
      suspended_ = true;
      return;
    case flowcontrol_resume:
      suspended_ = false;
      return;
    case set_linestate_mask:
      if (auto v = byte_value()) {
        linestate_mask_ = *v;
        reply(command, one(*v), out);
      }
      return;
    case set_modemstate_mask:
      if (auto v = byte_value()) {
        modemstate_mask_ = *v;
        reply(command, one(*v), out);
      }
      return;
    case purge_data:
      if (auto v = byte_value()) {
        if (*v >= 1 && *v <= 3) port_.purge(*v);
        reply(command, one(*v), out);
      }
      return;
    default:
      return;  // unknown command: ignored, as RFC 2217 asks
  }
}

}  // namespace wiretape::detail::rfc2217
