// The bench's copy of the Hokuyo example driver's decoding (examples/hokuyo,
// the MD stream path of hokuyo-scan) with eight planted decoding bugs, for
// measuring how well a search finds them (bench/fuzz_bench.py,
// docs/fuzzing.md "Figures"). Never use it as a driver.
//
// Each bug is reached only by a device answer that differs from the
// recording, and each ends the program its own way, so that a run tells
// which one it hit: an abort whose last stderr line is
// "planted bug NAME: ...", a SIGFPE, or a hang. The names (planted_bugs
// below) are what the bench counts.
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "wiretape/port.hpp"

namespace planted {

// What each bug is, by the name its crash prints (the SIGFPE and the hang
// print nothing: the bench knows them by the signal and the timeout).
//   echo-length-off-by-one  a stream echo one byte too long passes the length
//                           check and overflows the echo buffer
//   status-unhandled        BM's status switch has no default
//   status-table-index      a failure status indexes a 100-entry table by its
//                           two characters, digits or not
//   count-unchecked         the steps to decode come from the echo's end
//                           step, never checked against the data's length
//   cluster-division        the echo's cluster divides unchecked (SIGFPE)
//   range-overflow          a range in sixteenths of a mm overflows 16 bits
//   frame-ends-early        II's data lines are taken from one read
//   missing-terminator      a scan's data lines are read until the empty
//                           line, waiting on at every silence (a hang)
inline const char* const planted_bugs[] = {
    "echo-length-off-by-one", "status-unhandled", "status-table-index", "count-unchecked",
    "cluster-division",       "range-overflow",   "frame-ends-early",   "missing-terminator"};

// The device broke the protocol in a way the driver noticed: a clean error.
class ProtocolError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Scan {
  std::uint32_t timestamp_ms = 0;
  std::vector<std::uint16_t> ranges;  // sixteenths of a millimetre
  int remaining = -1;
};

struct Reply {
  std::string echo;
  std::string status;
  std::vector<std::string> lines;
};

class Driver {
 public:
  Driver(wiretape::Port& port, std::chrono::milliseconds line_timeout);

  std::map<std::string, std::string> version();     // VV
  std::map<std::string, std::string> parameters();  // PP
  std::map<std::string, std::string> state();       // II
  void laser_on();                                  // BM
  void start_stream(int first, int last, int cluster, int count);  // MD
  Scan read_stream_scan();

 private:
  std::string read_line();
  Reply read_reply(const std::string& command, bool stream);
  Reply transact(const std::string& command);
  void expect_status(const Reply& reply, const char* ok);
  Scan decode_scan(const Reply& reply);

  wiretape::Port& port_;
  std::chrono::milliseconds line_timeout_;
  std::string stream_command_;
  int stream_expected_remaining_ = 0;
};

}  // namespace planted
