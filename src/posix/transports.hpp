// The constructors of the port types that are operating-system transports.
// open_port() (src/open_port.cpp) calls them once the common keys have been
// taken; each reads the keys of its type through the key table.
#pragma once

#include <memory>

#include "wiretape/options.hpp"
#include "wiretape/port.hpp"

namespace wiretape::detail {

std::unique_ptr<Port> open_serial(Options& options);
std::unique_ptr<Port> open_tcp(Options& options);
std::unique_ptr<Port> open_udp(Options& options);
std::unique_ptr<Port> open_pty(Options& options);

}  // namespace wiretape::detail
