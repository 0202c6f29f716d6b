// planted-scan: the planted driver (planted_scip.hpp) as a program, for
// `wiretape fuzz` and `wiretape faults` to run: VV, PP, II, BM, then an MD
// stream of --scans scans of steps 44..725 in clusters of 3 (what
// `hokuyo-scan --mode md --cluster 3` asks a URG-04LX for).
//
// Exit codes as hokuyo-scan's: 0 ok; 1 the driver's requests differ from a
// replayed recording; 2 usage error; 3 device or I/O error.
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <string>

#include "planted_scip.hpp"
#include "wiretape/errors.hpp"

int main(int argc, char** argv) {
  std::string port_options;
  int scans = 1;
  double timeout_s = 2.0;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string option = argv[i];
    if (option == "--port") {
      port_options = argv[i + 1];
    } else if (option == "--scans") {
      scans = std::atoi(argv[i + 1]);
    } else if (option == "--timeout") {
      timeout_s = std::atof(argv[i + 1]);
    } else {
      std::cerr << "planted-scan: unknown argument \"" << option << "\"\n";
      return 2;
    }
  }
  if (argc % 2 == 0 || port_options.empty() || scans < 1 || scans > 99 || !(timeout_s > 0)) {
    std::cerr << "usage: planted-scan --port OPTS [--scans 1..99] [--timeout SECONDS]\n";
    return 2;
  }
  if (port_options.find('=') == std::string::npos) port_options = "type=serial,device=" + port_options;
  try {
    auto port = wiretape::open_port(port_options);
    planted::Driver driver(*port, std::chrono::milliseconds(static_cast<long long>(timeout_s * 1000)));
    driver.version();
    driver.parameters();
    driver.state();
    driver.laser_on();
    driver.start_stream(44, 725, 3, scans);
    for (int i = 0; i < scans; ++i) {
      const planted::Scan scan = driver.read_stream_scan();
      std::cout << "scan " << i + 1 << ": t=" << scan.timestamp_ms << " ms, " << scan.ranges.size()
                << " ranges\n";
    }
    return 0;
  } catch (const wiretape::OptionError& error) {
    std::cerr << "planted-scan: --port: " << error.what() << "\n";
    return 2;
  } catch (const wiretape::ReplayMismatch& error) {
    std::cerr << "planted-scan: the driver's requests differ from the recording:\n" << error.what() << "\n";
    return 1;
  } catch (const std::exception& error) {
    std::cerr << "planted-scan: " << error.what() << "\n";
    return 3;
  }
}
