#include <cstdio>
#include <string>

#include "core/open_port.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"
#include "wiretape/port.hpp"

namespace wiretape {

namespace {

// flexiport spelled the access mode as a bare key.
Access take_access(Options& options) {
  std::string bare_choice;
  for (const char* bare : {"readonly", "writeonly", "readwrite"}) {
    if (!options.take_bool(bare, false)) continue;
    if (!bare_choice.empty() || options.has("access")) {
      throw OptionError(bare, std::string("option '") + bare +
                                  "' conflicts with another access mode; "
                                  "give one of access=, readonly, writeonly, "
                                  "readwrite");
    }
    bare_choice = bare;
  }
  if (!bare_choice.empty()) options.set("access", bare_choice);
  const std::string access = options.take_choice(
      "access", "readwrite", {"readwrite", "readonly", "writeonly"});
  if (access == "readonly") return Access::read_only;
  if (access == "writeonly") return Access::write_only;
  return Access::read_write;
}

}  // namespace

std::unique_ptr<Port> open_port(std::string_view text) {
  return open_port(Options::parse(text));
}

std::unique_ptr<Port> open_port(Options options) {
  const std::string given = options.to_string();
  std::string type = options.take_choice(
      "type", "",
      {"serial", "tcp", "udp", "pty", "loopback", "replay", "logreader",
       "seriallog", "tcplog", "udplog"});
  if (type.empty()) {
    throw OptionError("type",
                      "missing option 'type': say which port to open, one of "
                      "serial, tcp, udp, pty, loopback, replay (e.g. "
                      "\"type=serial,device=/dev/ttyUSB0\")");
  }
  if (type == "logreader") type = "replay";
  // flexiport's logging port types: the named port, recorded to `file`.
  if (type == "seriallog" || type == "tcplog" || type == "udplog") {
    type.resize(type.size() - 3);
    options.alias("file", "log");
  }

  const Timeout timeout = options.take_timeout("timeout", forever);
  const Access access = take_access(options);
  const int debug = static_cast<int>(options.take_int("debug", 0, 0, 3));

  detail::RecordingConfig recording;
  const auto log = options.take("log");
  const bool recorded = log.has_value();
  recording.flush_ms = static_cast<int>(options.take_int("flush_ms", 100, 1, 3'600'000));
  recording.fsync = options.take_bool("fsync", false);
  recording.raise_errors =
      options.take_choice("log_errors", "raise", {"raise", "warn"}) == "raise";
  recording.metadata = options.take_prefixed("meta_");

  if (recorded && log->empty()) {
    throw OptionError("log", "option 'log' needs a file name (log=FILE)");
  }

  std::unique_ptr<Port> port;
  if (type == "serial") port = detail::open_serial(options);
  else if (type == "tcp") port = detail::open_tcp(options);
  else if (type == "udp") port = detail::open_udp(options);
  else if (type == "pty") port = detail::open_pty(options);
  else if (type == "loopback") port = detail::open_loopback(options);
  else port = detail::open_replay(options);
  options.finish(type);

  port->set_timeout(timeout);
  port->set_access(access);
  if (debug > 0) {
    std::fprintf(stderr, "wiretape: opened %s\n", port->description().c_str());
  }
  if (recorded) {
    recording.path = *log;
    recording.options_text = given;
    recording.port_type = type;
    port = detail::record_port(std::move(port), std::move(recording));
  }
  return port;
}

}  // namespace wiretape
