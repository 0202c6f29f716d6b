#include "session/record_kinds.hpp"

#include <array>
#include <iterator>
#include <stdexcept>

#include "util/json.hpp"

namespace wiretape {
namespace detail {

namespace {

namespace f = event_field;
constexpr JsonType string = JsonType::string;
constexpr JsonType integer = JsonType::integer;
constexpr JsonType boolean = JsonType::boolean;
constexpr bool required = true;
constexpr bool optional = false;

constexpr EventFieldSpec open_fields[] = {
    {f::description, string, required,
     "the device as its port describes itself, e.g. serial /dev/ttyUSB0 @ 115200 8N1"},
    {f::reopened, boolean, optional,
     "true: the proxy opened the device again after it went away"},
    {f::restarted, boolean, optional,
     "true: the proxy closed and reopened the device for a new client"},
};
constexpr EventFieldSpec settings_fields[] = {
    {f::baud, integer, required, "bits per second"},
    {f::databits, integer, optional, "5 to 8 (after configure)"},
    {f::stopbits, integer, optional, "1 or 2 (after configure)"},
    {f::parity, string, optional, "none, even, odd, mark or space (after configure)"},
    {f::flow, string, optional, "none, rtscts or xonxoff (after configure)"},
    {f::applied, boolean, optional,
     "proxy: false when the device has no line settings and only the client's view changed"},
    {f::source, string, optional,
     "proxy: who asked, rfc2217 or client's terminal settings"},
};
constexpr EventFieldSpec modem_lines_fields[] = {
    {f::dtr, boolean, optional, "the host's output: the level DTR was set to"},
    {f::rts, boolean, optional, "the host's output: the level RTS was set to"},
    {f::applied, boolean, optional, "proxy: false when the device has no modem lines"},
    {f::cts, boolean, optional,
     "the device's input CTS as read (1.2; cts, dsr, ri, cd come together)"},
    {f::dsr, boolean, optional, "the device's input DSR as read (1.2)"},
    {f::ri, boolean, optional, "the device's input RI as read (1.2)"},
    {f::cd, boolean, optional, "the device's input CD (DCD) as read (1.2)"},
};
constexpr EventFieldSpec break_fields[] = {
    {f::duration_ms, integer, required, "how long the break lasted, in milliseconds"},
    {f::applied, boolean, optional, "proxy: false when the device cannot send a break"},
};
constexpr EventFieldSpec client_connect_fields[] = {
    {f::peer, string, required, "the client: host:port for TCP, pty for a terminal"},
    {f::role, string, required, "control (may write and set the line) or monitor (reads only)"},
};
constexpr EventFieldSpec client_disconnect_fields[] = {
    {f::peer, string, optional, "the client, as in its client_connect"},
    {f::reason, string, optional, "why it went away, e.g. closed the connection"},
};
constexpr EventFieldSpec device_lost_fields[] = {
    {f::error, string, required, "what the port reported"},
    {f::error_number, integer, optional, "the errno, when there was one (library recording)"},
};

constexpr EventFieldSpec fault_fields[] = {
    {f::fault_kind, string, required, "the fault, as in faults=: drop:3, corrupt, disconnect, ..."},
    {f::where, string, required, "where it was asked for: exchange:N, rx:N, t:SECONDS, every:K, p:P"},
    {f::detail, string, optional, "what it did, e.g. flipped bit 3 of rx byte 120"},
};
constexpr EventFieldSpec redaction_fields[] = {
    {f::offset, integer, required, "the first scrubbed byte, from the start of the next rx or tx record"},
    {f::length, integer, required, "how many bytes were scrubbed; replay matches them as wildcards"},
};
constexpr EventFieldSpec capture_gap_fields[] = {
    {f::direction, string, required, "rx or tx: the direction whose bytes the capture lost"},
    {f::offset, integer, required, "the first lost byte, counted from the start of that direction"},
    {f::length, integer, required, "how many bytes were lost; none of them is in a record"},
};

template <std::size_t n>
constexpr RecordKindSpec event(RecordKind kind, std::string_view name, std::string_view meaning,
                               const EventFieldSpec (&fields)[n]) {
  return {kind, name, true, meaning, fields, n};
}
constexpr RecordKindSpec event(RecordKind kind, std::string_view name,
                               std::string_view meaning) {
  return {kind, name, true, meaning, nullptr, 0};
}
constexpr RecordKindSpec direction(RecordKind kind, std::string_view name,
                                   std::string_view meaning) {
  return {kind, name, false, meaning, nullptr, 0};
}

constexpr RecordKindSpec kinds[] = {
    direction(RecordKind::rx, "rx", "bytes from the device to the host"),
    direction(RecordKind::tx, "tx", "bytes from the host to the device"),
    event(RecordKind::open, "open", "the device was opened; the first is at t_ns 0",
          open_fields),
    event(RecordKind::close, "close", "the port was closed"),
    event(RecordKind::flush_input, "flush_input", "received, unread data was dropped"),
    event(RecordKind::flush_output, "flush_output", "written, unsent data was dropped"),
    event(RecordKind::drain, "drain", "the host waited for written data to leave"),
    event(RecordKind::settings, "settings",
          "the line settings changed: set_baud gives baud alone, configure all of them",
          settings_fields),
    event(RecordKind::modem_lines, "modem_lines",
          "the host set a modem line (dtr or rts), or the device's lines changed (cts, dsr, ri, cd)",
          modem_lines_fields),
    event(RecordKind::line_break, "break", "the host sent a break", break_fields),
    event(RecordKind::client_connect, "client_connect",
          "a client connected to the proxy or virtual device", client_connect_fields),
    event(RecordKind::client_disconnect, "client_disconnect", "a client went away",
          client_disconnect_fields),
    event(RecordKind::device_lost, "device_lost",
          "the device went away (EOF, ENXIO, ECONNRESET); replays as PortClosed here",
          device_lost_fields),
    event(RecordKind::fault, "fault",
          "replay injected a fault here (a recorded faulty replay); replay ignores it",
          fault_fields),
    event(RecordKind::redaction, "redaction",
          "bytes of the next rx or tx record were scrubbed by wiretape edit --redact",
          redaction_fields),
    event(RecordKind::capture_gap, "capture_gap",
          "an imported packet capture lost bytes here (convert --from pcap --allow-gaps)",
          capture_gap_fields),
};

bool is_integer(const json::Value& value) {
  return value.type == json::Value::Type::number &&
         value.text.find_first_of(".eE") == std::string::npos;
}

bool has_type(const json::Value& value, JsonType type) {
  switch (type) {
    case JsonType::string: return value.type == json::Value::Type::string;
    case JsonType::integer: return is_integer(value);
    case JsonType::boolean: return value.type == json::Value::Type::boolean;
  }
  return false;
}

}  // namespace

std::string_view to_string(JsonType type) {
  switch (type) {
    case JsonType::string: return "string";
    case JsonType::integer: return "integer";
    case JsonType::boolean: return "boolean";
  }
  return "unknown";
}

RecordKindTable record_kinds() { return {kinds, std::size(kinds)}; }

const RecordKindSpec* find_record_kind(RecordKind kind) {
  // Asked for every record a reader reads: a lookup by code, not a search.
  static const auto by_code = [] {
    std::array<const RecordKindSpec*, 256> table{};
    for (const RecordKindSpec& spec : kinds) table[spec.code()] = &spec;
    return table;
  }();
  return by_code[static_cast<std::uint8_t>(kind)];
}

const RecordKindSpec* find_record_kind(std::string_view name) {
  // The C++ enumerator's name, for those who spell it that way.
  if (name == "line_break") return find_record_kind(RecordKind::line_break);
  for (const RecordKindSpec& spec : kinds) {
    if (spec.name == name) return &spec;
  }
  return nullptr;
}

std::string record_kind_names() {
  std::string names;
  for (const RecordKindSpec& spec : kinds) {
    if (!names.empty()) names += ", ";
    names += spec.name;
  }
  return names;
}

std::optional<std::string> event_payload_problem(RecordKind kind, std::string_view payload) {
  const RecordKindSpec* spec = find_record_kind(kind);
  if (spec == nullptr) return "unknown record kind " + std::to_string(static_cast<int>(kind));
  const std::string name(spec->name);
  if (!spec->is_event) return name + " is a direction, its payload is bytes";
  json::Value root;
  try {
    root = json::parse(payload.empty() ? std::string_view("{}") : payload);
  } catch (const json::ParseError& e) {
    return name + " payload is not JSON: " + e.what() + " at byte " +
           std::to_string(e.offset());
  }
  if (!root.is_object()) return name + " payload is not a JSON object";
  for (const EventFieldSpec& field : *spec) {
    const json::Value* member = root.find(field.name);
    if (member == nullptr) {
      if (field.required) return name + " payload lacks \"" + std::string(field.name) + "\"";
      continue;
    }
    if (!has_type(*member, field.type)) {
      return name + " payload member \"" + std::string(field.name) + "\" is not a " +
             std::string(to_string(field.type)) + ": " + json::serialize(*member);
    }
  }
  for (const auto& [key, value] : root.members) {
    bool known = false;
    for (const EventFieldSpec& field : *spec) known = known || field.name == key;
    if (!known) return name + " payload member \"" + key + "\" is not in the table";
  }
  return std::nullopt;
}

namespace {

std::string with_article(JsonType type) {
  return (type == JsonType::integer ? "an " : "a ") + std::string(to_string(type));
}

JsonType type_of(const EventValue& value) {
  if (std::holds_alternative<bool>(value)) return JsonType::boolean;
  if (std::holds_alternative<std::int64_t>(value)) return JsonType::integer;
  return JsonType::string;
}

}  // namespace

std::string event_payload(RecordKind kind, const EventMembers& members) {
  const RecordKindSpec* spec = find_record_kind(kind);
  if (spec == nullptr) {
    throw std::invalid_argument("unknown record kind " + std::to_string(static_cast<int>(kind)) +
                                ": one of " + record_kind_names());
  }
  const std::string name(spec->name);
  if (!spec->is_event) {
    throw std::invalid_argument(name + " is a direction, not an event: its payload is bytes");
  }
  const auto member_list = [&] {
    std::string names;
    for (const EventFieldSpec& field : *spec) {
      if (!names.empty()) names += ", ";
      names += field.name;
    }
    return names.empty() ? std::string("none") : names;
  };
  for (std::size_t i = 0; i < members.size(); ++i) {
    const auto& [key, value] = members[i];
    const EventFieldSpec* field = nullptr;
    for (const EventFieldSpec& candidate : *spec) {
      if (candidate.name == key) field = &candidate;
    }
    if (field == nullptr) {
      throw std::invalid_argument(name + " event: unknown member \"" + key +
                                  "\" (its members: " + member_list() + ")");
    }
    if (type_of(value) != field->type) {
      throw std::invalid_argument(name + " event: member \"" + key + "\" must be " +
                                  with_article(field->type) + ", not " +
                                  with_article(type_of(value)));
    }
    for (std::size_t j = 0; j < i; ++j) {
      if (members[j].first == key) {
        throw std::invalid_argument(name + " event: member \"" + key + "\" given twice");
      }
    }
  }
  json::ObjectWriter object;
  for (const EventFieldSpec& field : *spec) {
    const EventValue* value = nullptr;
    for (const auto& [key, given] : members) {
      if (key == field.name) value = &given;
    }
    if (value == nullptr) {
      if (field.required) {
        throw std::invalid_argument(name + " event: required member \"" +
                                    std::string(field.name) + "\" is missing");
      }
      continue;
    }
    if (const bool* flag = std::get_if<bool>(value)) {
      object.add(field.name, *flag);
    } else if (const std::int64_t* number = std::get_if<std::int64_t>(value)) {
      object.add(field.name, *number);
    } else {
      object.add(field.name, std::get<std::string>(*value));
    }
  }
  return object.str();
}

std::string modem_inputs_payload(const ModemInputs& inputs) {
  return event_payload(RecordKind::modem_lines, {{event_field::cts, inputs.cts},
                                                 {event_field::dsr, inputs.dsr},
                                                 {event_field::ri, inputs.ri},
                                                 {event_field::cd, inputs.cd}});
}

namespace {

std::optional<json::Value> payload_object(std::string_view payload) {
  try {
    json::Value root = json::parse(payload.empty() ? std::string_view("{}") : payload);
    if (root.is_object()) return root;
  } catch (const json::ParseError&) {
  }
  return std::nullopt;
}

}  // namespace

std::optional<ModemInputs> modem_inputs_of(std::string_view payload, const ModemInputs& before) {
  const std::optional<json::Value> root = payload_object(payload);
  if (!root) return std::nullopt;
  ModemInputs inputs = before;
  bool any = false;
  const auto take = [&](const char* name, bool& level) {
    const json::Value* member = root->find(name);
    if (member == nullptr || member->type != json::Value::Type::boolean) return;
    level = member->boolean;
    any = true;
  };
  take(event_field::cts, inputs.cts);
  take(event_field::dsr, inputs.dsr);
  take(event_field::ri, inputs.ri);
  take(event_field::cd, inputs.cd);
  if (!any) return std::nullopt;
  return inputs;
}

bool records_host_lines(std::string_view payload) {
  const std::optional<json::Value> root = payload_object(payload);
  return root && (root->find(event_field::dtr) != nullptr || root->find(event_field::rts) != nullptr);
}

}  // namespace detail

std::string_view to_string(RecordKind kind) {
  const detail::RecordKindSpec* spec = detail::find_record_kind(kind);
  return spec != nullptr ? spec->name : std::string_view("unknown");
}

std::optional<RecordKind> record_kind_from_string(std::string_view name) {
  const detail::RecordKindSpec* spec = detail::find_record_kind(name);
  if (spec == nullptr) return std::nullopt;
  return spec->kind;
}

}  // namespace wiretape
