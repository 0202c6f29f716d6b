// flexiport's two-file logs (docs/session-format.md, "flexiport's logs"):
// the importer behind the session reader. Export is wiretape::export_flexiport.
#pragma once

#include <memory>
#include <optional>
#include <string>

#include "session/record_source.hpp"
#include "wiretape/session.hpp"

namespace wiretape::detail {

// flexiport's logs: `prefix` is "name.log" for name.logr + name.logw. Throws
// PortError when one cannot be opened or is not a regular file, SessionError
// when one is missing or not a flexiport log.
std::unique_ptr<RecordSource> open_flexiport(const std::string& prefix,
                                             SessionHeader& header);
// The "name.log" prefix `path` names when it is a flexiport log ("name.log",
// "name.logr" or "name.logw" with the pair on disk), else std::nullopt.
std::optional<std::string> flexiport_prefix(const std::string& path);

}  // namespace wiretape::detail
