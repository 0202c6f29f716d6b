// The port types open_port() knows, one row each (DESIGN.md section 25):
// the name `type=` gives, the constructor, and what the type's recordings
// are. A new transport is one row of port_types.cpp (and its keys, rows of
// the key table in src/core/option_keys.cpp, which names the types its keys
// apply to; tests/cpp/open/port_types_test.cpp holds the two lists equal).
//
// The folders below (replay above all) never see this table: what they need
// of it is passed down (datagram_port_types() into a replay's config).
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "wiretape/options.hpp"
#include "wiretape/port.hpp"

namespace wiretape::detail {

// What a port type is, as far as callers that hold only its name (the
// `port_type` of a recorded channel) need to know.
struct PortTypeCapabilities {
  // Records are the device's messages: their boundaries are kept, an empty
  // one is a message (udp). Otherwise a byte stream, cut where reads were.
  bool datagrams = false;
  // A serial line: modem lines, break and line settings, recorded and served.
  bool modem_lines = false;
};

struct PortType {
  std::string_view name;
  // Opens the port from the keys left once the common keys were taken.
  std::unique_ptr<Port> (*open)(Options& options);
  PortTypeCapabilities capabilities;
};

// flexiport's other spellings of `type=`.
struct PortTypeAlias {
  std::string_view name;  // logreader, seriallog, ...
  std::string_view type;  // the registered type it stands for
  // seriallog, tcplog, udplog: the type, recorded into `file` (log= by
  // flexiport's name); logreader is replay and nothing more.
  bool records_into_file = false;
};

// In the order `type=`'s help and errors list them.
const std::vector<PortType>& registered_port_types();
const std::vector<PortTypeAlias>& port_type_aliases();

// The row of a registered name (not an alias); nullptr when none is.
const PortType* find_port_type(std::string_view name);
// The alias `name`; nullptr when it is not one.
const PortTypeAlias* find_port_type_alias(std::string_view name);

// The registered names whose recordings are datagrams: what a replay and
// the segmentation are told (open_replay, segment_session_file).
std::vector<std::string> datagram_port_types();

// "serial, tcp, udp, pty, loopback, replay": for messages.
std::string registered_port_type_names();

}  // namespace wiretape::detail
