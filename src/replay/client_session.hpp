// Client sessions of a virtual device (DESIGN.md section 12): a client's
// k-th connection is served the recording from its k-th recorded
// client_connect on, and nothing the device said while no client was
// connected.
#pragma once

#include <cstdint>
#include <optional>

#include "session/record_source.hpp"

namespace wiretape::detail {

// The recorded time of the `k`-th (1-based) client_connect of a controlling
// client (monitors do not count), or nothing when the recording has fewer.
std::optional<std::uint64_t> find_client_connect(RecordSource& source, int k);

// Sources over what client session `k` is served: the records after the
// `k`-th client_connect, up to the client_disconnect that follows it (what
// comes after was said to nobody, or to the next client).
RecordSourceFactory client_session_sources(RecordSourceFactory sources, int k);

}  // namespace wiretape::detail
