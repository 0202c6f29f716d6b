// Fuzzes the Hokuyo example driver's decoding (examples/hokuyo, what
// hokuyo-scan --mode md --scans 3 --cluster 3 does after the probe) from its
// recording: each input is a fuzzing plan (docs/fuzzing.md) over the SCIP
// frames of examples/hokuyo/recordings/urg04lx_md.wtape, played through a
// replayed port (include/wiretape/fuzzing.hpp). A mutated reply must end in
// one of the driver's errors (ProtocolError, StatusError) or wiretape's
// (a replay mismatch when the driver reacts with a request the recording
// does not hold, PortClosed at the recording's end); a crash, a sanitizer
// report or any other exception is a finding.
//
// Built twice: hokuyo_scan_fuzz over urg04lx_md.wtape (3 scans: 8 answers),
// and, with WIRETAPE_BENCH, bench's hokuyo_scan20_fuzz over
// bench/planted/urg04lx_md15.wtape (15 scans: 20 answers), the figure of
// DESIGN §27 for a 20-exchange session (bench/fuzz_bench.py).
//
// The probe (Driver::open) is left out: on a reply it cannot read it waits
// for the line to go quiet, 100 ms a time, and the decoding is the same
// version() that the probe calls first.
#include <chrono>
#include <cstdint>
#include <string>

#include "hokuyo/scip.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/fuzzing.hpp"

#ifndef HOKUYO_FUZZ_RECORDING
#define HOKUYO_FUZZ_RECORDING HOKUYO_RECORDINGS_DIR "/urg04lx_md.wtape"
#endif
#ifndef HOKUYO_FUZZ_SCANS
#define HOKUYO_FUZZ_SCANS 3
#endif

namespace {

constexpr int recorded_scans = HOKUYO_FUZZ_SCANS;

const wiretape::FuzzedReplay& recording() {
  static const wiretape::FuzzedReplay replay(HOKUYO_FUZZ_RECORDING, "scip");
  return replay;
}

void run_driver(wiretape::Port& port) {
  hokuyo::DriverOptions options;
  // The replay releases each reply as its request is written (timing=none,
  // in this thread): a line not there at once never comes, so the driver
  // need not wait long for it (each run that waits costs this).
  options.line_timeout = std::chrono::milliseconds(1);
  options.probe_timeout = options.line_timeout;
  hokuyo::Driver driver(port, options);
  driver.version();
  driver.parameters();
  driver.state();
  driver.laser_on();
  driver.start_stream(hokuyo::ScanMode::md, 44, 725, 3, 0, recorded_scans);
  for (int scan = 0; scan < recorded_scans; ++scan) driver.read_stream_scan();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  auto port = recording().open(data, size);
  // The empty plan is the recording unchanged: the driver must read it
  // whole, or the target is not reaching the decoding it means to fuzz.
  const auto refused = [size] {
    if (size == 0) throw;
  };
  try {
    run_driver(*port);
  } catch (const hokuyo::ProtocolError&) {
    refused();
  } catch (const hokuyo::StatusError&) {
    refused();
  } catch (const wiretape::ReplayMismatch&) {
    refused();
  } catch (const wiretape::PortError&) {  // PortClosed at the recording's end
    refused();
  }
  return 0;
}
