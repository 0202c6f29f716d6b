// Placeholder until the transport lands.
#include <cerrno>

#include "detail/open.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

std::unique_ptr<Port> open_loopback(Options&) {
  throw PortError(ENOSYS, "open_loopback: not built yet");
}

}  // namespace wiretape::detail
