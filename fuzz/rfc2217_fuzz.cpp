// Fuzzes the RFC 2217 (Telnet COM-PORT-CONTROL) server session: any bytes a
// client sends must be parsed without crashing, with bounded output and
// state. The first byte picks where the input is split in two calls, so that
// every parser state is also crossed between reads.
#include <cstdint>
#include <cstdlib>
#include <string>

#include "bridge/rfc2217.hpp"

namespace {

// A device that takes every setting, as a serial port would.
class FakeComPort final : public wiretape::detail::rfc2217::ComPort {
 public:
  std::uint32_t set_baud(std::uint32_t baud) override {
    if (baud != 0) baud_ = baud;
    return baud_;
  }
  std::uint8_t set_data_size(std::uint8_t bits) override {
    if (bits >= 5 && bits <= 8) bits_ = bits;
    return bits_;
  }
  std::uint8_t set_parity(std::uint8_t code) override {
    if (code >= 1 && code <= 5) parity_ = code;
    return parity_;
  }
  std::uint8_t set_stop_size(std::uint8_t code) override {
    if (code == 1 || code == 2) stop_ = code;
    return stop_;
  }
  std::uint8_t set_control(std::uint8_t value) override { return value; }
  void purge(std::uint8_t which) override {
    if (which < 1 || which > 3) std::abort();  // the session filters these
  }
  std::uint8_t modem_state() override { return 0x30; }
  std::uint8_t line_state() override { return 0; }

 private:
  std::uint32_t baud_ = 9600;
  std::uint8_t bits_ = 8, parity_ = 1, stop_ = 1;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
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
