// The header of a .wtape file: its metadata JSON, written and parsed (the
// fixed bytes around it are in session/format.hpp).
#pragma once

#include <cstdint>
#include <string>

#include "wiretape/session.hpp"

namespace wiretape::detail {

// The header JSON of a session file.
std::string header_json(const SessionWriterOptions& options);
// Parses the header JSON into `header` (metadata_json included); throws
// SessionError(offset) naming `path` when it is not valid.
void parse_header_json(const std::string& json, const std::string& path,
                       std::uint64_t offset, SessionHeader& header);
// Now, as 2026-11-23T10:00:00.123456Z.
std::string utc_now_iso8601();
// The header's spelling of `capture`: "client" or "wire".
const char* capture_name(Capture capture);

}  // namespace wiretape::detail
