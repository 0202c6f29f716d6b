// Client sessions of a virtual device (DESIGN.md section 12): a client's
// k-th connection is served the recording from its k-th recorded
// client_connect on, and nothing the device said while no client was
// connected.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "session/record_source.hpp"

namespace wiretape::detail {

// The bridge's rule for client sessions, read back from the recorded
// events: a `client_connect` of a controlling client while no session is
// open begins one (a read-only monitor's connect, role "monitor", or a
// second client's, is none); the `client_disconnect` of that client's peer
// ends it (a monitor's or another client's does not).
class ClientSessionTracker {
 public:
  enum class Change { none, began, ended };
  Change feed(RecordKind kind, std::string_view payload);
  bool open() const { return peer_.has_value(); }

 private:
  std::optional<std::string> peer_;
};

// The recorded time of the `k`-th (1-based) client session's connect, or
// nothing when the recording has fewer.
std::optional<std::uint64_t> find_client_connect(RecordSource& source, int k);

// Sources over what client session `k` is served: the records after the
// `k`-th session's client_connect, up to the client_disconnect that ends it
// (what comes after was said to nobody, or to the next client).
RecordSourceFactory client_session_sources(RecordSourceFactory sources, int k);

// The number of client sessions the recording holds.
int count_client_sessions(RecordSource& source);

// match=request (DESIGN.md section 12: connection order is free): sources
// over client session `k`'s records, then over every other client
// session's, in recorded order, each from the `client_connect` record that
// began it to the `client_disconnect` that ended it; what was said to
// nobody is left out. The records are numbered in
// that order by whoever reads them, the same each time.
RecordSourceFactory sessions_first_sources(RecordSourceFactory sources, int k);

}  // namespace wiretape::detail
