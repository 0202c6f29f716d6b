// The record kinds of a .wtape file and the payload schema of each event:
// the one table the writers, the readers, the Python bindings and
// docs/session-format.md ("Record kinds", "Event payloads") all follow.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

#include "wiretape/session.hpp"

namespace wiretape::detail {

// The member names of event payloads, spelled here once. Every writer of an
// event payload names its members by these constants.
namespace event_field {
inline constexpr char description[] = "description";
inline constexpr char reopened[] = "reopened";
inline constexpr char restarted[] = "restarted";
inline constexpr char baud[] = "baud";
inline constexpr char databits[] = "databits";
inline constexpr char stopbits[] = "stopbits";
inline constexpr char parity[] = "parity";
inline constexpr char flow[] = "flow";
inline constexpr char applied[] = "applied";
inline constexpr char source[] = "source";
inline constexpr char dtr[] = "dtr";
inline constexpr char rts[] = "rts";
inline constexpr char cts[] = "cts";
inline constexpr char dsr[] = "dsr";
inline constexpr char ri[] = "ri";
inline constexpr char cd[] = "cd";
inline constexpr char duration_ms[] = "duration_ms";
inline constexpr char peer[] = "peer";
inline constexpr char role[] = "role";
inline constexpr char reason[] = "reason";
inline constexpr char error[] = "error";
inline constexpr char error_number[] = "errno";
inline constexpr char fault_kind[] = "kind";
inline constexpr char where[] = "where";
inline constexpr char detail[] = "detail";
inline constexpr char offset[] = "offset";
inline constexpr char length[] = "length";
inline constexpr char direction[] = "direction";
}  // namespace event_field

// The JSON type of an event payload member. Integers are JSON numbers
// without a fraction or exponent.
enum class JsonType { string, integer, boolean };
std::string_view to_string(JsonType type);

struct EventFieldSpec {
  std::string_view name;
  JsonType type;
  bool required;            // every writer writes it
  std::string_view meaning;  // one line, as in docs/session-format.md
};

struct RecordKindSpec {
  RecordKind kind;
  std::string_view name;  // as in files converted to text and in Python
  bool is_event;          // false: a direction (rx, tx), the payload is bytes
  std::string_view meaning;
  const EventFieldSpec* fields;  // the event payload's members, in writing order
  std::size_t field_count;

  std::uint8_t code() const { return static_cast<std::uint8_t>(kind); }
  const EventFieldSpec* begin() const { return fields; }
  const EventFieldSpec* end() const { return fields + field_count; }
};

// Every kind this version knows, in code order.
struct RecordKindTable {
  const RecordKindSpec* entries;
  std::size_t count;
  const RecordKindSpec* begin() const { return entries; }
  const RecordKindSpec* end() const { return entries + count; }
};
RecordKindTable record_kinds();

// The table's entry for `kind`, or nullptr for a kind this version does not
// know (read from a newer file).
const RecordKindSpec* find_record_kind(RecordKind kind);
// By name; "line_break" is accepted for "break".
const RecordKindSpec* find_record_kind(std::string_view name);

// The kinds' names joined by ", " (for error messages that list them).
std::string record_kind_names();

// Why `payload` does not follow the table's schema for `kind` (a member it
// lacks, has in the wrong type, or does not know; not a JSON object), or
// std::nullopt when it does. An empty payload stands for {}. Readers ignore
// unknown members; this check is strict so that the table stays complete.
std::optional<std::string> event_payload_problem(RecordKind kind, std::string_view payload);

// A member of an event payload being made: its name and value, of one of the
// table's JSON types (boolean, integer, string).
using EventValue = std::variant<bool, std::int64_t, std::string>;
using EventMembers = std::vector<std::pair<std::string, EventValue>>;

// The JSON payload of a `kind` event with `members`, in the table's writing
// order: the one maker of event payloads (C++ and, bound, Python). Throws
// std::invalid_argument naming the kind and the member when a member is not
// in the table, has the wrong type, is given twice or a required one is
// missing, or when `kind` is not an event.
std::string event_payload(RecordKind kind, const EventMembers& members);

// The device's modem inputs (DESIGN.md section 20), as a modem_lines event
// records them: all four together, read at one moment. A device whose lines
// were never recorded reads as a modem with the line up: CTS, DSR and CD
// asserted, RI not.
struct ModemInputs {
  bool cts = true;
  bool dsr = true;
  bool ri = false;
  bool cd = true;
  bool operator==(const ModemInputs& other) const {
    return cts == other.cts && dsr == other.dsr && ri == other.ri && cd == other.cd;
  }
  bool operator!=(const ModemInputs& other) const { return !(*this == other); }
};
std::string modem_inputs_payload(const ModemInputs& inputs);
// The device's inputs a modem_lines payload records, or nothing when it
// records only the host's outputs (dtr, rts). A member it lacks keeps the
// level of `before`.
std::optional<ModemInputs> modem_inputs_of(std::string_view payload, const ModemInputs& before);
// Whether a modem_lines payload records a change the host made (dtr, rts).
bool records_host_lines(std::string_view payload);

}  // namespace wiretape::detail
