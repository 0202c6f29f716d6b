// hokuyo-scan: reads scans from a Hokuyo URG/UTM scanner through any
// wiretape port (a serial line, TCP, or a replayed recording).
//
// Exit codes: 0 ok; 1 a replayed session did not match what the driver did;
// 2 usage error (bad arguments or port options); 3 device or I/O error
// (no device, protocol error, error status).
#include <cstdio>
#include <cerrno>
#include <cstdlib>
#include <stdexcept>
#include <system_error>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "hokuyo/scip.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"

namespace {

constexpr const char* usage_text =
    "usage: hokuyo-scan --port OPTS [--first N] [--last N] [--cluster N]\n"
    "                   [--scans N] [--mode gd|gs|md|ms|me] [--json]\n"
    "                   [--timeout SECONDS]\n"
    "\n"
    "Reads scans from a Hokuyo laser scanner speaking SCIP 2.0.\n"
    "  --port OPTS   wiretape port options, e.g. type=serial,device=/dev/ttyACM0\n"
    "                or type=replay,file=scan.wtape; a bare path is a serial device\n"
    "  --first N     first step (default: the device's AMIN)\n"
    "  --last N      last step (default: the device's AMAX)\n"
    "  --cluster N   steps merged into one range, 1..99 (default 1)\n"
    "  --scans N     number of scans (default 1)\n"
    "  --mode M      gd (default), gs: one request per scan; md, ms, me: a stream\n"
    "  --json        one JSON object per scan on stdout\n"
    "  --timeout S   how long to wait for each reply line (default 2)\n"
    "  --retries N   broken replies to recover from (QT, then again) (default 2)\n"
    "Exit codes: 0 ok, 1 replay mismatch, 2 usage error, 3 device or I/O error.\n";

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct Arguments {
  std::string port;
  std::optional<int> first, last;
  int cluster = 1;
  int scans = 1;
  hokuyo::ScanMode mode = hokuyo::ScanMode::gd;
  bool json = false;
  double timeout_s = 2.0;
  int retries = 2;
  bool inject_bug = false;
};

int parse_int(const std::string& option, const std::string& text, int min, int max) {
  char* end = nullptr;
  errno = 0;
  const long value = std::strtol(text.c_str(), &end, 10);
  if (text.empty() || *end != '\0' || errno != 0 || value < min || value > max)
    throw UsageError(option + ": \"" + text + "\" is not a whole number in " +
                     std::to_string(min) + ".." + std::to_string(max));
  return static_cast<int>(value);
}

Arguments parse_arguments(int argc, char** argv) {
  Arguments args;
  bool have_port = false;
  for (int i = 1; i < argc; ++i) {
    const std::string option = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw UsageError(option + " needs a value");
      return argv[++i];
    };
    if (option == "--help" || option == "-h") {
      std::cout << usage_text;
      std::exit(0);
    } else if (option == "--port") {
      args.port = value();
      have_port = true;
    } else if (option == "--first") {
      args.first = parse_int(option, value(), 0, 9999);
    } else if (option == "--last") {
      args.last = parse_int(option, value(), 0, 9999);
    } else if (option == "--cluster") {
      args.cluster = parse_int(option, value(), 1, 99);
    } else if (option == "--scans") {
      args.scans = parse_int(option, value(), 1, 1000000);
    } else if (option == "--mode") {
      try {
        args.mode = hokuyo::parse_scan_mode(value());
      } catch (const std::invalid_argument& error) {
        throw UsageError(std::string("--mode: ") + error.what());
      }
    } else if (option == "--json") {
      args.json = true;
    } else if (option == "--timeout") {
      const std::string text = value();
      char* end = nullptr;
      args.timeout_s = std::strtod(text.c_str(), &end);
      if (text.empty() || *end != '\0' || !(args.timeout_s > 0) || args.timeout_s > 3600)
        throw UsageError("--timeout: \"" + text + "\" is not a number of seconds in (0, 3600]");
    } else if (option == "--retries") {
      args.retries = parse_int(option, value(), 0, 100);
    } else if (option == "--inject-bug") {
      // Hidden: a deliberately broken driver, for the replay tests.
      args.inject_bug = true;
    } else {
      throw UsageError("unknown argument \"" + option + "\"");
    }
  }
  if (!have_port || args.port.empty()) throw UsageError("--port is required");
  return args;
}

std::string json_string(const std::string& text) {
  std::string out = "\"";
  for (unsigned char c : text) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\t': out += "\\t"; break;
      default:
        if (c < 0x20 || c >= 0x7f) {
          char hex[8];
          std::snprintf(hex, sizeof hex, "\\u%04x", c);
          out += hex;
        } else {
          out += static_cast<char>(c);
        }
    }
  }
  return out + "\"";
}

void append_list(std::ostringstream& out, const std::vector<std::uint32_t>& values) {
  out << '[';
  for (std::size_t i = 0; i < values.size(); ++i) out << (i ? "," : "") << values[i];
  out << ']';
}

void print_scan(const Arguments& args, const std::string& model,
                const std::string& serial, const hokuyo::Scan& scan, int index) {
  std::ostringstream out;
  if (args.json) {
    out << "{\"model\":" << json_string(model) << ",\"serial\":" << json_string(serial)
        << ",\"timestamp_ms\":" << scan.timestamp_ms
        << ",\"timestamp_unwrapped_ms\":" << scan.timestamp_unwrapped_ms
        << ",\"first\":" << scan.first << ",\"last\":" << scan.last
        << ",\"cluster\":" << scan.cluster << ",\"ranges\":";
    append_list(out, scan.ranges);
    if (args.mode == hokuyo::ScanMode::me) {
      out << ",\"intensities\":";
      append_list(out, scan.intensities);
    }
    out << '}';
  } else {
    out << "scan " << index << ": " << model << " " << serial << " t=" << scan.timestamp_ms
        << " ms steps " << scan.first << ".." << scan.last << " cluster " << scan.cluster
        << ": " << scan.ranges.size() << " ranges, first";
    for (std::size_t i = 0; i < scan.ranges.size() && i < 5; ++i) {
      out << ' ' << scan.ranges[i];
      if (!scan.intensities.empty()) out << '/' << scan.intensities[i];
    }
  }
  std::cout << out.str() << std::endl;
}

int run(const Arguments& args) {
  std::string options = args.port;
  if (options.find('=') == std::string::npos) options = "type=serial,device=" + options;
  auto port = wiretape::open_port(options);

  hokuyo::DriverOptions driver_options;
  driver_options.line_timeout = std::chrono::milliseconds(
      static_cast<long long>(args.timeout_s * 1000));
  driver_options.probe_timeout = driver_options.line_timeout;
  driver_options.inject_bug = args.inject_bug;
  hokuyo::Driver driver(*port, driver_options);

  const hokuyo::VersionInfo version = driver.open();
  const hokuyo::SensorParameters params = driver.parameters();
  driver.state();
  driver.laser_on();

  const int first = args.first.value_or(params.first_step);
  const int last = args.last.value_or(params.last_step);
  if (first < params.first_step || first > params.last_step)
    throw UsageError("--first " + std::to_string(first) + " is outside the device's steps " +
                     std::to_string(params.first_step) + ".." + std::to_string(params.last_step));
  if (last < first || last > params.last_step)
    throw UsageError("--last " + std::to_string(last) + " must be in " + std::to_string(first) +
                     ".." + std::to_string(params.last_step));

  // A broken reply (wrong sum, garbage, a cut-off line) is survived up to
  // --retries times: QT and drain, laser on again, then carry on.
  int retries_left = args.retries;
  auto recover = [&](const hokuyo::ProtocolError& error) {
    if (retries_left-- <= 0) throw;
    std::cerr << "hokuyo-scan: " << error.what() << "; recovering with QT\n";
    driver.recover();
    driver.laser_on();
  };

  if (args.mode == hokuyo::ScanMode::gd || args.mode == hokuyo::ScanMode::gs) {
    for (int i = 0; i < args.scans;) {
      try {
        print_scan(args, params.model, version.serial,
                   driver.get_scan(args.mode, first, last, args.cluster), i + 1);
        ++i;
      } catch (const hokuyo::ProtocolError& error) {
        recover(error);
      }
    }
    return 0;
  }
  // Streams: a count the device can hold, else "until stopped" and QT.
  const int interval = args.mode == hokuyo::ScanMode::me ? 1 : 0;
  auto start = [&](int scans_left) {
    driver.start_stream(args.mode, first, last, args.cluster, interval,
                        scans_left <= 99 ? scans_left : 0);
  };
  start(args.scans);
  for (int i = 0; i < args.scans;) {
    try {
      print_scan(args, params.model, version.serial, driver.read_stream_scan(), i + 1);
      ++i;
    } catch (const hokuyo::ProtocolError& error) {
      recover(error);
      start(args.scans - i);
    }
  }
  if (driver.streaming()) driver.stop_stream();
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Arguments args;
  try {
    args = parse_arguments(argc, argv);
    return run(args);
  } catch (const UsageError& error) {
    std::cerr << "hokuyo-scan: " << error.what() << "\n(--help for usage)\n";
    return 2;
  } catch (const wiretape::OptionError& error) {
    std::cerr << "hokuyo-scan: --port: " << error.what() << "\n";
    return 2;
  } catch (const wiretape::ReplayMismatch& error) {
    std::cerr << "hokuyo-scan: the driver's requests differ from the recording:\n"
              << error.what() << "\n";
    return 1;
  } catch (const hokuyo::StatusError& error) {
    std::cerr << "hokuyo-scan: " << error.what() << "\n";
    return 3;
  } catch (const hokuyo::ProtocolError& error) {
    std::cerr << "hokuyo-scan: protocol error: " << error.what() << "\n";
    return 3;
  } catch (const wiretape::PortClosed& error) {
    std::cerr << "hokuyo-scan: the device went away: " << error.what() << "\n";
    return 3;
  } catch (const std::system_error& error) {
    std::cerr << "hokuyo-scan: " << error.what() << "\n";
    return 3;
  } catch (const std::exception& error) {
    std::cerr << "hokuyo-scan: " << error.what() << "\n";
    return 3;
  }
}
