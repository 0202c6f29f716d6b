// wiretape.SessionHeader and Channel: a session's header from Python, as
// members (SessionHeader(**members)) or the file's header JSON (to_json, and
// to_dict / from_dict: the same layout as a dict), and a serial device's
// identity (read_device_identity, present_device_identity).
#include <algorithm>
#include <map>
#include <optional>
#include <string>

#include <nanobind/stl/map.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/vector.h>

#include "posix/device_identity.hpp"
#include "python/bindings.hpp"
#include "python/text_caster.hpp"
#include "python/session_members.hpp"
#include "session/format.hpp"
#include "session/header.hpp"
#include "util/hex.hpp"
#include "util/json.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/session.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace wiretape::python {

namespace {

Capture capture_from_python(const std::string& capture) {
  if (auto known = detail::capture_from_name(capture)) return *known;
  throw nb::value_error(("capture must be 'client' or 'wire', not '" + capture + "'").c_str());
}


// A device identity as Python sees it: a dict of its members (all of them,
// '' when not known), {} for none.
nb::dict identity_dict(const std::optional<DeviceIdentity>& identity) {
  nb::dict out;
  if (!identity) return out;
  for (const auto& member : detail::device_identity_members) {
    out[member.name] = (*identity).*member.value;
  }
  return out;
}

// The identity a dict of members names ({}: none); a member it does not
// have raises ValueError naming it, a value that is not a str TypeError.
std::optional<DeviceIdentity> identity_from_python(nb::dict members) {
  if (members.size() == 0) return std::nullopt;
  DeviceIdentity identity;
  for (auto [key, value] : members) {
    const std::string name = nb::cast<std::string>(nb::str(key));
    const auto* member = std::find_if(
        std::begin(detail::device_identity_members), std::end(detail::device_identity_members),
        [&](const detail::DeviceIdentityMember& m) { return name == m.name; });
    if (member == std::end(detail::device_identity_members)) {
      std::string names;
      for (const auto& known : detail::device_identity_members) {
        names += names.empty() ? "" : ", ";
        names += known.name;
      }
      throw nb::value_error(("device_identity has no member '" + detail::escape_bytes(name, 200) +
                             "' (its members: " + names + ")")
                                .c_str());
    }
    if (!nb::isinstance<nb::str>(value)) {
      throw nb::type_error(("device_identity member '" + name + "' must be a str").c_str());
    }
    identity.*member->value = nb::cast<std::string>(value);
  }
  return identity;
}

// A channel's fields by name, as the header JSON names them.
nb::dict channel_dict(const Channel& channel) {
  nb::dict out;
  out["id"] = channel.id;
  out["name"] = channel.name;
  out["port_options"] = channel.port_options;
  out["port_type"] = channel.port_type;
  out["capture"] = detail::capture_name(channel.capture);
  out["device_address"] = channel.device_address;
  out["device_identity"] = identity_dict(channel.device_identity);
  return out;
}

// A Channel from a Channel or a dict of its members (as channel_dict names
// them); an unknown member raises ValueError naming it, a wrong type TypeError.
Channel channel_from_python(nb::handle value) {
  if (nb::isinstance<Channel>(value)) return nb::cast<Channel>(value);
  if (!nb::isinstance<nb::dict>(value)) {
    throw nb::type_error("a channel must be a Channel or a dict of its members");
  }
  Channel channel;
  for (auto [key, member] : nb::borrow<nb::dict>(value)) {
    const std::string name = nb::cast<std::string>(nb::str(key));
    const auto text = [&]() {
      if (!nb::isinstance<nb::str>(member)) {
        throw nb::type_error(("channel member '" + name + "' must be a str").c_str());
      }
      return nb::cast<std::string>(member);
    };
    if (name == "id") {
      if (!PyLong_Check(member.ptr()) || PyBool_Check(member.ptr())) {
        throw nb::type_error("channel member 'id' must be an int");
      }
      const long long id = PyLong_AsLongLong(member.ptr());
      if (id < 0 || id > 0xffff) {
        PyErr_Clear();
        throw nb::value_error("channel member 'id' must be within 0..65535");
      }
      channel.id = static_cast<std::uint16_t>(id);
    } else if (name == "name") {
      channel.name = text();
    } else if (name == "port_options") {
      channel.port_options = text();
    } else if (name == "port_type") {
      channel.port_type = text();
    } else if (name == "capture") {
      channel.capture = capture_from_python(text());
    } else if (name == "device_address") {
      channel.device_address = text();
    } else if (name == "device_identity") {
      if (!nb::isinstance<nb::dict>(member)) {
        throw nb::type_error("channel member 'device_identity' must be a dict");
      }
      channel.device_identity = identity_from_python(nb::borrow<nb::dict>(member));
    } else {
      throw nb::value_error(("Channel has no member '" + detail::escape_bytes(name, 200) +
                             "' (its members: id, name, port_options, port_type, capture, "
                             "device_address, device_identity)")
                                .c_str());
    }
  }
  return channel;
}

// An attached recording's program (DESIGN §26) as a dict of the header
// JSON's member names, or None.
nb::object attached_dict(const std::optional<AttachedProgram>& attached) {
  if (!attached) return nb::none();
  namespace field = detail::header_field;
  nb::dict out;
  out[field::attached_pid] = attached->pid;
  out[field::attached_command] = attached->command;
  out[field::attached_utc] = attached->utc;
  out[field::attached_descriptors] = attached->descriptors;
  out[field::attached_device] = attached->device;
  out[field::attached_warnings] = attached->warnings;
  return out;
}

std::optional<AttachedProgram> attached_from_python(nb::handle value) {
  if (value.is_none()) return std::nullopt;
  if (!nb::isinstance<nb::dict>(value)) {
    throw nb::type_error("SessionHeader member 'attached' must be a dict or None");
  }
  namespace field = detail::header_field;
  nb::dict members = nb::borrow<nb::dict>(value);
  AttachedProgram attached;
  const auto member = [&](const char* name) -> nb::object {
    return members.contains(name) ? nb::object(members[name]) : nb::object(nb::none());
  };
  try {
    if (!member(field::attached_pid).is_none()) attached.pid = nb::cast<std::int64_t>(member(field::attached_pid));
    if (!member(field::attached_command).is_none()) attached.command = nb::cast<std::string>(member(field::attached_command));
    if (!member(field::attached_utc).is_none()) attached.utc = nb::cast<std::string>(member(field::attached_utc));
    if (!member(field::attached_descriptors).is_none()) attached.descriptors = nb::cast<std::vector<int>>(member(field::attached_descriptors));
    if (!member(field::attached_device).is_none()) attached.device = nb::cast<std::string>(member(field::attached_device));
    if (!member(field::attached_warnings).is_none()) attached.warnings = nb::cast<std::vector<std::string>>(member(field::attached_warnings));
  } catch (const nb::cast_error&) {
    throw nb::type_error("SessionHeader member 'attached' holds pid (int), command, utc, "
                         "device (str), descriptors (list of int) and warnings (list of str)");
  }
  return attached;
}

// The header's members by their attribute names (SessionHeader(**members)
// takes them): what == compares and repr shows. Not a layout for output:
// that is the file's JSON (to_dict).
nb::dict header_members(const SessionHeader& header) {
  nb::dict out;
  out["version_major"] = header.version_major;
  out["version_minor"] = header.version_minor;
  out["port_options"] = header.port_options;
  out["port_type"] = header.port_type;
  out["start_utc"] = header.start_utc;
  out["wiretape_version"] = header.wiretape_version;
  out["host"] = header.host;
  out["capture"] = detail::capture_name(header.capture);
  out["source_format"] = header.source_format;
  nb::list files;
  for (const auto& name : header.source_files) files.append(name);
  out["source_files"] = files;
  nb::dict details;
  for (const auto& [key, value] : header.source_details) details[key.c_str()] = value;
  out["source_details"] = details;
  out["device_address"] = header.device_address;
  nb::list edits;
  for (const auto& edit : header.edits) edits.append(edit);
  out["edits"] = edits;
  nb::dict metadata;
  for (const auto& [key, value] : header.user_metadata) metadata[key.c_str()] = value;
  out["metadata"] = metadata;
  out["device_identity"] = identity_dict(header.device_identity);
  nb::list channels;
  for (const Channel& channel : header.channels) channels.append(channel_dict(channel));
  out["channels"] = channels;
  out["attached"] = attached_dict(header.attached);
  return out;
}


// Whether every str in `value` (a str, or a list or dict of them) has a
// UTF-8 form, which a header's JSON needs.
bool utf8_encodable(nb::handle value) {
  if (nb::isinstance<nb::str>(value)) {
    if (PyUnicode_AsUTF8AndSize(value.ptr(), nullptr) != nullptr) return true;
    PyErr_Clear();
    return false;
  }
  if (nb::isinstance<nb::dict>(value)) {
    nb::dict members = nb::borrow<nb::dict>(value);
    return utf8_encodable(nb::list(members.keys())) && utf8_encodable(nb::list(members.values()));
  }
  if (nb::isinstance<nb::list>(value) || nb::isinstance<nb::tuple>(value)) {
    for (nb::handle item : value) {
      if (!utf8_encodable(item)) return false;
    }
  }
  return true;
}

// Whether `value` has the shape of the default member `model`: a str, an int,
// a list of str or a dict of str to str.
bool has_member_shape(nb::handle value, nb::handle model) {
  const auto all_str = [](nb::handle items) {
    for (nb::handle item : items) {
      if (!nb::isinstance<nb::str>(item)) return false;
    }
    return true;
  };
  // nanobind cannot convert a str holding a lone surrogate either; refused
  // here with the other shapes, by name.
  if (nb::isinstance<nb::str>(model)) return nb::isinstance<nb::str>(value);
  if (nb::isinstance<nb::list>(model)) {
    return (nb::isinstance<nb::list>(value) || nb::isinstance<nb::tuple>(value)) &&
           all_str(value);
  }
  if (nb::isinstance<nb::dict>(model)) {
    if (!nb::isinstance<nb::dict>(value)) return false;
    nb::dict members = nb::borrow<nb::dict>(value);
    return all_str(members.keys()) && all_str(members.values());
  }
  return PyLong_Check(value.ptr()) && !PyBool_Check(value.ptr());
}

// Sets the members of `header` named in `fields` (a dict, or keyword
// arguments), checked against header_members; None leaves a member as it
// is. The names are SessionHeader's attributes, spelled once.
void set_header_members(nb::handle header, nb::handle fields) {
  const nb::dict known = header_members(SessionHeader{});
  for (auto [key, value] : nb::borrow<nb::dict>(fields)) {
    const std::string name = nb::cast<std::string>(nb::str(key));
    if (!nb::isinstance<nb::str>(key) || !known.contains(key)) {
      std::string names;
      for (nb::handle member : known.keys()) {
        names += names.empty() ? "" : ", ";
        names += nb::cast<std::string>(member);
      }
      throw nb::value_error(("SessionHeader has no member '" + detail::escape_bytes(name, 200) + "' (its members: " +
                             names + ")")
                                .c_str());
    }
    if (value.is_none()) continue;
    if (name == "channels" || name == "attached") {  // their setters check them
      nb::setattr(header, key, value);
      continue;
    }
    if (!has_member_shape(value, known[key])) {
      const std::string expected = python_type_name(known[key]);
      throw nb::type_error(("SessionHeader member '" + name + "' must be a " +
                            (expected == "list"   ? "list of str"
                             : expected == "dict" ? "dict of str to str"
                                                  : expected) +
                            ", not " + python_type_name(value))
                               .c_str());
    }
    if (!utf8_encodable(value)) {
      throw nb::value_error(("SessionHeader member '" + name +
                             "' is not valid UTF-8 (a lone surrogate)")
                                .c_str());
    }
    nb::setattr(header, key, value);
  }
}

// A JSON value as json.loads gives it (a number written without a fraction
// or exponent as an int).
nb::object json_to_python(const detail::json::Value& value) {
  using Type = detail::json::Value::Type;
  switch (value.type) {
    case Type::null:
      return nb::none();
    case Type::boolean:
      return nb::bool_(value.boolean);
    case Type::number:
      if (value.text.find_first_of(".eE") == std::string::npos) {
        PyObject* number = PyLong_FromString(value.text.c_str(), nullptr, 10);
        if (number == nullptr) throw nb::python_error();
        return nb::steal(number);
      }
      return nb::float_(value.number);
    case Type::string:
      return nb::str(value.text.data(), value.text.size());
    case Type::array: {
      nb::list items;
      for (const auto& item : value.items) items.append(json_to_python(item));
      return std::move(items);
    }
    case Type::object: {
      nb::dict members;
      for (const auto& [key, member] : value.members) {
        members[nb::str(key.data(), key.size())] = json_to_python(member);
      }
      return std::move(members);
    }
  }
  return nb::none();
}

// The header as the file holds it: its JSON (header_json) as a dict, so that
// what Python prints or writes of a header has the file's one layout.
nb::dict header_layout(const SessionHeader& header) {
  return nb::borrow<nb::dict>(json_to_python(detail::json::parse(header.to_json())));
}

// The top-level members of the header JSON (docs/session-format.md,
// "Metadata"). Each but source is the attribute of its name.
constexpr const char* layout_members[] = {
    detail::header_field::port_options, detail::header_field::port_type,
    detail::header_field::start_utc,    detail::header_field::wiretape_version,
    detail::header_field::host,         detail::header_field::capture,
    detail::header_field::metadata,     detail::header_field::source,
    detail::header_field::device_address, detail::header_field::edits,
    detail::header_field::device_identity, detail::header_field::channels,
    detail::header_field::attached,
};

// Adds to `members` the attributes the header JSON's `source` object holds:
// format (as the reader, "unknown" when a source does not say), files, and
// every other member as a source detail.
void add_source_members(nb::handle source, nb::dict& members) {
  namespace field = detail::header_field;
  if (source.is_none()) return;
  if (!nb::isinstance<nb::dict>(source)) {
    throw nb::type_error(("SessionHeader member 'source' must be a dict (format, files and "
                          "string details), not " + python_type_name(source))
                             .c_str());
  }
  members["source_format"] = "unknown";
  nb::dict details;
  for (auto [key, value] : nb::borrow<nb::dict>(source)) {
    const std::string name = detail::escape_bytes(nb::cast<std::string>(nb::str(key)), 200);
    if (!nb::isinstance<nb::str>(key)) {
      throw nb::type_error(("SessionHeader member 'source' has a key that is not a str (" +
                            name + ")")
                               .c_str());
    }
    const bool files = name == field::source_files;
    if (!has_member_shape(value, files ? nb::object(nb::list()) : nb::object(nb::str("")))) {
      throw nb::type_error(("SessionHeader member 'source." + name + "' must be a " +
                            (files ? "list of str" : "str") + ", not " +
                            python_type_name(value))
                               .c_str());
    }
    if (name == field::source_format) {
      members["source_format"] = value;
    } else if (files) {
      members["source_files"] = value;
    } else {
      details[key] = value;
    }
  }
  members["source_details"] = details;
}

// A header from the header JSON's layout as a dict (what header_layout
// gives), checked: a member the layout lacks raises ValueError naming it, a
// wrong type TypeError; None, like a missing member, leaves the default. The
// JSON holds no version: the header's is the one writers write, as a file
// read back from it has.
SessionHeader header_from_layout(nb::dict layout) {
  nb::dict members;
  for (auto [key, value] : layout) {
    const std::string name = nb::cast<std::string>(nb::str(key));
    const bool known =
        nb::isinstance<nb::str>(key) &&
        std::any_of(std::begin(layout_members), std::end(layout_members),
                    [&](const char* member) { return name == member; });
    if (!known) {
      std::string names;
      for (const char* member : layout_members) {
        names += names.empty() ? "" : ", ";
        names += member;
      }
      throw nb::value_error(("the session header JSON has no member '" +
                             detail::escape_bytes(name, 200) + "' (its members: " + names +
                             "; docs/session-format.md)")
                                .c_str());
    }
    if (name == detail::header_field::source) {
      add_source_members(value, members);
    } else {
      members[key] = value;
    }
  }
  SessionHeader written;
  written.version_major = detail::session_version_major;
  written.version_minor = detail::session_version_minor;
  nb::object header = nb::cast(written);
  set_header_members(header, members);
  return nb::cast<SessionHeader>(header);
}

}  // namespace

// The Python type name of `value`, for error messages.
std::string python_type_name(nb::handle value) {
  return nb::cast<std::string>(nb::handle(reinterpret_cast<PyObject*>(Py_TYPE(value.ptr())))
                                   .attr("__name__"));
}

// What SessionWriter and Recorder write: `header`, or with none a session
// recorded now on this machine, with `members` set (checked).
SessionHeader header_to_write(const std::optional<SessionHeader>& header, nb::kwargs members) {
  nb::object chosen = nb::cast(header ? *header : SessionHeader::starting_now());
  set_header_members(chosen, members);
  return nb::cast<SessionHeader>(chosen);
}

void bind_header(nb::module_& m) {
  nb::class_<Channel>(
      m, "Channel",
      "One port of a session of several ports (format 1.2, docs/session-format.md, "
      "\"channels\"): its id (what its records carry), name and what the header says of "
      "a port. Channel(**members) with the members to_dict() names.")
      .def(
          "__init__",
          [](Channel* self, nb::kwargs members) { new (self) Channel(channel_from_python(members)); },
          nb::sig("def __init__(self, **members: object) -> None"))
      .def_rw("id", &Channel::id, "what the channel's records carry in Record.channel")
      .def_rw("name", &Channel::name, "the channel's name ('' only for the one channel of a "
                                      "session without named channels)")
      .def_rw("port_options", &Channel::port_options)
      .def_rw("port_type", &Channel::port_type)
      .def_prop_rw(
          "capture",
          [](const Channel& c) { return std::string(detail::capture_name(c.capture)); },
          [](Channel& c, const std::string& capture) { c.capture = capture_from_python(capture); },
          "'client' or 'wire'")
      .def_rw("device_address", &Channel::device_address)
      .def_prop_rw(
          "device_identity",
          [](const Channel& c) { return identity_dict(c.device_identity); },
          [](Channel& c, nb::dict members) { c.device_identity = identity_from_python(members); },
          "the serial device's identity, as SessionHeader.device_identity")
      .def("to_dict", &channel_dict, "the members as a dict")
      .def("__eq__", [](const Channel& a, const Channel& b) { return a == b; })
      .def("__copy__", [](const Channel& c) { return c; })
      .def("__deepcopy__", [](const Channel& c, nb::handle) { return c; }, "memo"_a)
      .def("__repr__", [](const Channel& c) {
        return "Channel(id=" + std::to_string(c.id) + ", name=" +
               std::string(nb::repr(nb::str(c.name.c_str(), c.name.size())).c_str()) +
               ", port_type=" +
               std::string(nb::repr(nb::str(c.port_type.c_str(), c.port_type.size())).c_str()) +
               ")";
      });
  m.def(
      "channel_name_problem",
      [](const std::string& name) { return channel_name_problem(name); }, "name"_a,
      "Why NAME cannot name a channel (not an identifier of at most 64 characters of "
      "letters, digits, '_' and '-'; or an option key), or None when it can.");

  nb::class_<SessionHeader>(
      m, "SessionHeader",
      "A session file's header (docs/session-format.md): what was recorded, where, when "
      "and how; the one type for reading (SessionReader.header) and writing "
      "(SessionWriter). SessionHeader(**members): members by their attribute names, "
      "checked (an unknown member or a wrong type raises); the others keep their defaults "
      "(start_utc and host empty: not known). SessionHeader.from_dict(d) takes the file's "
      "header JSON as a dict, as to_dict() gives it.")
      .def(
          "__init__",
          [](nb::handle self, nb::kwargs fields) {
            nb::inst_zero(self);
            new (nb::inst_ptr<SessionHeader>(self)) SessionHeader{};
            nb::inst_mark_ready(self);
            set_header_members(self, fields);
          },
          nb::sig("def __init__(self, **members: object) -> None"))
      .def_static("from_dict", &header_from_layout, "layout"_a,
                  "A header from the file's header JSON as a dict (as to_dict() gives it, "
                  "json.loads of a header's to_json()), checked: a member the layout lacks "
                  "or of the wrong type raises. Its version is SESSION_VERSION, what a "
                  "writer writes.")
      .def_static("starting_now", &SessionHeader::starting_now,
                  "A header for a session that starts now on this machine: start_utc now, "
                  "host this machine's name (what recorders write).")
      .def_rw("version_major", &SessionHeader::version_major,
              "the file's format version, as read (0.0 for a flexiport log); writers "
              "write their own")
      .def_rw("version_minor", &SessionHeader::version_minor)
      .def_rw("port_options", &SessionHeader::port_options,
              "the option string the port was opened with")
      .def_rw("port_type", &SessionHeader::port_type, "serial, tcp, udp, pty, loopback, ...")
      .def_rw("start_utc", &SessionHeader::start_utc,
              "when the device was opened, ISO 8601 UTC ('' when not known)")
      .def_rw("wiretape_version", &SessionHeader::wiretape_version,
              "the version of wiretape that wrote the file")
      .def_rw("host", &SessionHeader::host, "the recording machine's name ('' when not known)")
      .def_prop_rw(
          "capture",
          [](const SessionHeader& h) { return std::string(detail::capture_name(h.capture)); },
          [](SessionHeader& h, const std::string& capture) {
            h.capture = capture_from_python(capture);
          },
          "'client' (library recording) or 'wire' (proxy recording)")
      .def_rw("source_format", &SessionHeader::source_format,
              "'wiretape' (recorded by wiretape) or the format it was imported from: "
              "'flexiport', 'pcap', 'reserial', 'umockdev', ...")
      .def_rw("source_files", &SessionHeader::source_files,
              "an imported session's original file names")
      .def_rw("source_details", &SessionHeader::source_details,
              "what else the import noted (the stream, the test, the logs' formats)")
      .def_rw("device_address", &SessionHeader::device_address,
              "host:port of a network device, when known")
      .def_rw("edits", &SessionHeader::edits, "what wiretape edit changed, in order")
      .def_rw("metadata", &SessionHeader::user_metadata, "the free user metadata (--meta)")
      .def_prop_rw(
          "device_identity",
          [](const SessionHeader& h) { return identity_dict(h.device_identity); },
          [](SessionHeader& h, nb::dict members) {
            h.device_identity = identity_from_python(members);
          },
          "the serial device's identity (format 1.2; docs/session-format.md): a dict of "
          "kernel_name, subsystem, vendor_id, product_id, serial_number, manufacturer, "
          "product, interface, location, by_id ('' when not known); {} when the "
          "recording has none (a pty, a network device)")
      .def_prop_rw(
          "attached",
          [](const SessionHeader& h) { return attached_dict(h.attached); },
          [](SessionHeader& h, nb::handle value) { h.attached = attached_from_python(value); },
          nb::for_getter(nb::sig("def attached(self, /) -> dict[str, object] | None")),
          nb::for_setter(nb::sig("def attached(self, value: dict[str, object] | None, /) -> None")),
          "a recording made by attaching to a running program (record --attach): a dict of "
          "pid, command, utc, descriptors, device and warnings; None otherwise")
      .def(
          "clear_device_serial",
          [](SessionHeader& h) {
            if (h.device_identity) detail::clear_device_serial(*h.device_identity);
          },
          "Clears the device identity's serial number and its part of the by-id name "
          "(what edit --redact does).")
      .def_prop_rw(
          "channels",
          [](const SessionHeader& h) { return h.channels; },
          [](SessionHeader& h, nb::handle channels) {
            if (!nb::isinstance<nb::list>(channels) && !nb::isinstance<nb::tuple>(channels)) {
              throw nb::type_error("SessionHeader member 'channels' must be a list of Channel");
            }
            std::vector<Channel> read;
            for (nb::handle channel : channels) read.push_back(channel_from_python(channel));
            h.channels = std::move(read);
          },
          nb::for_getter(nb::sig("def channels(self, /) -> list[Channel]")),
          nb::for_setter(nb::sig(
              "def channels(self, value: list[Channel] | list[dict[str, object]], /) -> None")),
          "format 1.2: the session's ports (Channel objects, or dicts of their members "
          "when set), ids 0..n-1 in order; [] for a session of one unnamed port, which the "
          "port members describe. With channels, the port members are channel 0's.")
      .def("channel_list", &SessionHeader::channel_list,
           "Every channel: channels, or the one unnamed channel 0 the port members describe.")
      .def(
          "find_channel",
          [](const SessionHeader& h, const std::string& name) { return h.find_channel(name); },
          "name"_a, "The channel named NAME, or None.")
      .def_rw("metadata_json", &SessionHeader::metadata_json,
              "the header's JSON as stored (read) or written; to_json() makes it anew")
      .def("to_json", &SessionHeader::to_json,
           "The header's JSON object as a writer writes it. Raises OptionError naming the "
           "member a reader would refuse (not UTF-8, a start_utc out of range).")
      .def("to_dict", &header_layout,
           "The header as the file holds it: json.loads(to_json()), the one layout "
           "commands print and write (docs/session-format.md, \"Metadata\"; no "
           "version, which is the file's, not the header JSON's). Raises OptionError as "
           "to_json() does.")
      .def("__copy__", [](const SessionHeader& h) { return h; })
      .def("__deepcopy__", [](const SessionHeader& h, nb::handle) { return h; }, "memo"_a)
      .def("__eq__", [](const SessionHeader& a, const SessionHeader& b) {
        return header_members(a).equal(header_members(b));
      })
      .def("__repr__", [](const SessionHeader& h) {
        std::string text = "SessionHeader(";
        bool first = true;
        for (auto [key, value] : header_members(h)) {
          if (!first) text += ", ";
          first = false;
          text += nb::str(key).c_str();
          text += "=";
          text += nb::repr(value).c_str();
        }
        return text + ")";
      });

  m.def(
      "read_device_identity",
      [](const std::string& device, const std::string& sysfs_root, const std::string& dev_root) {
        return identity_dict(detail::read_device_identity(device, sysfs_root, dev_root));
      },
      "device"_a, "sysfs_root"_a = "/sys", "dev_root"_a = "/dev",
      "The identity of the serial device at `device` as record stores it (a dict as "
      "SessionHeader.device_identity; {} for a pty or a path with no device in sysfs).");
  m.def(
      "present_device_identity",
      [](nb::dict identity, const std::string& root, const std::string& device_path) {
        const DeviceIdentity known = identity_from_python(identity).value_or(DeviceIdentity{});
        const std::string tty_name = detail::presented_tty_name(known, device_path);
        if (tty_name.empty()) return nb::make_tuple(tty_name, std::string(), known.by_id);
        return nb::make_tuple(tty_name, detail::write_device_tree(known, root, tty_name),
                              known.by_id);
      },
      "identity"_a, "root"_a, "device_path"_a,
      "Writes under `root` the sysfs folders that present `identity` (as "
      "SessionHeader.device_identity) to a command that opens `device_path`: returns "
      "(tty_name, folder, by_id), the kernel name presented (device_path's own name when "
      "it is directly under /dev, else the recorded one), the folder that stands for "
      "/sys/class/tty/TTY_NAME (tty_name and folder '' when no name can be presented) "
      "and the by-id name to redirect ('' when none).");
}

}  // namespace wiretape::python
