// wiretape.SessionReader, SessionWriter, Record and export_flexiport: session
// files from Python. Records carry bytes; kinds are their names ("rx", "tx",
// "open", ... "break"); times are integer nanoseconds since the open.
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>

#include <nanobind/stl/map.h>
#include <nanobind/stl/vector.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>

#include "posix/file_checks.hpp"
#include "python/bindings.hpp"
#include "session/flexiport.hpp"
#include "session/format.hpp"
#include "session/header.hpp"
#include "session/reader.hpp"
#include "session/record_kinds.hpp"
#include "wiretape/errors.hpp"
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
    return std::string(PyBytes_AS_STRING(path.ptr()),
                       static_cast<std::size_t>(PyBytes_GET_SIZE(path.ptr())));
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
  if (capture == "client") return Capture::client;
  if (capture == "wire") return Capture::wire;
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
  out["metadata_json"] = header.metadata_json;
  return out;
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
          [](PyRecord* self, std::uint64_t t_ns, nb::handle kind, nb::bytes data) {
            new (self) PyRecord{};
            self->record.t_ns = t_ns;
            self->record.kind = kind_from_python(kind);
            self->record.data.assign(data.c_str(), data.size());
          },
          "t_ns"_a, "kind"_a, "data"_a = nb::bytes("", 0))
      .def_prop_ro("t_ns", [](const PyRecord& r) { return r.record.t_ns; },
                   "nanoseconds since the device was opened")
      .def_prop_ro("kind", [](const PyRecord& r) { return std::string(to_string(r.record.kind)); },
                   "'rx' (device to host), 'tx' (host to device), or an event name")
      .def_prop_ro("kind_code", [](const PyRecord& r) { return static_cast<int>(r.record.kind); })
      .def_prop_ro("data", [](const PyRecord& r) { return to_bytes(r.record.data); },
                   "the bytes (rx, tx) or the event's JSON object as bytes")
      .def("__eq__",
           [](const PyRecord& a, const PyRecord& b) {
             return a.record.t_ns == b.record.t_ns && a.record.kind == b.record.kind &&
                    a.record.data == b.record.data;
           })
      .def("__repr__", [](const PyRecord& r) {
        nb::object data = to_bytes(r.record.data);
        return "Record(t_ns=" + std::to_string(r.record.t_ns) + ", kind='" +
               std::string(to_string(r.record.kind)) + "', data=" +
               std::string(nb::repr(data).c_str()) + ")";
      });

  nb::class_<SessionHeader>(m, "SessionHeader",
                           "A session file's header (docs/session-format.md): what was "
                           "recorded, where, when and how. Read-only.")
      .def_ro("version_major", &SessionHeader::version_major, "the file's format version")
      .def_ro("version_minor", &SessionHeader::version_minor)
      .def_ro("port_options", &SessionHeader::port_options,
              "the option string the port was opened with")
      .def_ro("port_type", &SessionHeader::port_type, "serial, tcp, udp, pty, loopback, ...")
      .def_ro("start_utc", &SessionHeader::start_utc,
              "when the device was opened, ISO 8601 UTC")
      .def_ro("wiretape_version", &SessionHeader::wiretape_version,
              "the version of wiretape that wrote the file")
      .def_ro("host", &SessionHeader::host, "the recording machine's name")
      .def_prop_ro(
          "capture",
          [](const SessionHeader& h) { return std::string(detail::capture_name(h.capture)); },
          "'client' (library recording) or 'wire' (proxy recording)")
      .def_ro("source_format", &SessionHeader::source_format,
              "'wiretape' (recorded by wiretape) or the format it was imported from: "
              "'flexiport', 'pcap', 'reserial', 'umockdev', ...")
      .def_ro("source_files", &SessionHeader::source_files,
              "an imported session's original file names")
      .def_ro("source_details", &SessionHeader::source_details,
              "what else the import noted (the stream, the test, the logs' formats)")
      .def_ro("device_address", &SessionHeader::device_address,
              "host:port of a network device, when known")
      .def_ro("edits", &SessionHeader::edits, "what wiretape edit changed, in order")
      .def_ro("metadata", &SessionHeader::user_metadata, "the free user metadata (--meta)")
      .def_ro("metadata_json", &SessionHeader::metadata_json, "the header's JSON, as stored")
      .def("to_dict", &header_dict, "the fields above as a dict")
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

  nb::class_<PyReader>(m, "SessionReader",
                       "Reads a .wtape file or a flexiport log (name.log) record by record, "
                       "with memory independent of its size; a pipe or FIFO is read once, as "
                       "a stream, waiting for its writer (Ctrl-C ends the wait). Iterating yields Record objects; "
                       "at a damaged record iteration ends and .damage says where.")
      .def(
          "__init__",
          [](PyReader* self, nb::handle path) {
            const std::string p = path_from_python(path);
            new (self) PyReader{};
            nb::gil_scoped_release release;
            self->reader = std::make_unique<SessionReader>(p);
          },
          "path"_a)
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
          [](PyWriter* self, nb::handle path, const std::string& capture,
             const std::string& port_options, const std::string& port_type,
             std::optional<std::map<std::string, std::string>> metadata, int flush_ms,
             bool fsync, std::optional<std::string> start_utc, std::optional<std::string> host,
             const std::string& wiretape_version, const std::string& source_format,
             std::optional<std::vector<std::string>> source_files,
             std::optional<std::map<std::string, std::string>> source_details,
             const std::string& device_address,
             std::optional<std::vector<std::string>> edits) {
            SessionWriterOptions options;
            options.capture = capture_from_python(capture);
            options.port_options = port_options;
            options.port_type = port_type;
            if (metadata) options.metadata = *metadata;
            if (flush_ms < 0) throw nb::value_error("flush_ms must be >= 0");
            options.flush_ms = flush_ms;
            options.fsync = fsync;
            options.start_utc = std::move(start_utc);
            options.host = std::move(host);
            options.wiretape_version = wiretape_version;
            options.source_format = source_format;
            if (source_files) options.source_files = std::move(*source_files);
            if (source_details) options.source_details = std::move(*source_details);
            options.device_address = device_address;
            if (edits) options.edits = std::move(*edits);
            const std::string p = path_from_python(path);
            new (self) PyWriter{};
            self->path = p;
            nb::gil_scoped_release release;
            self->writer = std::make_unique<SessionWriter>(p, std::move(options));
          },
          "path"_a, nb::kw_only(), "capture"_a = "client", "port_options"_a = "",
          "port_type"_a = "", "metadata"_a = nb::none(), "flush_ms"_a = 100,
          "fsync"_a = false, "start_utc"_a = nb::none(), "host"_a = nb::none(),
          "wiretape_version"_a = "", "source_format"_a = "", "source_files"_a = nb::none(),
          "source_details"_a = nb::none(), "device_address"_a = "", "edits"_a = nb::none())
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

  m.def(
      "crc32c",
      [](nb::bytes data, std::uint32_t crc) { return crc32c(data.c_str(), data.size(), crc); },
      "data"_a, "crc"_a = 0, "The CRC32C (Castagnoli) of data, continuing from crc.");
}

}  // namespace wiretape::python
