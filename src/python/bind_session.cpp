// wiretape.SessionReader, SessionWriter, Recorder, Record and export_flexiport:
// session files from Python (their header: bind_header.cpp). Records carry bytes; kinds are their names ("rx", "tx",
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

#include "posix/file_checks.hpp"
#include "python/bindings.hpp"
#include "python/text_caster.hpp"
#include "python/session_members.hpp"
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


FlushPolicy flush_policy(int flush_ms, bool fsync, const std::string& compress) {
  if (flush_ms < 0) throw nb::value_error("flush_ms must be >= 0");
  if (compress != "none" && compress != "zstd") {
    throw OptionError("compress", "compress='" + compress + "': expected none or zstd");
  }
  return FlushPolicy{std::chrono::milliseconds(flush_ms), fsync,
                     compress == "zstd" ? Compression::zstd : Compression::none};
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
      .def_prop_ro(
          "unfinished",
          [](PyReader& self) -> nb::object {
            const auto& unfinished = self.get().unfinished();
            if (!unfinished) return nb::none();
            nb::object cls = nb::module_::import_("wiretape._core").attr("SessionError");
            nb::object error = cls(std::string(unfinished->what()), unfinished->offset());
            error.attr("message") = std::string(unfinished->what());
            return error;
          },
          nb::for_getter(nb::sig("def unfinished(self, /) -> SessionError | None")),
          "None, or (not damage: a warning) a SessionError with .offset and .message when "
          "reading stopped at the end of a file still being written: every record before "
          "it was read")
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
             int flush_ms, bool fsync, std::size_t header_room, const std::string& compress,
             nb::kwargs members) {
            const FlushPolicy flush = flush_policy(flush_ms, fsync, compress);
            const SessionHeader written = header_to_write(header, members);
            const std::string p = path_from_python(path);
            new (self) PyWriter{};
            self->path = p;
            nb::gil_scoped_release release;
            self->writer = std::make_unique<SessionWriter>(p, written, flush, header_room);
          },
          "path"_a, "header"_a = nb::none(), nb::kw_only(), "flush_ms"_a = 100,
          "fsync"_a = false, "header_room"_a = std::size_t{0}, "compress"_a = "none",
          "members"_a,
          nb::sig("def __init__(self, path: str | os.PathLike[str] | bytes, "
                  "header: SessionHeader | None = None, *, flush_ms: int = 100, "
                  "fsync: bool = False, header_room: int = 0, compress: str = 'none', "
                  "**members: object) -> None"),
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
             int flush_ms, bool fsync, std::size_t header_room, const std::string& compress,
             nb::kwargs members) {
            const FlushPolicy flush = flush_policy(flush_ms, fsync, compress);
            const SessionHeader written = header_to_write(header, members);
            const std::string p = path_from_python(path);
            nb::gil_scoped_release release;
            new (self) Recorder(p, written, flush, header_room);
          },
          "path"_a, "header"_a = nb::none(), nb::kw_only(), "flush_ms"_a = 100,
          "fsync"_a = false, "header_room"_a = Recorder::default_header_room,
          "compress"_a = "none", "members"_a,
          nb::sig("def __init__(self, path: str | os.PathLike[str] | bytes, "
                  "header: SessionHeader | None = None, *, flush_ms: int = 100, "
                  "fsync: bool = False, header_room: int = 32768, compress: str = 'none', "
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
  m.def("recorded_device", &testing::recorded_device, "port_options"_a,
        "The device setting a cassette was recorded from, for the command that records it "
        "again: PORT_OPTIONS as its header keeps them without log=, name= and the test "
        "helpers' meta_gtest= and meta_pytest_node=; '' when none are kept.");
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
