// The port-type registry (port_types.hpp): one row per type.
#include "open/port_types.hpp"

#include "ports/ports.hpp"
#include "posix/transports.hpp"
#include "replay/replay_port.hpp"

namespace wiretape::detail {

namespace {

std::unique_ptr<Port> open_replay_of_registered_types(Options& options) {
  return open_replay(options, datagram_port_types());
}

}  // namespace

const std::vector<PortType>& registered_port_types() {
  static const std::vector<PortType> types = {
      {"serial", open_serial, {/*datagrams=*/false, /*modem_lines=*/true}},
      {"tcp", open_tcp, {}},
      {"udp", open_udp, {/*datagrams=*/true, /*modem_lines=*/false}},
      {"pty", open_pty, {}},
      {"loopback", open_loopback, {}},
      // What a replay serves is its recording's: datagrams when the
      // recorded channel's type is one of datagram_port_types().
      {"replay", open_replay_of_registered_types, {}},
      // A serial line over the network: recorded as a serial port's.
      {"rfc2217", open_rfc2217, {/*datagrams=*/false, /*modem_lines=*/true}},
  };
  return types;
}

const std::vector<PortTypeAlias>& port_type_aliases() {
  static const std::vector<PortTypeAlias> aliases = {
      {"logreader", "replay", /*records_into_file=*/false},
      {"seriallog", "serial", /*records_into_file=*/true},
      {"tcplog", "tcp", /*records_into_file=*/true},
      {"udplog", "udp", /*records_into_file=*/true},
  };
  return aliases;
}

const PortType* find_port_type(std::string_view name) {
  for (const PortType& type : registered_port_types()) {
    if (type.name == name) return &type;
  }
  return nullptr;
}

const PortTypeAlias* find_port_type_alias(std::string_view name) {
  for (const PortTypeAlias& alias : port_type_aliases()) {
    if (alias.name == name) return &alias;
  }
  return nullptr;
}

std::vector<std::string> datagram_port_types() {
  std::vector<std::string> names;
  for (const PortType& type : registered_port_types()) {
    if (type.capabilities.datagrams) names.emplace_back(type.name);
  }
  return names;
}

std::string registered_port_type_names() {
  std::string names;
  for (const PortType& type : registered_port_types()) {
    if (!names.empty()) names += ", ";
    names += type.name;
  }
  return names;
}

}  // namespace wiretape::detail
