#include "core/rfc2217.hpp"

#include <optional>

namespace wiretape::detail::rfc2217 {

namespace {

// Telnet bytes (RFC 854/855) and the COM-PORT-OPTION (RFC 2217).
namespace telnet {
constexpr std::uint8_t se = 240, sb = 250, will = 251, wont = 252, do_ = 253,
                       dont = 254, iac = 255;
constexpr std::uint8_t binary = 0, echo = 1, sga = 3, com_port = 44;
}  // namespace telnet

// Client -> server commands; the server answers with command + 100.
enum Command : std::uint8_t {
  set_baudrate = 1,
  set_datasize = 2,
  set_parity = 3,
  set_stopsize = 4,
  set_control = 5,
  notify_linestate = 6,
  notify_modemstate = 7,
  flowcontrol_suspend = 8,
  flowcontrol_resume = 9,
  set_linestate_mask = 10,
  set_modemstate_mask = 11,
  purge_data = 12,
};
constexpr std::uint8_t server_reply_offset = 100;

// SET-CONTROL values.
namespace control {
constexpr std::uint8_t ask_flow = 0, flow_none = 1, flow_xonxoff = 2, flow_rtscts = 3,
                       ask_break = 4, break_on = 5, break_off = 6, ask_dtr = 7, dtr_on = 8,
                       dtr_off = 9, ask_rts = 10, rts_on = 11, rts_off = 12,
                       ask_inbound_flow = 13, inbound_flow_none = 14;
}  // namespace control

// Purge: 1 the server's receive buffer (data from the device), 2 its
// transmit buffer (data for the device), 3 both.
constexpr std::uint8_t purge_receive = 1, purge_transmit = 2;

std::optional<Parity> parity_of(std::uint8_t code) {
  switch (code) {
    case 1: return Parity::none;
    case 2: return Parity::odd;
    case 3: return Parity::even;
    case 4: return Parity::mark;
    case 5: return Parity::space;
    default: return std::nullopt;
  }
}

std::uint8_t code_of(Parity parity) {
  switch (parity) {
    case Parity::none: return 1;
    case Parity::odd: return 2;
    case Parity::even: return 3;
    case Parity::mark: return 4;
    case Parity::space: return 5;
  }
  return 1;
}

std::optional<StopBits> stop_bits_of(std::uint8_t code) {
  switch (code) {
    case 1: return StopBits::one;
    case 2: return StopBits::two;
    case 3: return StopBits::one_and_a_half;
    default: return std::nullopt;
  }
}

std::uint8_t code_of(StopBits stop_bits) {
  switch (stop_bits) {
    case StopBits::one: return 1;
    case StopBits::two: return 2;
    case StopBits::one_and_a_half: return 3;
  }
  return 1;
}

std::uint8_t code_of(FlowControl flow) {
  switch (flow) {
    case FlowControl::none: return control::flow_none;
    case FlowControl::xonxoff: return control::flow_xonxoff;
    case FlowControl::rtscts: return control::flow_rtscts;
  }
  return control::flow_none;
}

std::uint8_t code_of(const ModemLines& lines) {
  return static_cast<std::uint8_t>((lines.cd ? 0x80 : 0) | (lines.ri ? 0x40 : 0) |
                                   (lines.dsr ? 0x20 : 0) | (lines.cts ? 0x10 : 0));
}

std::uint8_t code_of(const LineState& state) {
  return static_cast<std::uint8_t>(
      (state.timeout ? 0x80 : 0) | (state.shift_register_empty ? 0x40 : 0) |
      (state.holding_register_empty ? 0x20 : 0) | (state.break_detected ? 0x10 : 0) |
      (state.framing_error ? 0x08 : 0) | (state.parity_error ? 0x04 : 0) |
      (state.overrun_error ? 0x02 : 0) | (state.data_ready ? 0x01 : 0));
}

// A SET-CONTROL request: the setting it names, answered with the value now
// in effect.
std::uint8_t apply_control(ComPort& port, std::uint8_t value) {
  using namespace control;
  const auto level = [](bool on, std::uint8_t on_code, std::uint8_t off_code) {
    return on ? on_code : off_code;
  };
  switch (value) {
    case ask_flow: return code_of(port.set_flow_control(std::nullopt));
    case flow_none: return code_of(port.set_flow_control(FlowControl::none));
    case flow_xonxoff: return code_of(port.set_flow_control(FlowControl::xonxoff));
    case flow_rtscts: return code_of(port.set_flow_control(FlowControl::rtscts));
    case ask_break: return level(port.set_break(std::nullopt), break_on, break_off);
    case break_on:
    case break_off: return level(port.set_break(value == break_on), break_on, break_off);
    case ask_dtr: return level(port.set_dtr(std::nullopt), dtr_on, dtr_off);
    case dtr_on:
    case dtr_off: return level(port.set_dtr(value == dtr_on), dtr_on, dtr_off);
    case ask_rts: return level(port.set_rts(std::nullopt), rts_on, rts_off);
    case rts_on:
    case rts_off: return level(port.set_rts(value == rts_on), rts_on, rts_off);
    // Inbound flow control follows the outbound one.
    case ask_inbound_flow: return inbound_flow_none;
    default: return value;
  }
}

void append_escaped(std::string& out, std::uint8_t byte) {
  out.push_back(static_cast<char>(byte));
  if (byte == telnet::iac) out.push_back(static_cast<char>(byte));
}

void append_option(std::string& out, std::uint8_t command, std::uint8_t option) {
  out.push_back(static_cast<char>(telnet::iac));
  out.push_back(static_cast<char>(command));
  out.push_back(static_cast<char>(option));
}


std::optional<FlowControl> flow_of(std::uint8_t code) {
  switch (code) {
    case control::flow_none: return FlowControl::none;
    case control::flow_xonxoff: return FlowControl::xonxoff;
    case control::flow_rtscts: return FlowControl::rtscts;
    default: return std::nullopt;
  }
}

ModemLines modem_lines_of(std::uint8_t code) {
  ModemLines lines;
  lines.cd = code & 0x80;
  lines.ri = code & 0x40;
  lines.dsr = code & 0x20;
  lines.cts = code & 0x10;
  return lines;
}

LineState line_state_of(std::uint8_t code) {
  LineState state;
  state.timeout = code & 0x80;
  state.shift_register_empty = code & 0x40;
  state.holding_register_empty = code & 0x20;
  state.break_detected = code & 0x10;
  state.framing_error = code & 0x08;
  state.parity_error = code & 0x04;
  state.overrun_error = code & 0x02;
  state.data_ready = code & 0x01;
  return state;
}

std::string one_byte(std::uint8_t value) { return std::string(1, static_cast<char>(value)); }

void encode_command(std::uint8_t code, const std::string& value, std::string& out) {
  out.push_back(static_cast<char>(telnet::iac));
  out.push_back(static_cast<char>(telnet::sb));
  out.push_back(static_cast<char>(telnet::com_port));
  append_escaped(out, code);
  for (char c : value) append_escaped(out, static_cast<std::uint8_t>(c));
  out.push_back(static_cast<char>(telnet::iac));
  out.push_back(static_cast<char>(telnet::se));
}

std::string request(std::uint8_t command, const std::string& value) {
  std::string out;
  encode_command(command, value, out);
  return out;
}

}  // namespace

// --- the shared Telnet session ---------------------------------------------

int TelnetSession::option_index(std::uint8_t option) {
  switch (option) {
    case telnet::binary: return kBinary;
    case telnet::sga: return kSga;
    case telnet::com_port: return kComPort;
    default: return -1;
  }
}

void TelnetSession::escape(const void* data, std::size_t size, std::string& out) {
  const auto* bytes = static_cast<const std::uint8_t*>(data);
  out.reserve(out.size() + size);
  for (std::size_t i = 0; i < size; ++i) append_escaped(out, bytes[i]);
}

void TelnetSession::com_port_command(std::uint8_t code, const std::string& value,
                                     std::string& out) {
  encode_command(code, value, out);
}

void TelnetSession::offer_ours(OptionIndex option, std::string& out) {
  static constexpr std::uint8_t codes[] = {telnet::binary, telnet::sga, telnet::com_port};
  if (we_[option] || we_offered_[option]) return;
  we_offered_[option] = true;
  append_option(out, telnet::will, codes[option]);
}

void TelnetSession::ask_theirs(OptionIndex option, std::string& out) {
  static constexpr std::uint8_t codes[] = {telnet::binary, telnet::sga, telnet::com_port};
  if (they_[option] || they_offered_[option]) return;
  they_offered_[option] = true;
  append_option(out, telnet::do_, codes[option]);
}

void TelnetSession::feed(const void* data, std::size_t size, std::string& data_out,
                         std::string& answers) {
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
          data_out.append(reinterpret_cast<const char*>(bytes + i), end - i);
          i = end - 1;
        }
        break;
      case State::iac:
        if (byte == telnet::iac) {
          data_out.push_back(static_cast<char>(byte));
          state_ = State::data;
          break;
        }
        ++telnet_commands_;
        if (byte >= telnet::will && byte <= telnet::dont) {
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
        negotiate(negotiation_command_, byte, answers);
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
          if (!sub_overflow_) subnegotiation(data_out, answers);
          sub_.clear();
          state_ = State::data;
        } else {
          // IAC <command> inside a subnegotiation: the peer broke off;
          // drop what it started and take the command.
          sub_.clear();
          state_ = State::iac;
          --i;
        }
        break;
    }
  }
}

void TelnetSession::negotiate(std::uint8_t command, std::uint8_t option, std::string& out) {
  const int index = option_index(option);
  switch (command) {
    case telnet::will:  // the peer offers to use `option` on its side
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
      if (index >= 0) {
        if (they_offered_[index]) refused_[index] = true;
        they_offered_[index] = false;
      }
      break;
    case telnet::do_:  // the peer asks us to use `option`
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
      if (index >= 0) {
        if (we_offered_[index]) refused_[index] = true;
        we_offered_[index] = false;
      }
      break;
    default:
      break;
  }
  after_negotiation(out);
}

void TelnetSession::subnegotiation(std::string& data_out, std::string& out) {
  if (sub_.size() < 2 || static_cast<std::uint8_t>(sub_[0]) != telnet::com_port) {
    return;  // another option's subnegotiation, or empty: ignored
  }
  before_com_port_command(data_out);
  com_port_subnegotiation(static_cast<std::uint8_t>(sub_[1]), sub_.substr(2), out);
}

// --- the server side -------------------------------------------------------

std::string ServerSession::greeting() {
  std::string out;
  // Only BINARY is offered: a client that sees an offer of SGA or
  // COM-PORT-OPTION before it sent its own requests (pyserial) takes the
  // option as agreed and never asks, so those are left to the client.
  offer_ours(kBinary, out);
  ask_theirs(kBinary, out);
  return out;
}

void ServerSession::after_negotiation(std::string& out) {
  // pyserial reads the modem lines from the last notification; give it one
  // as soon as the option is agreed.
  if (!announced_ && com_port_active()) {
    announced_ = true;
    reply(notify_modemstate, one_byte(code_of(port_.modem_lines())), out);
  }
}

void ServerSession::before_com_port_command(std::string& data_out) {
  if (device_data_sink_ && !data_out.empty()) device_data_sink_(data_out);
}

std::string ServerSession::modem_state_notification() {
  std::string out;
  if (com_port_active()) {
    reply(notify_modemstate, one_byte(code_of(port_.modem_lines()) & modemstate_mask_), out);
  }
  return out;
}

void ServerSession::reply(std::uint8_t command, const std::string& value, std::string& out) {
  com_port_command(static_cast<std::uint8_t>(command + server_reply_offset), value, out);
}

void ServerSession::com_port_subnegotiation(std::uint8_t command, const std::string& value,
                                            std::string& out) {
  const auto byte_value = [&]() -> std::optional<std::uint8_t> {
    if (value.size() != 1) return std::nullopt;
    return static_cast<std::uint8_t>(value[0]);
  };
  switch (command) {
    case set_baudrate: {
      if (value.size() != 4) return;
      std::uint32_t baud = 0;
      for (char c : value) baud = (baud << 8) | static_cast<std::uint8_t>(c);
      const std::uint32_t now =
          port_.set_baud(baud == 0 ? std::nullopt : std::optional<std::uint32_t>(baud));
      std::string answer(4, '\0');
      for (int i = 0; i < 4; ++i) {
        answer[static_cast<std::size_t>(i)] = static_cast<char>((now >> (8 * (3 - i))) & 0xff);
      }
      reply(command, answer, out);
      return;
    }
    case set_datasize:
      if (auto v = byte_value()) {
        const std::optional<int> bits =
            *v >= 5 && *v <= 8 ? std::optional<int>(*v) : std::nullopt;
        reply(command, one_byte(static_cast<std::uint8_t>(port_.set_data_bits(bits))), out);
      }
      return;
    case set_parity:
      if (auto v = byte_value()) reply(command, one_byte(code_of(port_.set_parity(parity_of(*v)))), out);
      return;
    case set_stopsize:
      if (auto v = byte_value()) {
        reply(command, one_byte(code_of(port_.set_stop_bits(stop_bits_of(*v)))), out);
      }
      return;
    case set_control:
      if (auto v = byte_value()) reply(command, one_byte(apply_control(port_, *v)), out);
      return;
    // A client that asks gets the whole state; the masks filter only what
    // the server sends unasked.
    case notify_linestate:
      reply(command, one_byte(code_of(port_.line_state())), out);
      return;
    case notify_modemstate:
      reply(command, one_byte(code_of(port_.modem_lines())), out);
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
        reply(command, one_byte(*v), out);
      }
      return;
    case set_modemstate_mask:
      if (auto v = byte_value()) {
        modemstate_mask_ = *v;
        reply(command, one_byte(*v), out);
      }
      return;
    case purge_data:
      if (auto v = byte_value()) {
        if (*v >= 1 && *v <= 3) port_.purge(*v & purge_receive, *v & purge_transmit);
        reply(command, one_byte(*v), out);
      }
      return;
    default:
      return;  // unknown command: ignored, as RFC 2217 asks
  }
}

// --- the client side -------------------------------------------------------

std::string ClientSession::greeting() {
  std::string out;
  offer_ours(kBinary, out);
  ask_theirs(kBinary, out);
  offer_ours(kSga, out);
  ask_theirs(kSga, out);
  offer_ours(kComPort, out);
  return out;
}

std::string ClientSession::set_baud(std::uint32_t baud) {
  std::string value(4, '\0');
  for (int i = 0; i < 4; ++i) {
    value[static_cast<std::size_t>(i)] = static_cast<char>((baud >> (8 * (3 - i))) & 0xff);
  }
  return request(set_baudrate, value);
}

std::string ClientSession::set_data_bits(int bits) {
  return request(set_datasize, one_byte(static_cast<std::uint8_t>(bits)));
}

std::string ClientSession::set_parity(Parity parity) {
  return request(Command::set_parity, one_byte(code_of(parity)));
}

std::string ClientSession::set_stop_bits(StopBits stop_bits) {
  return request(set_stopsize, one_byte(code_of(stop_bits)));
}

std::string ClientSession::set_flow_control(FlowControl flow) {
  return request(set_control, one_byte(code_of(flow)));
}

std::string ClientSession::set_break(bool on) {
  return request(set_control, one_byte(on ? control::break_on : control::break_off));
}

std::string ClientSession::set_dtr(bool on) {
  return request(set_control, one_byte(on ? control::dtr_on : control::dtr_off));
}

std::string ClientSession::set_rts(bool on) {
  return request(set_control, one_byte(on ? control::rts_on : control::rts_off));
}

std::string ClientSession::purge(bool from_device, bool for_device) {
  const auto which = static_cast<std::uint8_t>((from_device ? purge_receive : 0) |
                                               (for_device ? purge_transmit : 0));
  return request(purge_data, one_byte(which));
}

std::string ClientSession::set_modem_state_mask(std::uint8_t mask) {
  return request(set_modemstate_mask, one_byte(mask));
}

const char* ClientSession::name_of(Answer answer) {
  switch (answer) {
    case Answer::baud: return "SET-BAUDRATE";
    case Answer::data_size: return "SET-DATASIZE";
    case Answer::parity: return "SET-PARITY";
    case Answer::stop_size: return "SET-STOPSIZE";
    case Answer::control: return "SET-CONTROL";
    case Answer::purge: return "PURGE-DATA";
    case Answer::modem_mask: return "SET-MODEMSTATE-MASK";
    case Answer::count: break;
  }
  return "COM-PORT-OPTION";
}

void ClientSession::control_answer(std::uint8_t value) {
  using namespace control;
  if (auto flow = flow_of(value)) {
    state_.flow = flow;
  } else if (value == break_on || value == break_off) {
    state_.break_on = value == break_on;
  } else if (value == dtr_on || value == dtr_off) {
    state_.dtr = value == dtr_on;
  } else if (value == rts_on || value == rts_off) {
    state_.rts = value == rts_on;
  }
  // Inbound flow control and unknown values: answered, nothing to keep.
}

void ClientSession::com_port_subnegotiation(std::uint8_t code, const std::string& value,
                                            std::string& /*out*/) {
  // A server answers with the command's code + 100; anything else from it
  // (a client's code, an unknown one) is ignored, as RFC 2217 asks.
  if (code <= server_reply_offset) return;
  const auto command = static_cast<std::uint8_t>(code - server_reply_offset);
  const auto count = [&](Answer answer) { ++answers_[static_cast<int>(answer)]; };
  if (command == set_baudrate) {
    if (value.size() != 4) return;
    std::uint32_t baud = 0;
    for (char c : value) baud = (baud << 8) | static_cast<std::uint8_t>(c);
    state_.baud = baud;
    count(Answer::baud);
    return;
  }
  if (value.size() != 1) return;  // every other answer is one byte
  const auto v = static_cast<std::uint8_t>(value[0]);
  switch (command) {
    case set_datasize:
      if (v >= 5 && v <= 8) state_.data_bits = v;
      count(Answer::data_size);
      return;
    case Command::set_parity:
      if (auto parity = parity_of(v)) state_.parity = parity;
      count(Answer::parity);
      return;
    case set_stopsize:
      if (auto stop_bits = stop_bits_of(v)) state_.stop_bits = stop_bits;
      count(Answer::stop_size);
      return;
    case set_control:
      control_answer(v);
      count(Answer::control);
      return;
    case notify_linestate:
      state_.line_state = line_state_of(v);
      ++state_.line_notifications;
      return;
    case notify_modemstate:
      state_.modem_lines = modem_lines_of(v);
      ++state_.modem_notifications;
      return;
    case set_modemstate_mask:
      count(Answer::modem_mask);
      return;
    case purge_data:
      count(Answer::purge);
      return;
    default:
      return;
  }
}

}  // namespace wiretape::detail::rfc2217
