#include "replay/recorded_events.hpp"

#include "util/json.hpp"

namespace wiretape::detail {

namespace {

std::string member_text(const json::Value& value) {
  switch (value.type) {
    case json::Value::Type::boolean:
      return value.boolean ? "true" : "false";
    case json::Value::Type::number:
    case json::Value::Type::string:
      return value.text;
    default:
      return json::serialize(value);
  }
}

std::string fields_json(const EventFields& fields) {
  std::string text = "{";
  for (const auto& [key, value] : fields) {
    if (text.size() > 1) text += ",";
    const bool bare = value == "true" || value == "false" ||
                      (!value.empty() &&
                       value.find_first_not_of("-0123456789.") == std::string::npos);
    text += json::quote(key) + ":" + (bare ? value : json::quote(value));
  }
  return text + "}";
}

}  // namespace

bool is_line_event(RecordKind kind) {
  return kind == RecordKind::modem_lines || kind == RecordKind::line_break;
}

EventFields recorded_fields(const Record& record) {
  EventFields fields;
  try {
    const json::Value value = json::parse(record.data.empty() ? "{}" : record.data);
    for (const auto& [key, member] : value.members) {
      if (key == event_field::applied) continue;  // the proxy's note, not the client's doing
      fields[key] = member_text(member);
    }
  } catch (const json::ParseError&) {
  }
  return fields;
}

std::string event_text(RecordKind kind, const EventFields& fields) {
  if (kind == RecordKind::line_break) return "a break";
  if (kind == RecordKind::modem_lines) {
    std::string text;
    for (const char* line : {event_field::dtr, event_field::rts}) {
      const auto level = fields.find(line);
      if (level == fields.end()) continue;
      if (!text.empty()) text += ", ";
      for (const char* c = line; *c != '\0'; ++c) text += static_cast<char>(*c - 'a' + 'A');
      text += level->second == "true" ? " high" : " low";
    }
    if (!text.empty()) return text;
  }
  return std::string(to_string(kind)) + " " + fields_json(fields);
}

std::string recorded_event_text(const Record& record) {
  EventFields fields = recorded_fields(record);
  fields.erase(event_field::source);  // who made it, not what it was
  return event_text(record.kind, fields);
}

bool event_matches(const Record& recorded, const ClientEvent& made, bool compare_break_length) {
  if (recorded.kind != made.kind) return false;
  const EventFields recorded_members = recorded_fields(recorded);
  for (const auto& [key, text] : made.fields) {
    if (key == event_field::duration_ms && !compare_break_length) continue;
    const auto member = recorded_members.find(key);
    if (member != recorded_members.end() && member->second != text) return false;
  }
  // A line the recording changed that the client did not, or the reverse.
  if (made.kind == RecordKind::modem_lines) {
    for (const char* name : {event_field::dtr, event_field::rts}) {
      if (recorded_members.count(name) != made.fields.count(name)) return false;
    }
  }
  return true;
}

std::string event_mismatch_lines(const std::optional<Record>& expected,
                                 const std::optional<ClientEvent>& made) {
  // "line change" where both are line changes (or one is none), as the
  // docs show a missing pulse; "event" where settings are involved.
  const bool lines = (!expected || is_line_event(expected->kind)) &&
                     (!made || is_line_event(made->kind));
  const std::string noun = lines ? "line change" : "event";
  return "  expected " + noun + ": " +
         (expected ? recorded_event_text(*expected) : std::string("(none)")) + "\n" +
         "  actual " + noun + ":   " +
         (made ? event_text(made->kind, made->fields) : std::string("(none)")) + "\n";
}

}  // namespace wiretape::detail
