// Fuzzes the RFC 2217 (Telnet COM-PORT-CONTROL) sessions, the server's and
// the client's (type=rfc2217): any bytes a peer sends must be parsed without
// crashing, with bounded output and state. The first byte picks where the input is split in two calls, so that
// every parser state is also crossed between reads.
#include <cstdint>
#include <cstdlib>
#include <optional>
#include <string>

#include "core/rfc2217.hpp"

namespace {

using wiretape::FlowControl;
using wiretape::Parity;
using namespace wiretape::detail::rfc2217;

// A device that takes every setting, as a serial port would.
class FakeComPort final : public ComPort {
 public:
  std::uint32_t set_baud(std::optional<std::uint32_t> baud) override {
    if (baud) baud_ = *baud;
    return baud_;
  }
  int set_data_bits(std::optional<int> bits) override {
    if (bits && (*bits < 5 || *bits > 8)) std::abort();  // the session filters these
    if (bits) bits_ = *bits;
    return bits_;
  }
  Parity set_parity(std::optional<Parity> parity) override {
    if (parity) parity_ = *parity;
    return parity_;
  }
  StopBits set_stop_bits(std::optional<StopBits> stop_bits) override {
    if (stop_bits) stop_ = *stop_bits;
    return stop_;
  }
  FlowControl set_flow_control(std::optional<FlowControl> flow) override {
    if (flow) flow_ = *flow;
    return flow_;
  }
  bool set_break(std::optional<bool> on) override { return on.value_or(false); }
  bool set_dtr(std::optional<bool> on) override { return on.value_or(true); }
  bool set_rts(std::optional<bool> on) override { return on.value_or(true); }
  void purge(bool from_device, bool for_device) override {
    if (!from_device && !for_device) std::abort();  // the session filters these
  }
  ModemLines modem_lines() override { return {}; }
  LineState line_state() override { return {}; }

 private:
  std::uint32_t baud_ = 9600;
  int bits_ = 8;
  Parity parity_ = Parity::none;
  StopBits stop_ = StopBits::one;
  FlowControl flow_ = FlowControl::none;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using wiretape::detail::rfc2217::ClientSession;
  using wiretape::detail::rfc2217::ServerSession;
  if (size == 0) return 0;
  const std::size_t rest = size - 1;
  const std::size_t split = rest * data[0] / 0xFF;
  FakeComPort port;
  ServerSession session(port);
  std::string to_device;
  std::string to_client = session.greeting();
  const std::size_t greeting = to_client.size();
  session.receive(data + 1, split, to_device, to_client);
  session.receive(data + 1 + split, rest - split, to_device, to_client);
  // Data never grows on its way to the device.
  if (to_device.size() > rest) std::abort();
  // Each input byte answers with a bounded amount (a negotiation answer of
  // 3 bytes, or an escaped 4-byte reply of at most 16 bytes per 3 input
  // bytes), plus one modem-state announcement.
  if (to_client.size() > greeting + 16 * rest + 16) std::abort();

  // The client session, fed the same bytes as a server's: its data never
  // grows, and it answers at most a refusal (3 bytes) per negotiation.
  ClientSession client;
  std::string data_out;
  std::string to_server = client.greeting();
  const std::size_t client_greeting = to_server.size();
  client.receive(data + 1, split, data_out, to_server);
  client.receive(data + 1 + split, rest - split, data_out, to_server);
  if (data_out.size() > rest) std::abort();
  if (to_server.size() > client_greeting + rest) std::abort();

  // Device data escaped for the client reads back unchanged.
  std::string escaped;
  ServerSession::escape(data, size, escaped);
  FakeComPort other_port;
  ServerSession reader(other_port);
  std::string unescaped;
  std::string answers;
  reader.receive(escaped.data(), escaped.size(), unescaped, answers);
  if (unescaped != std::string(reinterpret_cast<const char*>(data), size)) std::abort();
  if (!answers.empty()) std::abort();
  return 0;
}
