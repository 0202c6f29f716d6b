// The planted driver (planted_scip.hpp) fuzzed in process from its
// recording (include/wiretape/fuzzing.hpp): each input is a plan over the
// SCIP frames of bench/planted/urg04lx_md15.wtape (VV, PP, II, BM, MD and
// 15 scans: 20 device answers). A clean driver error or wiretape's replay
// errors end a run; a planted bug aborts it (the hang cannot happen here: a
// read past the recording's end raises PortClosed at once).
#include <chrono>
#include <cstdint>

#include "planted_scip.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/fuzzing.hpp"

namespace {

constexpr int recorded_scans = 15;

const wiretape::FuzzedReplay& recording() {
  static const wiretape::FuzzedReplay replay(PLANTED_RECORDING, "scip");
  return replay;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  auto port = recording().open(data, size);
  try {
    // timing=none: a reply not there at once never comes.
    planted::Driver driver(*port, std::chrono::milliseconds(1));
    driver.version();
    driver.parameters();
    driver.state();
    driver.laser_on();
    driver.start_stream(44, 725, 3, recorded_scans);
    for (int i = 0; i < recorded_scans; ++i) driver.read_stream_scan();
  } catch (const planted::ProtocolError&) {
    if (size == 0) throw;  // the recording unchanged must be read whole
  } catch (const wiretape::ReplayMismatch&) {
    if (size == 0) throw;
  } catch (const wiretape::PortError&) {
    if (size == 0) throw;
  }
  return 0;
}
