// RFC 2217 (Telnet COM-PORT-CONTROL) server side, without any I/O: the
// bridge feeds it what a client sent and gets back the data for the device
// and the Telnet answers for the client. Kept free of sockets so that it can
// be fuzzed (fuzz/rfc2217_fuzz.cpp) and tested byte for byte.
//
// Hostile input is bounded: a subnegotiation longer than
// kMaxSubnegotiation bytes is dropped whole, unknown commands and options
// are refused or ignored, and no input makes the parser allocate more than
// that bound beyond the data it passes through.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace wiretape::detail::rfc2217 {

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

// RFC 2217 parity codes: 1 none, 2 odd, 3 even, 4 mark, 5 space.
// Stop size codes: 1 one, 2 two, 3 one and a half.
// SET-CONTROL values used here: 1 no flow control, 2 xon/xoff, 3 rts/cts,
// 5/6 break on/off, 8/9 DTR on/off, 11/12 RTS on/off; 0, 4, 7, 10 ask.
// Purge: 1 the server's receive buffer (data from the device), 2 its
// transmit buffer (data for the device), 3 both.
// Modem state bits: 0x80 CD, 0x40 RI, 0x20 DSR, 0x10 CTS.

// What a session asks of the device. Each setter receives the client's
// value (0 asks for the current one) and returns the value now in effect,
// which is what the client is told.
class ComPort {
 public:
  virtual ~ComPort() = default;
  virtual std::uint32_t set_baud(std::uint32_t baud) = 0;
  virtual std::uint8_t set_data_size(std::uint8_t bits) = 0;
  virtual std::uint8_t set_parity(std::uint8_t code) = 0;
  virtual std::uint8_t set_stop_size(std::uint8_t code) = 0;
  virtual std::uint8_t set_control(std::uint8_t value) = 0;
  virtual void purge(std::uint8_t which) = 0;
  virtual std::uint8_t modem_state() = 0;
  virtual std::uint8_t line_state() = 0;
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
