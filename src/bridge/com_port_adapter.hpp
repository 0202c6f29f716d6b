// RFC 2217's view of the device: what a Telnet COM-PORT client may read and
// change, carried out on the bridge's device side. A controlling client
// changes the line; a monitor (--shared) cannot change it.
//
// A monitor's requests are acknowledged with what it asked for and kept as
// that monitor's own view of the line, never applied: RFC 2217 clients
// (pyserial's among them) take an answer that differs from their request as
// a refusal and fail to open, and a monitor opens with settings of its own.
#pragma once

#include <optional>

#include "bridge/device_side.hpp"
#include "core/rfc2217.hpp"

namespace wiretape::detail::bridge {

class ComPortAdapter final : public rfc2217::ComPort {
 public:
  ComPortAdapter(DeviceSide& device, bool control) : device_(device), control_(control) {}

  std::uint32_t set_baud(std::optional<std::uint32_t> baud) override;
  int set_data_bits(std::optional<int> bits) override;
  Parity set_parity(std::optional<Parity> parity) override;
  rfc2217::StopBits set_stop_bits(std::optional<rfc2217::StopBits> stop_bits) override;
  FlowControl set_flow_control(std::optional<FlowControl> flow) override;
  bool set_break(std::optional<bool> on) override;
  bool set_dtr(std::optional<bool> on) override;
  bool set_rts(std::optional<bool> on) override;
  void purge(bool from_device, bool for_device) override;
  rfc2217::ModemLines modem_lines() override;
  rfc2217::LineState line_state() override { return {}; }

 private:
  // A monitor's line: what it asked for, starting from the device's.
  struct OwnLine {
    SerialSettings settings;
    bool dtr = true;
    bool rts = true;
    bool break_on = false;
  };

  // Whether this client's requests change the device.
  bool acts() const { return control_ && device_.is_open(); }
  OwnLine& own_line();
  // The settings this client is told are in effect.
  SerialSettings settings();
  template <typename Change>
  void change_settings(Change change);
  bool set_output(ModemOutput line, std::optional<bool> on);

  DeviceSide& device_;
  bool control_;
  std::optional<OwnLine> own_line_;  // monitors only, from their first request
};

}  // namespace wiretape::detail::bridge
