// A SCIP 2.0 driver for Hokuyo URG/UTM laser scanners over any wiretape::Port
// (serial, tcp, replay...). One Driver owns the conversation on one port; it
// is not thread-safe.
//
// Wire rules this driver enforces (SCIP 2.0):
//   - every reply starts with the echo of the command, then a status line of
//     two characters and their sum, then data lines (each ending with its
//     own sum character), then an empty line;
//   - a sum is the low six bits of the byte sum of the line, plus 0x30;
//   - scan data is the concatenation of the data lines (at most 64
//     characters each), read in 2-, 3- or 4-character groups of 6 bits that
//     may straddle line breaks.
#pragma once

#include <chrono>
#include <cstdint>
#include <map>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "wiretape/port.hpp"

namespace hokuyo {

// The device's reply broke the protocol: wrong echo, wrong sum, a line that
// cannot be decoded, no reply in time. The message names the command.
class ProtocolError : public std::runtime_error {
 public:
  ProtocolError(std::string command, const std::string& what)
      : std::runtime_error(what), command_(std::move(command)) {}
  const std::string& command() const noexcept { return command_; }

 private:
  std::string command_;
};

// The device answered with a status that means failure (e.g. "10": laser
// off, "0E": command not understood, "50".."97": hardware fault).
class StatusError : public std::runtime_error {
 public:
  StatusError(std::string command, std::string status, const std::string& what)
      : std::runtime_error(what),
        command_(std::move(command)),
        status_(std::move(status)) {}
  const std::string& command() const noexcept { return command_; }
  const std::string& status() const noexcept { return status_; }
  bool hardware_fault() const;

 private:
  std::string command_;
  std::string status_;
};

// What VV reports.
struct VersionInfo {
  std::string vendor;
  std::string product;
  std::string firmware;
  std::string protocol;
  std::string serial;
};

// What PP reports.
struct SensorParameters {
  std::string model;       // "URG-04LX" (MODL up to the first '(')
  unsigned min_range_mm = 0;  // DMIN
  unsigned max_range_mm = 0;  // DMAX
  unsigned resolution = 0;    // ARES: steps in a full turn
  int first_step = 0;         // AMIN
  int last_step = 0;          // AMAX
  int front_step = 0;         // AFRT
  unsigned scan_rpm = 0;      // SCAN
};

enum class ScanMode { gd, gs, md, ms, me };
ScanMode parse_scan_mode(std::string_view text);  // std::invalid_argument
const char* scan_mode_command(ScanMode mode);     // "GD", "GS", ...

struct Scan {
  std::uint32_t timestamp_ms = 0;           // the device's 24-bit counter
  std::uint64_t timestamp_unwrapped_ms = 0;  // corrected for wrap-around
  int first = 0;
  int last = 0;
  int cluster = 1;
  std::vector<std::uint32_t> ranges;
  std::vector<std::uint32_t> intensities;  // ME only
  int remaining = -1;  // streams: the echo's remaining-scan counter
};

// One parsed reply: echo, status, data lines (sums checked and removed).
struct Reply {
  std::string echo;
  std::string status;
  std::vector<std::string> lines;
};

struct DriverOptions {
  // How long to wait for each line of a reply.
  std::chrono::milliseconds line_timeout{2000};
  // How long VV may stay silent before the SCIP 1.1 switch is tried.
  std::chrono::milliseconds probe_timeout{1000};
  // Test hook: corrupt the GD/GS start step by one so that a replay catches
  // the driver asking for something it did not record.
  bool inject_bug = false;
};

class Driver {
 public:
  explicit Driver(wiretape::Port& port, DriverOptions options = {});

  // VV. If VV gets no valid reply: QT (a device still streaming for an
  // earlier program), VV again, and only if that fails too SCIP2.0 (the
  // SCIP 1.1 switch) and VV.
  VersionInfo open();
  VersionInfo version();             // VV
  SensorParameters parameters();     // PP
  std::map<std::string, std::string> state();  // II
  void laser_on();                   // BM ("02" already on is fine)
  void laser_off();                  // QT
  void reset();                      // RS
  bool switched_from_scip1() const noexcept { return switched_from_scip1_; }

  // GD/GS: one scan.
  Scan get_scan(ScanMode mode, int first, int last, int cluster);
  // MD/MS/ME: a stream of `count` scans (0: until stopped).
  void start_stream(ScanMode mode, int first, int last, int cluster,
                    int interval, int count);
  Scan read_stream_scan();
  bool streaming() const noexcept { return streaming_; }
  void stop_stream();  // QT, discarding the scans still in flight

  // TM: time adjust mode.
  void enter_time_mode();   // TM0 ("02" already in it is fine)
  std::uint32_t device_time_ms();  // TM1
  void leave_time_mode();   // TM2 ("03" already out is fine)

  // After a broken or partial reply: QT, then discard everything up to the
  // QT reply and until the line is quiet.
  void recover();

  // The low-level exchange: writes `command` + LF and reads its reply.
  Reply transact(const std::string& command);

 private:
  std::string read_line(const std::string& command);
  // Discards input until none came for `quiet`, or `limit` passed.
  void drain_until_quiet(std::chrono::milliseconds quiet,
                         std::chrono::milliseconds limit);
  Reply read_reply(const std::string& command, bool echo_is_stream);
  void send(const std::string& command);
  void expect_status(const Reply& reply, std::initializer_list<const char*> ok);
  Scan decode_scan(const std::string& command, const Reply& reply, ScanMode mode,
                   int first, int last, int cluster, std::size_t first_line);
  std::uint64_t unwrap(std::uint32_t raw);

  wiretape::Port& port_;
  DriverOptions options_;
  bool switched_from_scip1_ = false;
  bool streaming_ = false;
  std::string stream_command_;  // without the scan count
  ScanMode stream_mode_ = ScanMode::md;
  int stream_first_ = 0, stream_last_ = 0, stream_cluster_ = 1;
  int stream_count_ = 0;
  int stream_expected_remaining_ = 0;
  bool have_timestamp_ = false;
  std::uint32_t last_timestamp_ = 0;
  std::uint64_t timestamp_wraps_ = 0;
};

// --- encoding helpers (public for tests and tools) ---------------------------
char checksum(std::string_view bytes);
// Decodes `digits` characters (2, 3 or 4) of SCIP's 6-bit encoding.
std::uint32_t decode(std::string_view text);
std::string encode(std::uint32_t value, int digits);
// Describes a status of `command` in words ("laser is off", ...).
std::string describe_status(std::string_view command, std::string_view status);

}  // namespace hokuyo
