// wiretape.SessionReader, SessionWriter, Record and export_flexiport: session
// files from Python. Records carry bytes; kinds are their names ("rx", "tx",
// "open", ... "break"); times are integer nanoseconds since the open.
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>

#include <nanobind/stl/map.h>
#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/unique_ptr.h>
#include <nanobind/stl/vector.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/string_view.h>

#include "posix/device_identity.hpp"
#include "posix/file_checks.hpp"
#include "util/hex.hpp"
#include "python/bindings.hpp"
#include "session/flexiport.hpp"
#include "session/format.hpp"
#include "session/header.hpp"
#include "session/reader.hpp"
#include "session/record_kinds.hpp"
#include "wiretape/cassette_names.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"
#include "wiretape/recorder.hpp"
#include "wiretape/session.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace wiretape::python {

namespace {

// A session read from a FIFO waits for its writer without the GIL, where
// Python's signal handlers only set a flag: the wait runs them (Ctrl-C, and
// SIGTERM as the CLI maps it), and their exception ends it.
void run_python_signal_handlers() {
  nb::gil_scoped_acquire acquire;
  check_signals();
}

// str, bytes or os.PathLike, as open() takes.
std::string path_from_python(nb::handle value) {
  PyObject* fspath = PyOS_FSPath(value.ptr());
  if (fspath == nullptr) throw nb::python_error();
  nb::object path = nb::steal(fspath);
  if (PyBytes_Check(path.ptr())) {
    // The stable ABI's calls, not the macros: one abi3 wheel for 3.12 on.
    return std::string(PyBytes_AsString(path.ptr()),
                       static_cast<std::size_t>(PyBytes_Size(path.ptr())));
  }
  return nb::cast<std::string>(path);
}

nb::bytes to_bytes(const std::string& data) { return nb::bytes(data.data(), data.size()); }

// A kind given as its name, or as its numeric code (for kinds this version
// does not name: conversions keep them).
RecordKind kind_from_python(nb::handle kind) {
  if (PyLong_Check(kind.ptr())) {
    int overflow = 0;
    const long code = PyLong_AsLongAndOverflow(kind.ptr(), &overflow);
    if (overflow != 0 || code < 0 || code > 255) {
      throw nb::value_error("a record kind code is 0..255");
    }
    return static_cast<RecordKind>(code);
  }
  const std::string name = nb::cast<std::string>(kind);
  if (auto known = record_kind_from_string(name)) return *known;
  throw nb::value_error(
      ("unknown record kind '" + name + "': one of " + detail::record_kind_names()).c_str());
}

Capture capture_from_python(const std::string& capture) {
  if (auto known = detail::capture_from_name(capture)) return *known;
  throw nb::value_error(("capture must be 'client' or 'wire', not '" + capture + "'").c_str());
}

struct PyRecord {
  Record record;
};

// The reader, closable from Python (closing releases the file).
struct PyReader {
  std::unique_ptr<SessionReader> reader;

  SessionReader& get() {
    if (!reader) throw nb::value_error("the session reader is closed");
    return *reader;
  }
};

struct PyWriter {
  std::unique_ptr<SessionWriter> writer;
  std::string path;

  SessionWriter& get() {
    if (!writer) throw nb::value_error("the session writer is closed");
    return *writer;
  }
  void close() {
    if (!writer) return;
    std::unique_ptr<SessionWriter> closing = std::move(writer);
    nb::gil_scoped_release release;
    closing->close();
  }
};

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

// The header's fields by name, as show, stats and convert lay them out.
nb::dict header_dict(const SessionHeader& header) {
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
  return out;
}

// The Python type name of `value`, for error messages.
std::string python_type_name(nb::handle value) {
  return nb::cast<std::string>(nb::handle(reinterpret_cast<PyObject*>(Py_TYPE(value.ptr())))
                                   .attr("__name__"));
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
// arguments), checked against the members to_dict() gives; None leaves a
// member as it is. The names are SessionHeader's attributes, spelled once.
void set_header_members(nb::handle header, nb::handle fields) {
  const nb::dict known = header_dict(SessionHeader{});
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
    if (name == "channels") {  // its setter checks each channel
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

// What SessionWriter and Recorder write: `header`, or with none a session
// recorded now on this machine, with `members` set (checked).
SessionHeader header_to_write(const std::optional<SessionHeader>& header, nb::kwargs members) {
  nb::object chosen = nb::cast(header ? *header : SessionHeader::starting_now());
  set_header_members(chosen, members);
  return nb::cast<SessionHeader>(chosen);
}

FlushPolicy flush_policy(int flush_ms, bool fsync) {
  if (flush_ms < 0) throw nb::value_error("flush_ms must be >= 0");
  return FlushPolicy{std::chrono::milliseconds(flush_ms), fsync};
}

// An event's members from a Python dict: bool, int or str values.
detail::EventMembers event_members_from_python(RecordKind kind, nb::dict fields) {
  detail::EventMembers members;
  for (auto [key, value] : fields) {
    const std::string name = nb::cast<std::string>(nb::str(key));
    if (PyBool_Check(value.ptr())) {
      members.emplace_back(name, nb::cast<bool>(value));
    } else if (PyLong_Check(value.ptr())) {
      int overflow = 0;
      const long long number = PyLong_AsLongLongAndOverflow(value.ptr(), &overflow);
      if (overflow != 0) {
        throw nb::value_error((std::string(to_string(kind)) + " event: member \"" + name +
                               "\" is out of the 64-bit range")
                                  .c_str());
      }
      members.emplace_back(name, static_cast<std::int64_t>(number));
    } else if (nb::isinstance<nb::str>(value)) {
      members.emplace_back(name, nb::cast<std::string>(value));
    } else {
      throw nb::value_error((std::string(to_string(kind)) + " event: member \"" + name +
                             "\" is a " + python_type_name(value) +
                             "; event members are bool, int or str")
                                .c_str());
    }
  }
  return members;
}

// The record-kind table as Python sees it: a tuple of dicts, in code order.
nb::tuple record_kinds_tuple() {
  nb::list kinds;
  for (const detail::RecordKindSpec& spec : detail::record_kinds()) {
    nb::list fields;
    for (const detail::EventFieldSpec& field : spec) {
      nb::dict f;
      f["name"] = std::string(field.name);
      f["type"] = std::string(detail::to_string(field.type));
      f["required"] = field.required;
      f["meaning"] = std::string(field.meaning);
      fields.append(f);
    }
    nb::dict kind;
    kind["name"] = std::string(spec.name);
    kind["code"] = static_cast<int>(spec.code());
    kind["is_event"] = spec.is_event;
    kind["meaning"] = std::string(spec.meaning);
    kind["fields"] = nb::tuple(fields);
    kinds.append(kind);
  }
  return nb::tuple(kinds);
}

// The byte layout's constants, for Python code that reads files itself.
void bind_format_constants(nb::module_& m) {
  m.attr("SESSION_MAGIC") = nb::bytes(detail::session_magic, sizeof detail::session_magic);
  m.attr("SESSION_VERSION") =
      nb::make_tuple(detail::session_version_major, detail::session_version_minor);
  // magic, major, minor, JSON length: the JSON follows, then its CRC.
  m.attr("FILE_HEADER_FIXED_SIZE") = detail::file_header_fixed_size;
  m.attr("MAX_HEADER_JSON") = detail::max_header_json;
  // length, kind, flags, reserved, t_ns: the payload follows, then its CRC.
  m.attr("RECORD_HEADER_SIZE") = detail::record_header_size;
  m.attr("CRC_SIZE") = detail::crc_size;
  // Bytes a file header and a record take besides their JSON or payload.
  m.attr("FILE_HEADER_OVERHEAD") = detail::file_header_fixed_size + detail::crc_size;
  m.attr("RECORD_OVERHEAD") = detail::record_header_size + detail::crc_size;
  m.attr("MAX_RECORD_T_NS") = detail::max_record_t_ns;
}

}  // namespace

void bind_session(nb::module_& m) {
  detail::set_interruption_check(&run_python_signal_handlers);
  bind_format_constants(m);
  m.attr("RECORD_KINDS") = record_kinds_tuple();
  m.def(
      "start_utc_problem",
      [](const std::string& start_utc) { return detail::start_utc_problem(start_utc); },
      "start_utc"_a,
      "Why a session header's start_utc would be refused (not YYYY-MM-DDTHH:MM:SS[.frac]Z, "
      "out of range), or None.");
  m.def(
      "record_content_problem",
      [](nb::handle kind, std::uint64_t t_ns, nb::bytes data) {
        return detail::record_content_problem(kind_from_python(kind), t_ns,
                                              std::string_view(data.c_str(), data.size()));
      },
      "kind"_a, "t_ns"_a, "data"_a,
      "Why a reader would stop at this record although its CRC matches (a time past "
      "MAX_RECORD_T_NS, an event payload that is not a JSON object within the limits), "
      "or None: the rule the writer and every reader apply.");
  m.def(
      "flexiport_prefix",
      [](nb::handle path) { return detail::flexiport_prefix(path_from_python(path)); },
      "path"_a,
      "The 'name.log' prefix PATH stands for when it is a flexiport log ('name.log', "
      "'name.logr' or 'name.logw' with the pair on disk), else None.");

  nb::class_<PyRecord>(m, "Record", "One record of a session: t_ns, kind, data.")
      .def(
          "__init__",
          [](PyRecord* self, std::uint64_t t_ns, nb::handle kind, nb::bytes data,
             std::uint16_t channel) {
            new (self) PyRecord{};
            self->record.t_ns = t_ns;
            self->record.kind = kind_from_python(kind);
            self->record.data.assign(data.c_str(), data.size());
            self->record.channel = channel;
          },
          "t_ns"_a, "kind"_a, "data"_a = nb::bytes("", 0), "channel"_a = 0)
      .def_prop_ro("t_ns", [](const PyRecord& r) { return r.record.t_ns; },
                   "nanoseconds since the device was opened")
      .def_prop_ro("kind", [](const PyRecord& r) { return std::string(to_string(r.record.kind)); },
                   "'rx' (device to host), 'tx' (host to device), or an event name")
      .def_prop_ro("kind_code", [](const PyRecord& r) { return static_cast<int>(r.record.kind); })
      .def_prop_ro("channel", [](const PyRecord& r) { return r.record.channel; },
                   "the id of the record's channel (SessionHeader.channels); 0 in a session "
                   "of one port")
      .def_prop_ro("data", [](const PyRecord& r) { return to_bytes(r.record.data); },
                   "the bytes (rx, tx) or the event's JSON object as bytes")
      .def("__eq__",
           [](const PyRecord& a, const PyRecord& b) {
             return a.record.t_ns == b.record.t_ns && a.record.kind == b.record.kind &&
                    a.record.data == b.record.data && a.record.channel == b.record.channel;
           })
      .def("__repr__", [](const PyRecord& r) {
        nb::object data = to_bytes(r.record.data);
        return "Record(t_ns=" + std::to_string(r.record.t_ns) + ", kind='" +
               std::string(to_string(r.record.kind)) + "', data=" +
               std::string(nb::repr(data).c_str()) +
               (r.record.channel != 0 ? ", channel=" + std::to_string(r.record.channel) : "") +
               ")";
      });

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
      "(SessionWriter). SessionHeader(**members) or SessionHeader.from_dict(d): members "
      "as to_dict() names them, checked (an unknown member or a wrong type raises); the "
      "others keep their defaults (start_utc and host empty: not known).")
      .def(
          "__init__",
          [](nb::handle self, nb::kwargs fields) {
            nb::inst_zero(self);
            new (nb::inst_ptr<SessionHeader>(self)) SessionHeader{};
            nb::inst_mark_ready(self);
            set_header_members(self, fields);
          },
          nb::sig("def __init__(self, **members: object) -> None"))
      .def_static(
          "from_dict",
          [](nb::dict fields) {
            nb::object header = nb::cast(SessionHeader{});
            set_header_members(header, fields);
            return nb::cast<SessionHeader>(header);
          },
          "members"_a, "A header from a dict of members (as to_dict() gives them), checked.")
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
      .def("to_dict", &header_dict,
           "the members above as a dict, but metadata_json (the stored text, derived)")
      .def("__copy__", [](const SessionHeader& h) { return h; })
      .def("__deepcopy__", [](const SessionHeader& h, nb::handle) { return h; }, "memo"_a)
      .def("__eq__", [](const SessionHeader& a, const SessionHeader& b) {
        return header_dict(a).equal(header_dict(b));
      })
      .def("__repr__", [](const SessionHeader& h) {
        std::string text = "SessionHeader(";
        bool first = true;
        for (auto [key, value] : header_dict(h)) {
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

  m.def(
      "event_payload",
      [](nb::handle kind, nb::dict fields) {
        const RecordKind k = kind_from_python(kind);
        const std::string payload = detail::event_payload(k, event_members_from_python(k, fields));
        return to_bytes(payload);
      },
      "kind"_a, "fields"_a,
      "The JSON payload of an event of KIND ('settings', 'fault', ...) with the members "
      "FIELDS (bool, int or str), as bytes in the record-kind table's order. Raises "
      "ValueError naming the kind and the member: not in the table, wrong type, missing "
      "when required.");

  nb::class_<PyReader>(m, "SessionReader",
                       "Reads a .wtape file or a flexiport log (name.log) record by record, "
                       "with memory independent of its size; a pipe or FIFO is read once, as "
                       "a stream, waiting for its writer (Ctrl-C ends the wait). Iterating yields Record objects; "
                       "at a damaged record iteration ends and .damage says where.")
      .def(
          "__init__",
          [](PyReader* self, nb::handle path, std::optional<std::uint16_t> channel) {
            const std::string p = path_from_python(path);
            new (self) PyReader{};
            nb::gil_scoped_release release;
            self->reader = std::make_unique<SessionReader>(p, channel);
          },
          "path"_a, "channel"_a = nb::none(),
          "CHANNEL: only that channel's records (its id); None: every channel's, in "
          "recorded order (Record.channel says which).")
      .def("__iter__", [](nb::handle self) { return self; },
           nb::sig("def __iter__(self) -> SessionReader"))
      .def("__next__",
           [](PyReader& self) {
             PyRecord out;
             bool more = false;
             SessionReader& reader = self.get();
             {
               nb::gil_scoped_release release;
               more = reader.next(out.record);
             }
             if (!more) throw nb::stop_iteration();
             return out;
           })
      .def_prop_ro("header", [](PyReader& self) { return self.get().header(); },
                   "the session's header (a SessionHeader)")
      .def_prop_ro(
          "damage",
          [](PyReader& self) -> nb::object {
            const auto& damage = self.get().damage();
            if (!damage) return nb::none();
            // The class bind_errors() registered, looked up when needed.
            nb::object cls = nb::module_::import_("wiretape._core").attr("SessionError");
            nb::object error = cls(std::string(damage->what()), damage->offset());
            error.attr("message") = std::string(damage->what());
            return error;
          },
          nb::for_getter(nb::sig("def damage(self, /) -> SessionError | None")),
          "None, or a SessionError (not raised) with .offset and .message: where "
          "reading stopped and why")
      .def("rewind", [](PyReader& self) { self.get().rewind(); }, "back to the first record")
      .def_prop_ro("path", [](PyReader& self) { return self.get().path(); })
      .def("close", [](PyReader& self) { self.reader.reset(); })
      .def("__enter__", [](nb::handle self) { return self; },
           nb::sig("def __enter__(self) -> SessionReader"))
      .def("__exit__", [](PyReader& self, nb::args) { self.reader.reset(); });

  nb::class_<PyWriter>(m, "SessionWriter",
                       "Writes a new .wtape file (truncating PATH). Buffered; buffered records "
                       "reach the OS at most flush_ms after they were written. A full disk or "
                       "file-size limit raises PortError; what was written before stays "
                       "readable.")
      .def(
          "__init__",
          [](PyWriter* self, nb::handle path, std::optional<SessionHeader> header,
             int flush_ms, bool fsync, std::size_t header_room, nb::kwargs members) {
            const FlushPolicy flush = flush_policy(flush_ms, fsync);
            const SessionHeader written = header_to_write(header, members);
            const std::string p = path_from_python(path);
            new (self) PyWriter{};
            self->path = p;
            nb::gil_scoped_release release;
            self->writer = std::make_unique<SessionWriter>(p, written, flush, header_room);
          },
          "path"_a, "header"_a = nb::none(), nb::kw_only(), "flush_ms"_a = 100,
          "fsync"_a = false, "header_room"_a = std::size_t{0}, "members"_a,
          nb::sig("def __init__(self, path: str | os.PathLike[str] | bytes, "
                  "header: SessionHeader | None = None, *, flush_ms: int = 100, "
                  "fsync: bool = False, header_room: int = 0, **members: object) -> None"),
          "HEADER (default: SessionHeader.starting_now()) with MEMBERS (keyword arguments "
          "named as SessionHeader's members) set on it is what the file's header says. "
          "header_room: spare header bytes (spaces) kept so that add_channel() can rewrite "
          "the header in place; 0 writes it exactly as long as its JSON.")
      .def_prop_ro("header", [](PyWriter& self) { return self.get().header(); },
                   "the header as written (this library's format version, metadata_json)")
      .def(
          "write",
          [](PyWriter& self, nb::handle kind, std::uint64_t t_ns, nb::bytes data,
             std::uint16_t channel) {
            const RecordKind k = kind_from_python(kind);
            SessionWriter& writer = self.get();
            writer.write(k, t_ns, std::string_view(data.c_str(), data.size()), channel);
          },
          "kind"_a, "t_ns"_a, "data"_a = nb::bytes("", 0), "channel"_a = 0,
          "Appends a record: kind is a name ('rx', 'tx', 'open', ...) or a code. channel is "
          "reserved for sessions of several ports: 0, the session's port.")
      .def(
          "add_channel",
          [](PyWriter& self, const Channel& channel) {
            SessionWriter& writer = self.get();
            nb::gil_scoped_release release;
            return writer.add_channel(channel);
          },
          "channel"_a,
          "Adds CHANNEL (its id is ignored) to the header's channels, rewriting the header in "
          "place within the header_room reserved; returns its id. Raises OptionError naming "
          "'name' (a bad or taken name), SessionError when the header has no room left.")
      .def("flush",
           [](PyWriter& self) {
             SessionWriter& writer = self.get();
             nb::gil_scoped_release release;
             writer.flush();
           })
      .def("close", [](PyWriter& self) { self.close(); })
      .def_prop_ro("path", [](PyWriter& self) { return self.path; })
      .def("__enter__", [](nb::handle self) { return self; },
           nb::sig("def __enter__(self) -> SessionWriter"))
      .def("__exit__", [](PyWriter& self, nb::args) { self.close(); });

  // Held by shared_ptr: a Bridge records into it (Bridge(recorder=...)).
  nb::class_<Recorder>(m, "Recorder",
                       "Records several ports into one session file, one channel each, on one "
                       "clock (time 0: the first channel's open). Its ports keep the file "
                       "open; it is closed at close() (or leaving a with block), or when the "
                       "recorder and its ports are gone.")
      .def(
          "__init__",
          [](Recorder* self, nb::handle path, std::optional<SessionHeader> header,
             int flush_ms, bool fsync, std::size_t header_room, nb::kwargs members) {
            const FlushPolicy flush = flush_policy(flush_ms, fsync);
            const SessionHeader written = header_to_write(header, members);
            const std::string p = path_from_python(path);
            nb::gil_scoped_release release;
            new (self) Recorder(p, written, flush, header_room);
          },
          "path"_a, "header"_a = nb::none(), nb::kw_only(), "flush_ms"_a = 100,
          "fsync"_a = false, "header_room"_a = Recorder::default_header_room, "members"_a,
          nb::sig("def __init__(self, path: str | os.PathLike[str] | bytes, "
                  "header: SessionHeader | None = None, *, flush_ms: int = 100, "
                  "fsync: bool = False, header_room: int = 32768, "
                  "**members: object) -> None"),
          "Creates the session file. HEADER (default: SessionHeader.starting_now()) with "
          "MEMBERS set on it is its header; each port adds its channel to it. header_room: "
          "the bytes kept for the channels' entries.")
      .def(
          "open_port",
          [](Recorder& self, const std::string& options) {
            nb::gil_scoped_release release;
            return self.open_port(std::string_view(options));
          },
          "options"_a,
          "Opens the port OPTIONS describe (as open_port() does) recording into a new "
          "channel named by its name=NAME: 'name=gps,type=serial,device=/dev/ttyUSB0'. "
          "Raises OptionError naming the key (a missing, bad or taken name; log=).")
      .def("close", &Recorder::close, nb::call_guard<nb::gil_scoped_release>(),
           "Flushes and closes the file; its ports go on, unrecorded.")
      .def("now_ns", &Recorder::now_ns,
           "The recorder's clock: ns since its first channel's open (0 before).")
      .def_prop_ro("path", &Recorder::path)
      .def_prop_ro("header", &Recorder::header, "the header as written so far")
      .def("__enter__", [](nb::handle self) { return self; },
           nb::sig("def __enter__(self) -> Recorder"))
      .def("__exit__",
           [](Recorder& self, nb::args) {
             nb::gil_scoped_release release;
             self.close();
           });

  m.def(
      "export_flexiport",
      [](nb::handle source, nb::handle prefix, const std::string& format) {
        const std::string s = path_from_python(source);
        const std::string p = path_from_python(prefix);
        if (format != "new" && format != "old") {
          throw nb::value_error(("flexiport format '" + format +
                                 "': expected new (flexiport from 2008-07) or old")
                                    .c_str());
        }
        const FlexiportFormat layout =
            format == "old" ? FlexiportFormat::legacy : FlexiportFormat::modern;
        nb::gil_scoped_release release;
        return export_flexiport(s, p, layout);
      },
      "source"_a, "prefix"_a, "format"_a = "new",
      "Writes a session (.wtape or flexiport) as flexiport's logs PREFIX + 'r' (reads) "
      "and PREFIX + 'w' (writes), in its new format (from 2008-07) or the old one; "
      "events are dropped. A FIFO or a "
      "device there (through a symbolic link too) is written through. Returns the "
      "number of records written.");

  // Cassette rules (wiretape/cassette_names.hpp), for the pytest plugin.
  m.attr("MAX_CASSETTE_NAME_LENGTH") = testing::max_cassette_name_length;
  m.def("safe_file_name", &testing::safe_file_name, "name"_a,
        "NAME as a cassette's file name: runs of characters but ASCII letters, digits and "
        "._-=+ become one _, _ and . are trimmed; a name that changed or is longer than "
        "MAX_CASSETTE_NAME_LENGTH is cut to fit and ends with - and 12 hex digits of its "
        "SHA-1, so that distinct tests never share a cassette.");
  m.def("cassette_file_name", &testing::cassette_file_name, "test_name_parts"_a,
        "A test's cassette file name from its name's parts, outermost first (suite or "
        "class, then the test with its parameters): joined by '.', made safe, + '.wtape'.");
  m.def(
      "cassette_directory",
      [](nb::handle source_file, const std::string& directory) {
        return testing::cassette_directory(path_from_python(source_file), directory);
      },
      "source_file"_a, "directory"_a = "",
      "The folder of SOURCE_FILE's cassettes: <its dir>/recordings/<its stem>, or "
      "<DIRECTORY>/<its stem> when a directory is given.");
  m.def(
      "publish_recording",
      [](nb::handle recording, nb::handle cassette) {
        const std::string from = path_from_python(recording);
        const std::string to = path_from_python(cassette);
        nb::gil_scoped_release release;
        testing::publish_recording(from, to);
      },
      "recording"_a, "cassette"_a,
      "Moves a finished recording to CASSETTE, its header naming the cassette "
      "(log=<its file name>) instead of the temporary file RECORDING; a damaged "
      "recording, or one naming no such file, is moved as it is.");

  m.def(
      "crc32c",
      [](nb::bytes data, std::uint32_t crc) { return crc32c(data.c_str(), data.size(), crc); },
      "data"_a, "crc"_a = 0, "The CRC32C (Castagnoli) of data, continuing from crc.");
}

}  // namespace wiretape::python
