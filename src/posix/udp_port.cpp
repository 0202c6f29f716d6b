// Placeholder until the transport lands.
#include <cerrno>

#include "detail/open.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

std::unique_ptr<Port> open_udp(Options&) {
  throw PortError(ENOSYS, "open_udp: not built yet");
}

}  // namespace wiretape::detail
