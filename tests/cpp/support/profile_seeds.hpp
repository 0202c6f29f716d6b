// Two valid rx frames for each built-in profile, for the fuzzing tests'
// property over every profile. Header-only.
#pragma once

#include <string>
#include <vector>

#include "wiretape/profile.hpp"

namespace wiretape::test {

// A recorded device side for `profile`, two frames of it, made valid by the
// profile's own checksum rule (a checksum field left zero here).
inline std::vector<std::string> profile_seed_frames(const Profile& profile) {
  const std::string name(profile.name());
  std::vector<std::string> frames;
  if (name == "scip") frames = {"VV\n00P\nVEND:Hokuyo;[\n\n", "MD0044072501001\n00P\n\n"};
  else if (name == "nmea") frames = {"$GPGGA,1,2*00\r\n", "$GPRMC,3*00\r\n"};
  else if (name == "slcan") frames = {"t1232AABB\r", "z\r"};
  else if (name == "modbus-rtu") frames = {std::string("\x01\x03\x04\x00\x01\x00\x02\x00\x00", 9),
                                           std::string("\x01\x06\x00\x01\x00\x03\x00\x00", 8)};
  else if (name == "modbus-tcp") frames = {std::string("\x00\x01\x00\x00\x00\x05\x01\x03\x02\x00\x2a", 11),
                                           std::string("\x00\x02\x00\x00\x00\x05\x01\x03\x02\x00\x2b", 11)};
  else if (name == "mavlink")
    frames = {std::string("\xfe\x09\x00\x01\x01\x00\x00\x00\x00\x00\x02\x03\x51\x04\x03\x00\x00", 17),
              std::string("\xfe\x09\x01\x01\x01\x00\x00\x00\x00\x00\x02\x03\x51\x04\x03\x00\x00", 17)};
  else frames = {"OK\r\n", "READY\r\n"};
  for (std::string& frame : frames) frame = profile.recompute_checksums(StreamDirection::rx, frame);
  return frames;
}

}  // namespace wiretape::test
