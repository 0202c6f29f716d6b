// Ports that wrap or fake others: the loopback port and the recorder behind
// `log=FILE`. open_port() (src/open/open_port.cpp) makes them.
#pragma once

#include <map>
#include <memory>
#include <string>
#include <string_view>

#include "wiretape/options.hpp"
#include "wiretape/port.hpp"
#include "wiretape/recorder.hpp"
#include "wiretape/session.hpp"

namespace wiretape::detail {

std::unique_ptr<Port> open_loopback(Options& options);

// What `log=FILE` asks for: a recording of the port into a session file.
struct RecordingConfig {
  std::string path;
  std::string options_text;  // the option string as the user gave it
  std::string port_type;
  int flush_ms = 100;
  bool fsync = false;
  bool compress = false;     // compress=zstd
  bool raise_errors = true;  // log_errors=raise (else warn on stderr)
  std::map<std::string, std::string> metadata;  // meta_KEY=VALUE
};

// How a recorded port treats the channel it records into.
struct RecordingTarget {
  // The port's close closes the file (log=): its errors are the port's.
  bool owns_file = true;
  bool raise_errors = true;  // log_errors=raise (else warn on stderr)
  // This port's open is the recorder's time 0 (its first channel).
  bool opens_the_clock = true;
};

// Wraps `inner` so that everything crossing it is recorded (capture=client)
// into a new session file of one unnamed channel (log=FILE). A replay's
// injected faults are recorded too, as `fault` events.
std::unique_ptr<Port> record_port(std::unique_ptr<Port> inner,
                                  RecordingConfig config);
// The same into `channel` of a file (a Recorder's port; log= is this with a
// file of its own).
std::unique_ptr<Port> record_port_into(std::unique_ptr<Port> inner, RecordingChannel channel,
                                       RecordingTarget target);

}  // namespace wiretape::detail
