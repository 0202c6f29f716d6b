// The replaying port over any record source (tests feed synthetic sessions).
#pragma once

#include <memory>

#include "replay/record_source.hpp"
#include "replay/replay_config.hpp"
#include "wiretape/port.hpp"

namespace wiretape::detail {

std::unique_ptr<Port> open_replay_session(ReplayConfig config,
                                          RecordSourceFactory sources);

}  // namespace wiretape::detail
