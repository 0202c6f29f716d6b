// The session reader's private side: the record source behind
// wiretape::SessionReader, for the replay engine, which reads large payloads
// as views (RecordSource::next(record, view)) instead of copies.
#pragma once

#include <memory>
#include <string>

#include "session/record_source.hpp"
#include "wiretape/session.hpp"

namespace wiretape::detail {

// The records of a .wtape file or a flexiport log pair ("name.log"), and its
// header into `header`. Throws PortError when a file cannot be opened or is
// not a regular file, SessionError when it is not a usable session; damage
// later on ends the records and is reported by damage().
std::unique_ptr<RecordSource> open_session_source(const std::string& path,
                                                  SessionHeader& header);

}  // namespace wiretape::detail
