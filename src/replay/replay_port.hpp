// The replaying port over any record source (tests feed synthetic sessions).
#pragma once

#include <functional>

#include <memory>
#include <string>
#include <vector>

#include "replay/faults.hpp"
#include "session/record_source.hpp"
#include "replay/replay_config.hpp"
#include "wiretape/port.hpp"

namespace wiretape::detail {

// In replay_session_file.cpp: sources over the records of channel `channel`
// of the session file at `path` (.wtape or flexiport log pair).
RecordSourceFactory session_source_factory(const std::string& path,
                                           std::uint16_t channel = 0);

// The channel of `header` that `config` replays (channel=, DESIGN.md section
// 19). Throws OptionError naming `channel` when it is missing on a file of
// several channels, or names none of the file's.
Channel choose_channel(const ReplayConfig& config, const SessionHeader& header);

std::unique_ptr<Port> open_replay_session(ReplayConfig config,
                                          RecordSourceFactory sources);
// The recorded port types whose records are datagrams (udp), as the
// port-type registry above says (detail::datagram_port_types() in
// src/open/port_types.hpp): replay is told, it knows no port type.
using DatagramPortTypes = std::vector<std::string>;
// Whether `channel` was recorded from a port of one of `datagram_types`.
bool recorded_as_datagrams(const Channel& channel, const DatagramPortTypes& datagram_types);

// The line settings a recorded port's options open it with: the serial keys
// they give, a serial port's defaults for the others (and for options that
// do not parse: the header's text is not the replay's to refuse).
SerialSettings recorded_line_settings(const std::string& port_options);

// The replay keys of `options` and what the session file they name says
// (its channel, datagrams, line settings, the channel's faults): what
// open_replay plays the file's records with. Throws as open_replay does.
ReplayConfig replay_file_config(Options& options, const DatagramPortTypes& datagram_types);

// type=replay for open_port() (src/open/port_types.cpp): the replay keys of
// `options`, then the session file they name.
std::unique_ptr<Port> open_replay(Options& options, const DatagramPortTypes& datagram_types);

// True when `port` is a replay whose recording has nothing more for the
// client to read (at_end=silent): a read without a timeout would raise
// PortClosed. For callers that wait in slices (the Python binding), which
// would otherwise wait forever. False for every other port.
bool replay_read_would_block_forever(Port& port);

// True when `port` is a replay whose recording holds any rx (data the
// device sent): a client served none of it was not given the device. False
// for every other port.
bool replay_recording_has_rx(const Port& port);

// A virtual device's client flushed (its input, with the dropped bytes
// delivered again, or its output): rx the recording shows after a recorded
// client flush is entitled once the client has made as many. No-op for
// other ports.
void replay_client_flushed(Port& port);

// True when `port` is a replay whose first client session begins with rx
// before any tx (a greeting). False for every other port.
bool replay_recording_greets(const Port& port);

// Client sessions of a virtual device (DESIGN.md section 12). When `port`
// is a replay, holds back everything until the next client session begins
// (a bridge calls it at open and when its client leaves) and returns true;
// false for every other port.
bool replay_await_client(Port& port);
// When `port` is a replay, starts the next client session now and returns
// true if it starts afresh (at the recording's next client_connect, or at
// its start for the first): whatever was queued for an earlier client is
// not this client's. False for every other port.
bool replay_begin_client_session(Port& port);

// A replay's injected faults (faults=) reach whoever wraps it through
// report_faults_to (core/fault_hook.hpp): a replay is a FaultSource.
// Whether a replay's reads fail because of an injected disconnect or
// reconnect (not a recorded loss).
bool replay_lost_by_fault(Port& port);
// The injected silence (faults=) after which the replay answers nothing, as
// KIND@WHERE; empty when none fired, and for every other port.
std::string replay_silenced_by_fault(Port& port);

}  // namespace wiretape::detail
