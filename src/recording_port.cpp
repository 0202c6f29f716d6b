// Placeholder until recording lands.
#include <cerrno>

#include "detail/open.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

std::unique_ptr<Port> record_port(std::unique_ptr<Port>, RecordingConfig) {
  throw PortError(ENOSYS, "recording: not built yet");
}

}  // namespace wiretape::detail
