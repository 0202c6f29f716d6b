// RFC 2217 (Telnet COM-PORT-CONTROL) server side, without any I/O: the
// bridge feeds it what a client sent and gets back the data for the device
// and the Telnet answers for the client. Kept free of sockets so that it can
// be fuzzed (fuzz/rfc2217_fuzz.cpp) and tested byte for byte.
//
// The protocol's codes (Telnet commands, COM-PORT-OPTION subcommands and
// their values) live in rfc2217.cpp alone; the bridge sees typed settings.
//
// Hostile input is bounded: a subnegotiation longer than
// kMaxSubnegotiation bytes is dropped whole, unknown commands and options
// are refused or ignored, and no input makes the parser allocate more than
// that bound beyond the data it passes through.
#pragma once

#include <cstddef>
#include <cstdint>
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

// What a session asks of the device, in the line's own terms: the protocol's
// codes never leave this module. Each setter receives what the client asked
// for (nullopt when it only asks what is in effect, or sent a value it has no
// meaning for) and returns what is in effect now, which the client is told.
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

constexpr std::size_t kMaxSubnegotiation = 64;

class ServerSession {
 public:
  explicit ServerSession(ComPort& port) : port_(port) {}

  // What the server sends first: it offers BINARY both ways.
  std::string greeting();
  // Feeds bytes from the client: data for the device is appended to
  // `to_device` (IAC IAC unescaped), answers to `to_client`.
  void receive(const void* data, std::size_t size, std::string& to_device,
               std::string& to_client);
  // Device data for the client, with IAC doubled.
  static void escape(const void* data, std::size_t size, std::string& out);
  // A NOTIFY-MODEMSTATE with the device's current modem state, for a
  // change the server noticed; empty until COM-PORT-OPTION is agreed.
  std::string modem_state_notification();

  // The client asked the server to stop sending data (FLOWCONTROL-SUSPEND).
  bool suspended() const { return suspended_; }
  // The client agreed to COM-PORT-OPTION on either side: it speaks RFC 2217.
  bool com_port_active() const { return we_[kComPort] || they_[kComPort]; }

 private:
  enum class State { data, iac, negotiate, subnegotiation, subnegotiation_iac };
  enum OptionIndex { kBinary, kSga, kComPort, kOptionCount };

  static int option_index(std::uint8_t option);
  void negotiate(std::uint8_t command, std::uint8_t option, std::string& out);
  void subnegotiation(std::string& out);
  void reply(std::uint8_t command, const std::string& value, std::string& out);
  void maybe_announce(std::string& out);

  ComPort& port_;
  State state_ = State::data;
  std::uint8_t negotiation_command_ = 0;
  std::string sub_;
  bool sub_overflow_ = false;
  // Options enabled on our side (WILL) and the client's (DO), and our
  // pending offers (so an answer to them is not answered again).
  bool we_[kOptionCount] = {};
  bool they_[kOptionCount] = {};
  bool we_offered_[kOptionCount] = {};
  bool they_offered_[kOptionCount] = {};
  bool announced_ = false;
  bool suspended_ = false;
  std::uint8_t linestate_mask_ = 0;
  std::uint8_t modemstate_mask_ = 0xff;
};

}  // namespace wiretape::detail::rfc2217
