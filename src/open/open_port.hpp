// The factory that opens every port type (open_port() in port.hpp) through
// the registry (port_types.hpp). It stands above the folders of the port
// types, so that src/core/ depends on nothing above it (DESIGN.md sections
// 18 and 25); this header gathers the port types' constructors for the
// callers that make ports by hand (tests).
#pragma once

#include <string_view>

#include "ports/ports.hpp"
#include "posix/transports.hpp"
#include "replay/replay_port.hpp"

namespace wiretape::detail {

// Checks the option string of a replay as open_port() would, and opens
// nothing (not even the session file): the syntax, the common keys, every
// replay key and the keys' dependencies. Throws OptionError naming the key.
// For callers that must refuse bad keys before any side effect of their own
// (the CLI's replay, before it listens or makes a pty).
void check_replay_options(std::string_view options);

// Whether the replay key speed= has anything to scale in a replay of these
// keys: its clock (timing=session|causal) or the waits of its injected
// faults (delay, stall, trickle, reconnect). The rule open_port() refuses
// a useless speed= by; `wiretape replay --speed K -- CMD` asks it whether
// K goes to the replay too, or to CMD's clock alone.
bool replay_speed_applies(std::string_view options);

}  // namespace wiretape::detail
