// The built-in profiles, each in a file of its own; profile.cpp lists them
// in the registry.
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <string_view>

#include "replay/profile.hpp"

namespace wiretape::detail {

// Hokuyo SCIP 2.0 laser scanners (scip.cpp).
std::shared_ptr<const Profile> make_scip_profile();

// Lines ending with `delimiter` (lines.cpp); OptionError (key "delimiter")
// for an empty one. The registry's `lines` ends them with LF.
std::shared_ptr<const Profile> make_lines_profile(std::string delimiter);
std::shared_ptr<const Profile> make_default_lines_profile();

// NMEA 0183 sentences (nmea.cpp).
std::shared_ptr<const Profile> make_nmea_profile();
// Serial-line CAN, LAWICEL (slcan.cpp).
std::shared_ptr<const Profile> make_slcan_profile();
// Modbus RTU and Modbus TCP (modbus.cpp).
std::shared_ptr<const Profile> make_modbus_rtu_profile();
std::shared_ptr<const Profile> make_modbus_tcp_profile();
// MAVLink v1 and v2 (mavlink.cpp).
std::shared_ptr<const Profile> make_mavlink_profile();

}  // namespace wiretape::detail
