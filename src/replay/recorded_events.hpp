// The client's settings, line changes and breaks as match=sequence checks
// them against the recorded events one by one (docs/replay.md, "Events" and
// "Modem lines and break"): what a recorded event says, whether the client's
// matches it, and how a mismatch report names both.
#pragma once

#include <map>
#include <optional>
#include <string>

#include "session/record_kinds.hpp"
#include "wiretape/session.hpp"

namespace wiretape::detail {

// An event's JSON members as text (baud -> "115200", dtr -> "true").
using EventFields = std::map<std::string, std::string>;

// What the client did, as the port was told it.
struct ClientEvent {
  RecordKind kind = RecordKind::settings;
  EventFields fields;
};

bool is_line_event(RecordKind kind);

// The members of a recorded event's payload, less the proxy's own note
// (`applied`); none for a payload that is not JSON.
EventFields recorded_fields(const Record& record);

// An event in words: "DTR low", "DTR low, RTS high", "a break",
// "settings {"baud":115200}".
std::string event_text(RecordKind kind, const EventFields& fields);
std::string recorded_event_text(const Record& record);

// Whether the client's event is the recorded one: the same kind, and every
// member both name equal (set_baud matches a recorded full configuration
// with that rate); a modem_lines event changes the same lines. A break's
// length is compared only when `compare_break_length` (check=timing: it is
// the client's timing).
bool event_matches(const Record& recorded, const ClientEvent& made, bool compare_break_length);

// The report's lines for an event mismatch: the recorded event expected
// there (none: the recording has none) and the client's (none: it made
// none).
std::string event_mismatch_lines(const std::optional<Record>& expected,
                                 const std::optional<ClientEvent>& made);

}  // namespace wiretape::detail
