// RFC 2217 (Telnet COM-PORT-CONTROL), both sides, without any I/O: one
// Telnet reader and one option negotiation shared by the server session
// (the bridge's `serve`/`replay --listen --protocol rfc2217`) and the client
// session (the port type=rfc2217, src/posix/rfc2217_port.cpp). Each is fed
// what its peer sent and gives back the data and the Telnet answers. Kept
// free of sockets so that both can be fuzzed (fuzz/rfc2217_fuzz.cpp) and
// tested byte for byte (tests/cpp/core/rfc2217_test.cpp).
//
// The protocol's codes (Telnet commands, COM-PORT-OPTION subcommands and
// their values) live in rfc2217.cpp alone; the users see typed settings.
//
// Hostile input is bounded: a subnegotiation longer than
// kMaxSubnegotiation bytes is dropped whole, unknown commands and options
// are refused or ignored, and no input makes the parser allocate more than
// that bound beyond the data it passes through.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "wiretape/port.hpp"

namespace wiretape::detail::rfc2217 {

// The modem inputs RFC 2217 reports (NOTIFY-MODEMSTATE's upper bits).
struct ModemLines {
  bool cts = false;
  bool dsr = false;
  bool ri = false;
  bool cd = false;
  bool operator==(const ModemLines& other) const {
    return cts == other.cts && dsr == other.dsr && ri == other.ri && cd == other.cd;
  }
  bool operator!=(const ModemLines& other) const { return !(*this == other); }
};

// The line state RFC 2217 reports (NOTIFY-LINESTATE).
struct LineState {
  bool timeout = false;
  bool shift_register_empty = false;
  bool holding_register_empty = false;
  bool break_detected = false;
  bool framing_error = false;
  bool parity_error = false;
  bool overrun_error = false;
  bool data_ready = false;
};

enum class StopBits { one, two, one_and_a_half };

constexpr std::size_t kMaxSubnegotiation = 64;

// What both sides share: the Telnet reader (data, IAC IAC, negotiations,
// subnegotiations) and the negotiation of the three options RFC 2217 uses
// (BINARY, SUPPRESS-GO-AHEAD, COM-PORT-OPTION), each side's agreement kept
// apart (ours: WILL/WONT; theirs: DO/DONT), every other option refused.
class TelnetSession {
 public:
  virtual ~TelnetSession() = default;
  // Data for the peer, with IAC doubled.
  static void escape(const void* data, std::size_t size, std::string& out);

 protected:
  enum OptionIndex { kBinary, kSga, kComPort, kOptionCount };

  // Feeds bytes from the peer: data (IAC IAC unescaped) is appended to
  // `data_out`, Telnet answers to `answers`.
  void feed(const void* data, std::size_t size, std::string& data_out, std::string& answers);
  // Offers to use `option` on our side (WILL) or asks the peer to use it on
  // theirs (DO), once.
  void offer_ours(OptionIndex option, std::string& out);
  void ask_theirs(OptionIndex option, std::string& out);
  // IAC SB COM-PORT-OPTION <code> <value, escaped> IAC SE.
  static void com_port_command(std::uint8_t code, const std::string& value, std::string& out);

  // A subnegotiation of COM-PORT-OPTION, without its option byte: the
  // command code, then its value.
  virtual void com_port_subnegotiation(std::uint8_t code, const std::string& value,
                                       std::string& out) = 0;
  // Called after every negotiation the peer sent.
  virtual void after_negotiation(std::string& /*out*/) {}
  // Called before a COM-PORT-OPTION command is taken, with the data of this
  // feed() that came before it.
  virtual void before_com_port_command(std::string& /*data_out*/) {}

  bool ours(OptionIndex option) const { return we_[option]; }
  bool theirs(OptionIndex option) const { return they_[option]; }
  // The peer answered an offer or a request of ours for `option` with
  // DONT or WONT.
  bool refused(OptionIndex option) const { return refused_[option]; }
  // How many Telnet commands (IAC followed by anything but IAC) arrived.
  std::uint64_t telnet_commands() const { return telnet_commands_; }

 private:
  enum class State { data, iac, negotiate, subnegotiation, subnegotiation_iac };
  static int option_index(std::uint8_t option);
  void negotiate(std::uint8_t command, std::uint8_t option, std::string& out);
  void subnegotiation(std::string& data_out, std::string& out);

  State state_ = State::data;
  std::uint8_t negotiation_command_ = 0;
  std::string sub_;
  bool sub_overflow_ = false;
  // Options enabled on our side (WILL) and the peer's (DO), our pending
  // offers (so an answer to them is not answered again), and refusals.
  bool we_[kOptionCount] = {};
  bool they_[kOptionCount] = {};
  bool we_offered_[kOptionCount] = {};
  bool they_offered_[kOptionCount] = {};
  bool refused_[kOptionCount] = {};
  std::uint64_t telnet_commands_ = 0;
};

// What a server session asks of the device, in the line's own terms. Each
// setter receives what the client asked for (nullopt when it only asks what
// is in effect, or sent a value it has no meaning for) and returns what is
// in effect now, which the client is told.
class ComPort {
 public:
  virtual ~ComPort() = default;
  virtual std::uint32_t set_baud(std::optional<std::uint32_t> baud) = 0;
  virtual int set_data_bits(std::optional<int> bits) = 0;
  virtual Parity set_parity(std::optional<Parity> parity) = 0;
  virtual StopBits set_stop_bits(std::optional<StopBits> stop_bits) = 0;
  virtual FlowControl set_flow_control(std::optional<FlowControl> flow) = 0;
  virtual bool set_break(std::optional<bool> on) = 0;
  virtual bool set_dtr(std::optional<bool> on) = 0;
  virtual bool set_rts(std::optional<bool> on) = 0;
  // Drops data the server holds: what came from the device and is not yet
  // sent to the client, and/or what is waiting to be written to the device.
  virtual void purge(bool from_device, bool for_device) = 0;
  virtual ModemLines modem_lines() = 0;
  virtual LineState line_state() = 0;
};

class ServerSession final : public TelnetSession {
 public:
  explicit ServerSession(ComPort& port) : port_(port) {}

  // What the server sends first: it offers BINARY both ways.
  std::string greeting();
  // Feeds bytes from the client: data for the device is appended to
  // `to_device` (IAC IAC unescaped), answers to `to_client`.
  void receive(const void* data, std::size_t size, std::string& to_device,
               std::string& to_client) {
    feed(data, size, to_device, to_client);
  }
  // A NOTIFY-MODEMSTATE with the device's current modem state, for a
  // change the server noticed; empty until COM-PORT-OPTION is agreed.
  std::string modem_state_notification();
  // Where data that came before a COM-PORT command in the same receive()
  // goes before the command is applied (the sink sends it to the device
  // and clears it), so that the device gets the bytes and the settings in
  // the client's order. Without a sink, receive() returns all the data
  // after taking every command.
  void set_device_data_sink(std::function<void(std::string&)> sink) {
    device_data_sink_ = std::move(sink);
  }

  // The client asked the server to stop sending data (FLOWCONTROL-SUSPEND).
  bool suspended() const { return suspended_; }
  // The client agreed to COM-PORT-OPTION on either side: it speaks RFC 2217.
  bool com_port_active() const { return ours(kComPort) || theirs(kComPort); }

 private:
  void com_port_subnegotiation(std::uint8_t code, const std::string& value,
                               std::string& out) override;
  void after_negotiation(std::string& out) override;
  void before_com_port_command(std::string& data_out) override;
  void reply(std::uint8_t command, const std::string& value, std::string& out);

  ComPort& port_;
  std::function<void(std::string&)> device_data_sink_;
  bool announced_ = false;
  bool suspended_ = false;
  std::uint8_t linestate_mask_ = 0;
  std::uint8_t modemstate_mask_ = 0xff;
};

// The answers a client waits for, one counter each: a request is answered
// once its counter moved past the value it had when the request was sent.
enum class Answer { baud, data_size, parity, stop_size, control, purge, modem_mask, count };

// What the server said is in effect, and its notifications.
struct ServerState {
  std::optional<std::uint32_t> baud;
  std::optional<int> data_bits;
  std::optional<Parity> parity;
  std::optional<StopBits> stop_bits;
  std::optional<FlowControl> flow;
  std::optional<bool> break_on;
  std::optional<bool> dtr;
  std::optional<bool> rts;
  std::optional<ModemLines> modem_lines;  // from the last NOTIFY-MODEMSTATE
  std::optional<LineState> line_state;    // from the last NOTIFY-LINESTATE
  std::uint64_t modem_notifications = 0;
  std::uint64_t line_notifications = 0;
};

class ClientSession final : public TelnetSession {
 public:
  // What the client sends first: BINARY and SUPPRESS-GO-AHEAD both ways,
  // and WILL COM-PORT-OPTION (RFC 2217: the client offers, the server
  // answers DO).
  std::string greeting();
  // Feeds bytes from the server: device data is appended to `data`
  // (IAC IAC unescaped), answers for the server to `to_server`.
  void receive(const void* bytes, std::size_t size, std::string& data, std::string& to_server) {
    feed(bytes, size, data, to_server);
  }

  // The server agreed to COM-PORT-OPTION (DO, or WILL on its side).
  bool com_port_agreed() const { return ours(kComPort) || theirs(kComPort); }
  // The server refused COM-PORT-OPTION (DONT/WONT): not an RFC 2217 server.
  bool com_port_refused() const { return refused(kComPort) && !com_port_agreed(); }
  // BINARY was agreed (or refused) both ways.
  bool binary_settled() const {
    return (ours(kBinary) || refused(kBinary)) && (theirs(kBinary) || refused(kBinary));
  }
  bool binary_refused() const { return refused(kBinary); }
  // Whether the server sent any Telnet command at all (a plain TCP port
  // sends none).
  bool heard_telnet() const { return telnet_commands() > 0; }

  // Requests, each a whole COM-PORT-OPTION subnegotiation.
  static std::string set_baud(std::uint32_t baud);
  static std::string set_data_bits(int bits);
  static std::string set_parity(Parity parity);
  static std::string set_stop_bits(StopBits stop_bits);
  static std::string set_flow_control(FlowControl flow);
  static std::string set_break(bool on);
  static std::string set_dtr(bool on);
  static std::string set_rts(bool on);
  // PURGE-DATA: the server's buffer of device data for us, and/or its
  // buffer of our data for the device.
  static std::string purge(bool from_device, bool for_device);
  static std::string set_modem_state_mask(std::uint8_t mask);
  // The request's name as RFC 2217 spells it, for errors.
  static const char* name_of(Answer answer);

  std::uint64_t answers(Answer answer) const {
    return answers_[static_cast<int>(answer)];
  }
  const ServerState& state() const { return state_; }

 private:
  void com_port_subnegotiation(std::uint8_t code, const std::string& value,
                               std::string& out) override;
  void control_answer(std::uint8_t value);

  ServerState state_;
  std::uint64_t answers_[static_cast<int>(Answer::count)] = {};
};

}  // namespace wiretape::detail::rfc2217
