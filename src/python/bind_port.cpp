// wiretape.open_port() and wiretape.Port: the C++ Port with bytes, float
// seconds and pyserial-like names.
//
// Every call that can block releases the GIL. Waits (reads, wait_readable)
// run in slices of signal_check_interval: between slices the GIL is taken
// back and Python's signal handlers run, so Ctrl-C interrupts a blocked read
// even when the port's timeout is None. Slicing never loses data: a read that
// times out consumes nothing.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <string>
#include <string_view>

#include <nanobind/stl/optional.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/unique_ptr.h>
#include <nanobind/stl/vector.h>

#include "replay/replay_port.hpp"

#include "python/bindings.hpp"
#include "python/text_caster.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"
#include "open/open_port.hpp"
#include "wiretape/port.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace wiretape::python {

// --- shared helpers ---------------------------------------------------------

namespace {

// A Python value of option_string()'s pairs as the C++ value it stands for;
// bool before int, which it is a subclass of.
OptionValue option_value_from_python(const std::string& key, nb::handle value) {
  if (PyBool_Check(value.ptr())) return value.ptr() == Py_True;
  if (PyLong_Check(value.ptr())) {
    int overflow = 0;
    const long long whole = PyLong_AsLongLongAndOverflow(value.ptr(), &overflow);
    if (whole == -1 && PyErr_Occurred()) throw nb::python_error();
    if (overflow != 0) {
      throw OptionError(key, "option '" + key + "': " + nb::str(value).c_str() +
                                 " is beyond a 64-bit whole number");
    }
    return static_cast<std::int64_t>(whole);
  }
  if (PyFloat_Check(value.ptr())) return PyFloat_AsDouble(value.ptr());
  if (PyUnicode_Check(value.ptr())) return nb::cast<std::string>(value);
  if (PyObject_HasAttrString(value.ptr(), "__fspath__")) {
    nb::object path = nb::module_::import_("os").attr("fspath")(value);
    if (PyUnicode_Check(path.ptr())) return nb::cast<std::string>(path);
  }
  throw nb::type_error(("option '" + key + "': a value must be str, int, float, bool or a "
                        "path, not " + nb::cast<std::string>(nb::type_name(value.type())))
                           .c_str());
}

std::string option_string_from_python(nb::iterable pairs) {
  std::vector<std::pair<std::string, OptionValue>> converted;
  for (nb::handle pair : pairs) {
    if (!PySequence_Check(pair.ptr()) || PyUnicode_Check(pair.ptr()) ||
        PySequence_Size(pair.ptr()) != 2) {
      throw nb::type_error("option_string() takes (key, value) pairs");
    }
    nb::sequence items = nb::borrow<nb::sequence>(pair);
    nb::object key = items[0];
    if (!PyUnicode_Check(key.ptr())) {
      throw nb::type_error(("an option key must be str, not " +
                            nb::cast<std::string>(nb::type_name(key.type())))
                               .c_str());
    }
    std::string name = nb::cast<std::string>(key);
    OptionValue value = option_value_from_python(name, items[1]);
    converted.emplace_back(std::move(name), std::move(value));
  }
  return option_string(converted);
}

}  // namespace

Timeout timeout_from_python(nb::handle value) {
  if (value.is_none()) return forever;
  double seconds = 0.0;
  if (PyFloat_Check(value.ptr()) || PyLong_Check(value.ptr())) {
    seconds = PyFloat_AsDouble(value.ptr());
    if (seconds == -1.0 && PyErr_Occurred()) throw nb::python_error();
  } else if (nb::hasattr(value, "total_seconds")) {  // datetime.timedelta
    seconds = nb::cast<double>(value.attr("total_seconds")());
  } else {
    throw nb::type_error(
        ("timeout must be None (block) or a number of seconds, not " +
         nb::cast<std::string>(nb::type_name(value.type())))
            .c_str());
  }
  if (std::isnan(seconds) || seconds < 0.0) {
    throw nb::value_error(
        ("timeout must be None (block) or >= 0 seconds, got " +
         std::string(nb::repr(value).c_str()))
            .c_str());
  }
  // Beyond ~31 years a deadline would overflow the clock: that is forever.
  if (seconds >= 1e9) return forever;
  return std::chrono::nanoseconds(static_cast<std::int64_t>(std::llround(seconds * 1e9)));
}

nb::object timeout_to_python(Timeout timeout) {
  if (!timeout) return nb::none();
  return nb::float_(std::chrono::duration<double>(*timeout).count());
}

void check_signals() {
  if (PyErr_CheckSignals() != 0) throw nb::python_error();
}

namespace {

// The per-call timeout: `...` (omitted) is the port's own.
Timeout call_timeout(const Port& port, nb::handle value) {
  if (value.is(nb::ellipsis())) return port.timeout();
  return timeout_from_python(value);
}

enum class Direction { reading, writing };

// Runs attempt(slice_end) with the GIL released until it returns true or
// `timeout` expires, checking Python's signals between slices. attempt must
// return by slice_end (it passes remaining(slice_end) to the port).
template <typename Attempt>
void run_in_slices(Port& port, Timeout timeout, Attempt&& attempt,
                   Direction direction = Direction::reading) {
  using Clock = std::chrono::steady_clock;
  // A first attempt that cannot wait (its deadline has passed), with the GIL
  // held: a read whose bytes are there already (a replay releases the
  // answer as the request is written) or a write the device takes at once
  // costs no GIL hand-over and no clock reading.
  if (attempt(Deadline(Clock::time_point{}))) return;  // the clock's epoch: long past
  const Deadline deadline = deadline_after(timeout);
  for (;;) {
    // A replay whose recording has ended raises PortClosed on a read that
    // would block forever; slices alone would hide that it is forever.
    if (direction == Direction::reading && !timeout &&
        detail::replay_read_would_block_forever(port)) {
      nb::gil_scoped_release release;
      attempt(Deadline());
      return;
    }
    Clock::time_point slice_end = Clock::now() + signal_check_interval;
    bool last = false;
    if (deadline && *deadline <= slice_end) {
      slice_end = *deadline;
      last = true;
    }
    bool done;
    {
      nb::gil_scoped_release release;
      done = attempt(Deadline(slice_end));
    }
    if (done || last) return;
    check_signals();
  }
}

// A read-only view of a bytes-like object (bytes, bytearray, memoryview...),
// valid while this lives; holding the buffer keeps it from being resized, so
// it may be used with the GIL released.
class ByteView {
 public:
  ByteView(nb::handle object, const char* what) {
    if (PyUnicode_Check(object.ptr())) {
      throw nb::type_error((std::string(what) +
                            " must be bytes-like, not str (encode it first)")
                               .c_str());
    }
    if (PyObject_GetBuffer(object.ptr(), &view_, PyBUF_SIMPLE) != 0) {
      PyErr_Clear();
      throw nb::type_error((std::string(what) + " must be bytes-like, not " +
                            nb::cast<std::string>(nb::type_name(object.type())))
                               .c_str());
    }
  }
  ~ByteView() { PyBuffer_Release(&view_); }
  ByteView(const ByteView&) = delete;
  ByteView& operator=(const ByteView&) = delete;

  const char* data() const { return static_cast<const char*>(view_.buf); }
  std::size_t size() const { return static_cast<std::size_t>(view_.len); }
  std::string_view view() const { return {data(), size()}; }

 private:
  Py_buffer view_{};
};

std::size_t byte_count(long long value, const char* what) {
  if (value < 0) {
    throw nb::value_error(
        (std::string(what) + " must be >= 0, got " + std::to_string(value)).c_str());
  }
  return static_cast<std::size_t>(value);
}

std::size_t optional_byte_count(nb::handle value, const char* what) {
  if (value.is_none()) return Port::unlimited;
  return byte_count(nb::cast<long long>(value), what);
}

// Reads never allocate more than this per call for read(size): a read
// returns what is there, so a smaller buffer changes nothing for the caller.
constexpr std::size_t max_read_chunk = 1 << 20;

nb::bytes to_bytes(const std::string& data) {
  return nb::bytes(data.data(), data.size());
}

nb::bytes read(Port& port, long long size, nb::handle timeout) {
  const std::size_t wanted = std::min(byte_count(size, "size"), max_read_chunk);
  const Timeout limit = call_timeout(port, timeout);
  if (wanted == 0) return nb::bytes("", 0);
  std::string buffer(wanted, '\0');
  std::size_t got = 0;
  run_in_slices(port, limit, [&](Deadline slice_end) {
    got = port.read(&buffer[0], buffer.size(), remaining(slice_end));
    return got > 0;
  });
  return nb::bytes(buffer.data(), got);
}

// Advances a compound read (C++ owns its logic) to the call's deadline in
// slices, so that Ctrl-C is seen; it stays one read for a log= recording.
// Interrupted, the read ends with what it consumed (recorded, not returned).
CompoundRead& advance_in_slices(Port& port, CompoundRead& read, Timeout limit) {
  if (!read.complete()) {
    run_in_slices(port, limit,
                  [&](Deadline slice_end) { return read.advance(slice_end); });
  }
  return read;
}

std::string delimiter_from(nb::handle object, const char* what) {
  ByteView view(object, what);
  return std::string(view.view());
}

nb::bytes read_exactly(Port& port, long long count, nb::handle timeout) {
  CompoundRead read = CompoundRead::exactly(port, byte_count(count, "count"));
  return to_bytes(advance_in_slices(port, read, call_timeout(port, timeout)).finish());
}

nb::bytes read_until(Port& port, nb::handle expected, nb::handle size,
                     nb::handle timeout) {
  CompoundRead read = CompoundRead::until(port, delimiter_from(expected, "expected"),
                                          optional_byte_count(size, "size"));
  return to_bytes(advance_in_slices(port, read, call_timeout(port, timeout)).finish());
}

nb::bytes read_line(Port& port, nb::handle size, nb::handle timeout) {
  CompoundRead read = CompoundRead::until(port, "\n", optional_byte_count(size, "size"));
  return to_bytes(advance_in_slices(port, read, call_timeout(port, timeout)).finish());
}

std::size_t skip(Port& port, long long count, nb::handle timeout) {
  CompoundRead read = CompoundRead::discard(port, byte_count(count, "count"));
  advance_in_slices(port, read, call_timeout(port, timeout)).finish();
  return read.consumed();
}

bool skip_until(Port& port, nb::handle delimiter_object, nb::handle timeout) {
  const std::string delimiter = delimiter_from(delimiter_object, "delimiter");
  if (delimiter.empty()) throw nb::value_error("delimiter must not be empty");
  CompoundRead read = CompoundRead::discard_until(port, delimiter);
  advance_in_slices(port, read, call_timeout(port, timeout)).finish();
  return read.found_delimiter();
}

bool wait_readable(Port& port, nb::handle timeout) {
  const Timeout limit = call_timeout(port, timeout);
  bool ready = false;
  run_in_slices(port, limit, [&](Deadline slice_end) {
    ready = port.wait_readable(remaining(slice_end));
    return ready;
  });
  return ready;
}

// Writes wait in slices too, so that Ctrl-C reaches a write to a device that
// does not drain (flow control held, a full pty) however long the timeout.
// `all`: go on until every byte is written (write_all), else stop after the
// first bytes the device took (write).
std::size_t write_in_slices(Port& port, nb::handle data, bool all) {
  ByteView view(data, "data");
  if (view.size() == 0) return port.write(view.data(), 0);
  std::size_t sent = 0;
  run_in_slices(
      port, port.timeout(),
      [&](Deadline slice_end) {
        const char* rest = view.data() + sent;
        const std::size_t left = view.size() - sent;
        sent += all ? port.write_all(rest, left, remaining(slice_end))
                    : port.write(rest, left, remaining(slice_end));
        return all ? sent == view.size() : sent > 0;
      },
      Direction::writing);
  return sent;
}

int fileno(const Port& port) {
  const int handle = port.native_handle();
  if (handle < 0) throw PortClosed(port.description() + ": the port is closed");
  return handle;
}

const char* access_name(Access access) {
  switch (access) {
    case Access::read_only: return "readonly";
    case Access::write_only: return "writeonly";
    case Access::read_write: break;
  }
  return "readwrite";
}


Parity parse_parity(const std::string& name) {
  for (Parity parity : {Parity::none, Parity::even, Parity::odd, Parity::mark,
                        Parity::space}) {
    if (name == to_string(parity)) return parity;
  }
  throw nb::value_error(("parity must be one of none, even, odd, mark, space; got '" +
                         name + "'")
                            .c_str());
}

FlowControl parse_flow(const std::string& name) {
  for (FlowControl flow :
       {FlowControl::none, FlowControl::rtscts, FlowControl::xonxoff}) {
    if (name == to_string(flow)) return flow;
  }
  throw nb::value_error(
      ("flow must be one of none, rtscts, xonxoff; got '" + name + "'").c_str());
}

nb::dict settings_dict(const SerialSettings& settings) {
  nb::dict result;
  result["baud"] = settings.baud;
  result["databits"] = settings.data_bits;
  result["stopbits"] = settings.stop_bits;
  result["parity"] = to_string(settings.parity);
  result["flow"] = to_string(settings.flow);
  return result;
}

void configure(Port& port, nb::handle baud, nb::handle databits,
               nb::handle stopbits, nb::handle parity, nb::handle flow) {
  SerialSettings settings = port.serial_settings();
  if (!baud.is_none()) {
    const long long value = nb::cast<long long>(baud);
    if (value <= 0 || value > 0xFFFFFFFFLL) {
      throw nb::value_error(("baud must be a positive rate, got " +
                             std::to_string(value)).c_str());
    }
    settings.baud = static_cast<unsigned>(value);
  }
  if (!databits.is_none()) {
    settings.data_bits = nb::cast<int>(databits);
    if (settings.data_bits < 5 || settings.data_bits > 8) {
      throw nb::value_error(("databits must be 5, 6, 7 or 8, got " +
                             std::to_string(settings.data_bits)).c_str());
    }
  }
  if (!stopbits.is_none()) {
    settings.stop_bits = nb::cast<int>(stopbits);
    if (settings.stop_bits != 1 && settings.stop_bits != 2) {
      throw nb::value_error(("stopbits must be 1 or 2, got " +
                             std::to_string(settings.stop_bits)).c_str());
    }
  }
  if (!parity.is_none()) settings.parity = parse_parity(nb::cast<std::string>(parity));
  if (!flow.is_none()) settings.flow = parse_flow(nb::cast<std::string>(flow));
  nb::gil_scoped_release release;
  port.configure(settings);
}

void send_break(Port& port, double duration) {
  if (std::isnan(duration) || duration < 0.0 || duration > 3600.0) {
    throw nb::value_error("duration must be between 0 and 3600 seconds");
  }
  const auto milliseconds =
      std::chrono::milliseconds(std::llround(duration * 1000.0));
  nb::gil_scoped_release release;
  port.send_break(milliseconds);
}

// The levels of DTR and RTS last set through a Python Port live in its
// instance dictionary: the C++ Port sets lines, it does not remember them.
constexpr const char dtr_attribute[] = "_wiretape_dtr";
constexpr const char rts_attribute[] = "_wiretape_rts";

bool modem_line(Port& port, bool (Port::*line)()) {
  nb::gil_scoped_release release;
  return (port.*line)();
}

bool output_line(nb::handle self, const char* attribute) {
  if (nb::hasattr(self, attribute)) return nb::cast<bool>(self.attr(attribute));
  // Never set: raises PortError(ENOTSUP) on a port without modem lines, as
  // setting it would.
  modem_line(nb::cast<Port&>(self), &Port::cts);
  return true;
}

void set_output_line(nb::handle self, bool level, void (Port::*set)(bool),
                     const char* attribute) {
  {
    Port& port = nb::cast<Port&>(self);
    nb::gil_scoped_release release;
    (port.*set)(level);
  }
  nb::setattr(self, attribute, nb::bool_(level));
}

bool dtr(nb::handle self) { return output_line(self, dtr_attribute); }
bool rts(nb::handle self) { return output_line(self, rts_attribute); }
void set_dtr(nb::handle self, bool level) {
  set_output_line(self, level, &Port::set_dtr, dtr_attribute);
}
void set_rts(nb::handle self, bool level) {
  set_output_line(self, level, &Port::set_rts, rts_attribute);
}

std::string repr(const Port& port) {
  return "<wiretape.Port " + port.description() +
         (port.is_open() ? "" : " (closed)") + ">";
}

constexpr const char port_doc[] = R"(A connection to a device: serial line, TCP, UDP,
pseudo-terminal, in-memory loopback, or a replayed recording. Made by open_port().

Reads follow wiretape's (C++) semantics: read(size) returns what is there,
at least one byte and at most size, or b"" when the timeout expires; the
compound reads (read_exactly, read_until, read_line, skip_until) return what
they have when the timeout expires and never raise on a timeout.

Every `timeout` argument is in seconds (a float, or a datetime.timedelta):
None blocks, 0 polls; omitted means
the port's own `timeout`. Ctrl-C interrupts a blocked read. One reader and
one writer may run at once on different threads; close() from another thread
wakes a blocked read, which then raises PortClosed.)";

// An integer, number or seconds key's smallest or largest valid value, as a
// Python int or float; None for the other value types.
nb::object range_end(const OptionKey& key, bool largest) {
  if (key.type == OptionType::integer) {
    return nb::int_(largest ? key.max_integer : key.min_integer);
  }
  if (key.type == OptionType::number || key.type == OptionType::seconds) {
    return nb::float_(largest ? key.max_number : key.min_number);
  }
  return nb::none();
}

// `text` as a port of `port_type` reads key `name`: the row's typed accessor
// checks it (type, range, choices) and gives the value.
nb::object option_value(std::string_view port_type, std::string_view name,
                        const std::string& text) {
  Options options;
  options.set(name, text);
  options.set_port_type(port_type);
  const OptionKey* row = find_option_key(name, port_type);
  if (row == nullptr) {
    throw OptionError(std::string(name), "option '" + std::string(name) +
                                             "' is not a key of type=" + std::string(port_type));
  }
  switch (row->type) {
    case OptionType::boolean: return nb::bool_(options.take_bool(name));
    case OptionType::integer: return nb::int_(options.take_int(name));
    case OptionType::number: return nb::float_(options.take_double(name));
    case OptionType::seconds: {
      const Timeout timeout = options.take_timeout(name);
      if (!timeout) return nb::none();
      return nb::float_(std::chrono::duration<double>(*timeout).count());
    }
    case OptionType::choice: return nb::str(options.take_choice(name).c_str());
    case OptionType::text:
    case OptionType::path: break;
  }
  return nb::str(options.take_string(name).c_str());
}

}  // namespace

void bind_port(nb::module_& m) {
  nb::class_<Port>(m, "Port", port_doc, nb::dynamic_attr())
      // --- reading ---------------------------------------------------------
      .def("read", &read,
           nb::sig("def read(self, size: int = 1, timeout: float | datetime.timedelta | None = ...) -> bytes"),
           "size"_a = 1, "timeout"_a.none() = nb::ellipsis(),
           "What is there, at least one byte and at most `size`; b\"\" when the "
           "timeout expires.")
      .def("read_exactly", &read_exactly,
           nb::sig("def read_exactly(self, count: int, timeout: float | datetime.timedelta | None = ...) -> bytes"),
           "count"_a, "timeout"_a.none() = nb::ellipsis(),
           "Exactly `count` bytes, or what came before the timeout expired.")
      .def("read_until", &read_until,
           nb::sig("def read_until(self, expected: bytes = b\"\\n\", size: int | None = None, "
                   "timeout: float | datetime.timedelta | None = ...) -> bytes"),
           "expected"_a = nb::bytes("\n", 1),
           "size"_a.none() = nb::none(), "timeout"_a.none() = nb::ellipsis(),
           "Up to and including `expected`, or `size` bytes, or what came "
           "before the timeout expired. Nothing past `expected` is consumed.")
      .def("read_line", &read_line,
           "size"_a.none() = nb::none(), "timeout"_a.none() = nb::ellipsis(),
           nb::sig("def read_line(self, size: int | None = None, "
                   "timeout: float | datetime.timedelta | None = ...) -> bytes"),
           "Up to and including b\"\\n\" (see read_until).")
      .def("skip", &skip,
           nb::sig("def skip(self, count: int, timeout: float | datetime.timedelta | None = ...) -> int"),
           "count"_a, "timeout"_a.none() = nb::ellipsis(),
           "Discards up to `count` bytes; returns how many were discarded.")
      .def("skip_until", &skip_until,
           nb::sig("def skip_until(self, delimiter: bytes, timeout: float | datetime.timedelta | None = ...) -> bool"),
           "delimiter"_a, "timeout"_a.none() = nb::ellipsis(),
           "Discards through `delimiter`; False if the timeout expired first.")
      .def("available", [](Port& port) { return port.available(); },
           "Bytes that a read would return at once.")
      .def_prop_ro("in_waiting", [](Port& port) { return port.available(); },
                   "Bytes that a read would return at once (pyserial's name).")
      .def("wait_readable", &wait_readable,
           nb::sig("def wait_readable(self, timeout: float | datetime.timedelta | None = ...) -> bool"),
           "timeout"_a.none() = nb::ellipsis(),
           "True once a read would not block (data, or the device is gone); "
           "False when the timeout expired.")
      // --- writing ---------------------------------------------------------
      .def("write", [](Port& port, nb::handle data) { return write_in_slices(port, data, false); }, nb::sig("def write(self, data: bytes) -> int"), "data"_a,
           "Writes what the device accepts, at least one byte, or 0 when the "
           "port's timeout expires; returns the count written.")
      .def("write_all", [](Port& port, nb::handle data) { return write_in_slices(port, data, true); }, nb::sig("def write_all(self, data: bytes) -> int"), "data"_a,
           "Writes everything; returns less than len(data) only when the "
           "port's timeout expired.")
      // --- buffers -----------------------------------------------------------
      .def("flush_input", &Port::flush_input, nb::call_guard<nb::gil_scoped_release>(),
           "Drops what was received and not yet read.")
      .def("flush_output", &Port::flush_output, nb::call_guard<nb::gil_scoped_release>(),
           "Drops what was written and not yet sent.")
      .def("drain", &Port::drain, nb::call_guard<nb::gil_scoped_release>(),
           "Waits until written data has left.")
      // --- state -------------------------------------------------------------
      .def_prop_rw(
          "timeout", [](const Port& port) { return timeout_to_python(port.timeout()); },
          [](Port& port, nb::handle value) { port.set_timeout(timeout_from_python(value)); },
          nb::arg("value").none(),
          nb::for_getter(nb::sig("def timeout(self) -> float | None")),
          nb::for_setter(nb::sig("def timeout(self, value: float | datetime.timedelta | None, /) -> None")),
          "The port's timeout in seconds (or a datetime.timedelta): None "
          "blocks, 0 polls.")
      .def("close", &Port::close, nb::call_guard<nb::gil_scoped_release>(),
           "Closes the port; a read blocked in another thread raises PortClosed.")
      .def_prop_ro("is_open", [](const Port& port) { return port.is_open(); })
      .def_prop_ro("description", [](const Port& port) { return port.description(); },
                   "Human-readable, e.g. 'serial /dev/ttyUSB0 @ 115200 8N1'.")
      .def_prop_ro("type", [](const Port& port) { return port.type(); },
                   "The port's type as in the option string: 'serial', 'tcp', ...")
      .def_prop_ro("left_unused", [](const Port& port) { return port.left_unused(); },
                   "A replay, once closed: what its client left of the recording, as "
                   "unused= words it ('' when it used it all), whatever unused= says; '' "
                   "before close() and for other ports.")
      .def_prop_ro("access", [](const Port& port) { return access_name(port.access()); },
                   "'readwrite', 'readonly' or 'writeonly'.")
      .def("fileno", &fileno,
           "A file descriptor that polls readable exactly when available() > 0 "
           "(for select, selectors, asyncio). Raises PortClosed after close().")
      .def("native_handle", [](const Port& port) { return port.native_handle(); },
           "As fileno(), but -1 after close().")
      // --- serial line control -------------------------------------------------
      .def("set_baud", [](Port& port, unsigned baud) {
             nb::gil_scoped_release release;
             port.set_baud(baud);
           }, "baud"_a)
      .def_prop_rw(
          "baud", [](const Port& port) { return port.serial_settings().baud; },
          [](Port& port, unsigned baud) {
            nb::gil_scoped_release release;
            port.set_baud(baud);
          },
          "The line rate; PortError (ENOTSUP) on a port without one.")
      .def("configure", &configure,
           nb::sig("def configure(self, *, baud: int | None = None, databits: int | None = None, "
                   "stopbits: int | None = None, parity: str | None = None, "
                   "flow: str | None = None) -> None"),
           nb::kw_only(), "baud"_a.none() = nb::none(),
           "databits"_a.none() = nb::none(), "stopbits"_a.none() = nb::none(),
           "parity"_a.none() = nb::none(), "flow"_a.none() = nb::none(),
           "Changes the given line settings, keeping the others.")
      .def("serial_settings",
           [](const Port& port) { return settings_dict(port.serial_settings()); },
           "The line settings: {'baud', 'databits', 'stopbits', 'parity', 'flow'}.")
      .def("set_dtr", &set_dtr, "level"_a, nb::sig("def set_dtr(self, level: bool) -> None"))
      .def("set_rts", &set_rts, "level"_a, nb::sig("def set_rts(self, level: bool) -> None"))
      .def_prop_rw("dtr", &dtr, &set_dtr,
                   "DTR: the level last set (True before any: the OS raises it at "
                   "open); settable.")
      .def_prop_rw("rts", &rts, &set_rts,
                   "RTS: the level last set (True before any: the OS raises it at "
                   "open); settable.")
      .def_prop_ro("cts", [](Port& port) { return modem_line(port, &Port::cts); },
                   "CTS as the device drives it.")
      .def_prop_ro("dsr", [](Port& port) { return modem_line(port, &Port::dsr); },
                   "DSR as the device drives it.")
      .def_prop_ro("ri", [](Port& port) { return modem_line(port, &Port::ri); },
                   "RI (ring indicator) as the device drives it.")
      .def_prop_ro("cd", [](Port& port) { return modem_line(port, &Port::cd); },
                   "CD (carrier detect) as the device drives it.")
      .def("send_break", &send_break, "duration"_a = 0.25,
           "Holds the line in break for `duration` seconds.")
      // --- context manager -----------------------------------------------------
      .def("__enter__", [](Port& port) -> Port& { return port; },
           nb::rv_policy::reference)
      .def("__exit__",
           [](Port& port, nb::handle, nb::handle, nb::handle) {
             nb::gil_scoped_release release;
             port.close();
           },
           nb::arg().none(), nb::arg().none(), nb::arg().none())
      .def("__repr__", &repr);

  m.def("open_port",
        [](const std::string& options) {
          nb::gil_scoped_release release;
          return open_port(std::string_view(options));
        },
        "options"_a,
        "Opens the port an option string describes, e.g. "
        "'type=serial,device=/dev/ttyUSB0,baud=115200'. Raises OptionError for "
        "a bad string, PortError when the device cannot be opened.");
  m.def("check_replay_options",
        [](const std::string& options) { detail::check_replay_options(options); },
        "options"_a,
        "Checks a replay's option string ('type=replay,file=...,timing=none') as "
        "open_port() would, opening nothing, not even the session file. Raises "
        "OptionError naming the key.");
  m.def("replay_speed_applies",
        [](const std::string& options) { return detail::replay_speed_applies(options); },
        "options"_a,
        "Whether a replay of these keys has something for speed= to scale: a clock "
        "(timing=session or causal) or an injected wait (delay, stall, trickle, "
        "reconnect). open_port() refuses speed= where it has not.");

  m.def("quote_option_value",
        [](std::string_view value) { return quote_option_value(value); }, "value"_a,
        "A value as it is written in an option string: as is, or in double "
        "quotes with \\\" and \\\\ escaped when it is empty or holds a "
        "separator, '=', '\"' or '\\\\'.");
  m.def("option_value", &option_value, "port_type"_a, "name"_a, "text"_a,
        nb::sig("def option_value(port_type: str, name: str, text: str) -> "
                "bool | int | float | str | None"),
        "`text` read as a port of `port_type` reads its key `name`, checked against "
        "the key table (type, range, choices): a bool, int, float (seconds: None "
        "for forever) or str. OptionError naming the key for a bad value or a key "
        "that is not one of the type's.");
  m.def("option_string", &option_string_from_python, "pairs"_a,
        nb::sig("def option_string(pairs: collections.abc.Iterable[tuple[str, str | int | "
                "float | bool | os.PathLike[str]]]) -> str"),
        "'key=value,...' of (key, value) pairs in order: values quoted as "
        "quote_option_value() quotes them, numbers and booleans written by the one "
        "rule of the C++ option strings (2.0 as 2, 0.25, 1e-06; True as true), a "
        "path as its text. parse_options() gives the pairs back (as text). Raises "
        "OptionError naming the key for a key that is not one, a key given twice, a "
        "NUL byte or a number that is not finite; TypeError for another type of value.");
  nb::class_<OptionKey>(m, "OptionKey",
                        "One row of the key table: a key of one or more port types "
                        "(docs/options.md).")
      .def_prop_ro("name", [](const OptionKey& key) { return key.name; },
                   "the key; with prefix, the prefix ('meta_' for meta_KEY)")
      .def_prop_ro("port_types",
                   [](const OptionKey& key) {
                     return std::vector<std::string>(key.port_types.begin(),
                                                     key.port_types.end());
                   },
                   "the port types the key applies to")
      .def_prop_ro("type", [](const OptionKey& key) { return std::string(to_string(key.type)); },
                   "boolean, integer, number, seconds, choice, text or path")
      .def_prop_ro("choices",
                   [](const OptionKey& key) {
                     return std::vector<std::string>(key.choices.begin(), key.choices.end());
                   },
                   "the valid values of a choice")
      .def_prop_ro("default",
                   [](const OptionKey& key) -> std::optional<std::string> {
                     if (key.default_value.empty()) return std::nullopt;
                     return std::string(key.default_value);
                   },
                   "the value when the key is not given, as written in an option "
                   "string; None when it has none")
      .def_prop_ro("required", [](const OptionKey& key) { return key.required; })
      .def_prop_ro("prefix", [](const OptionKey& key) { return key.prefix; },
                   "the key stands for every key starting with name (meta_KEY)")
      .def_prop_ro("minimum", [](const OptionKey& key) { return range_end(key, false); },
                   "the smallest valid integer, number or seconds; None for other types")
      .def_prop_ro("maximum", [](const OptionKey& key) { return range_end(key, true); },
                   "the largest valid integer, number or seconds; None for other types")
      .def_prop_ro("alias_of", [](const OptionKey& key) { return key.alias_of; },
                   "the key this is flexiport's name of; '' when none")
      .def_prop_ro("flag", [](const OptionKey& key) { return key.flag; },
                   "the wiretape CLI flag that mirrors the key; '' when none")
      .def_prop_ro("help", [](const OptionKey& key) { return key.help; })
      .def("applies_to", &OptionKey::applies_to, "port_type"_a)
      .def("__repr__", [](const OptionKey& key) {
        return "<OptionKey " + std::string(key.name) + " of " +
               std::string(key.port_types.front()) + (key.port_types.size() > 1 ? ", ...>" : ">");
      });
  m.def("option_keys", [] { return option_keys(); },
        "Every key of every port type (the key table), common keys first.");
  m.def("port_types",
        [] { return std::vector<std::string>(port_types().begin(), port_types().end()); },
        "The port types an option string can open (type= after flexiport's spellings).");
  m.def("parse_options",
        [](std::string_view text) {
          std::vector<std::pair<std::string, std::string>> pairs;
          for (auto& entry : parse_options(text)) {
            pairs.emplace_back(std::move(entry.key), std::move(entry.value));
          }
          return pairs;
        },
        "text"_a,
        "An option string's (key, value) pairs in order, values unquoted, a bare "
        "key as '1'. Raises OptionError as open_port() would for bad syntax (a "
        "key given twice included).");
  m.def("suggest_key",
        [](std::string_view name, std::string_view port_type) {
          return suggest_key(name, port_type);
        },
        "name"_a, "port_type"_a,
        "The key of port_type nearest to the unknown name (a typo), or None.");
  m.def("device_options",
        [](std::string_view device) { return device_options(device); }, "device"_a,
        "The option string a device setting stands for: a bare path (no '=') "
        "means type=serial,device=PATH; an option string is returned as given. "
        "Raises OptionError when the setting is empty.");
}

}  // namespace wiretape::python
