#include "bridge/com_port_adapter.hpp"

namespace wiretape::detail::bridge {

ComPortAdapter::OwnLine& ComPortAdapter::own_line() {
  if (!own_line_) {
    OwnLine line;
    line.settings = device_.current_settings();
    line.dtr = device_.output_level(ModemOutput::dtr);
    line.rts = device_.output_level(ModemOutput::rts);
    line.break_on = device_.break_on();
    own_line_ = line;
  }
  return *own_line_;
}

SerialSettings ComPortAdapter::settings() {
  return control_ ? device_.current_settings() : own_line().settings;
}

template <typename Change>
void ComPortAdapter::change_settings(Change change) {
  if (!control_) {
    change(own_line().settings);
    return;
  }
  if (!acts()) return;
  SerialSettings target = device_.current_settings();
  change(target);
  device_.apply_settings(target, "rfc2217");
}

std::uint32_t ComPortAdapter::set_baud(std::optional<std::uint32_t> baud) {
  if (baud) change_settings([&](SerialSettings& s) { s.baud = *baud; });
  return settings().baud;
}

int ComPortAdapter::set_data_bits(std::optional<int> bits) {
  if (bits) change_settings([&](SerialSettings& s) { s.data_bits = *bits; });
  return settings().data_bits;
}

Parity ComPortAdapter::set_parity(std::optional<Parity> parity) {
  if (parity) change_settings([&](SerialSettings& s) { s.parity = *parity; });
  return settings().parity;
}

rfc2217::StopBits ComPortAdapter::set_stop_bits(std::optional<rfc2217::StopBits> stop_bits) {
  // One and a half stop bits have no termios equivalent: refused.
  if (stop_bits && *stop_bits != rfc2217::StopBits::one_and_a_half) {
    change_settings([&](SerialSettings& s) {
      s.stop_bits = *stop_bits == rfc2217::StopBits::two ? 2 : 1;
    });
  }
  return settings().stop_bits == 2 ? rfc2217::StopBits::two : rfc2217::StopBits::one;
}

FlowControl ComPortAdapter::set_flow_control(std::optional<FlowControl> flow) {
  if (flow) change_settings([&](SerialSettings& s) { s.flow = *flow; });
  return settings().flow;
}

bool ComPortAdapter::set_break(std::optional<bool> on) {
  if (!control_) {
    if (on) own_line().break_on = *on;
    return own_line().break_on;
  }
  if (!on) return device_.break_on();
  if (acts()) {
    if (*on) device_.start_break();
    else device_.end_break();
  }
  return *on ? device_.break_on() : false;
}

bool ComPortAdapter::set_output(ModemOutput line, std::optional<bool> on) {
  if (!control_) {
    bool& level = line == ModemOutput::dtr ? own_line().dtr : own_line().rts;
    if (on) level = *on;
    return level;
  }
  if (on && acts()) device_.set_output_level(line, *on);
  return device_.output_level(line);
}

bool ComPortAdapter::set_dtr(std::optional<bool> on) { return set_output(ModemOutput::dtr, on); }
bool ComPortAdapter::set_rts(std::optional<bool> on) { return set_output(ModemOutput::rts, on); }

void ComPortAdapter::purge(bool from_device, bool for_device) {
  if (acts()) device_.purge(from_device, for_device);
}

rfc2217::ModemLines ComPortAdapter::modem_lines() {
  rfc2217::ModemLines lines;
  if (!device_.is_open()) return lines;
  if (const auto inputs = device_.modem_inputs()) {
    lines.cts = inputs->cts;
    lines.dsr = inputs->dsr;
    lines.ri = inputs->ri;
    lines.cd = inputs->cd;
  }
  return lines;
}

}  // namespace wiretape::detail::bridge
