// wiretape's exceptions as Python classes, and the translator that turns the
// C++ exceptions into them. The classes are written in Python (below) because
// each derives from the built-in exception a Python user would catch
// (ValueError, OSError, AssertionError) and carries attributes; nanobind's
// nb::exception<T> gives neither.
#include <cstring>
#include <exception>
#include <string>

#include <nanobind/eval.h>

#include "python/bindings.hpp"
#include "python/text_caster.hpp"
#include "wiretape/errors.hpp"

namespace nb = nanobind;

namespace wiretape::python {

namespace {

constexpr const char exception_classes[] = R"PY(
class OptionError(ValueError):
    """A bad option string: unknown key, bad value, or a key that does not
    apply to the port type. ``key`` names the offending key ("" when the
    problem is the syntax of the string)."""

    def __init__(self, message="", key=""):
        super().__init__(message)
        self.key = key

    def __reduce__(self):
        return (type(self), (str(self), self.key))


class PortError(OSError):
    """An operating-system error on a port. ``errno`` is the error number
    (None when the failure did not come from the OS); ``str()`` is the full
    message naming the port and what failed."""

    def __str__(self):
        if len(self.args) == 2 and self.strerror is not None:
            return str(self.strerror)
        return super().__str__()

    def __reduce__(self):
        return (type(self), self.args)


class PortClosed(PortError):
    """The device went away (EOF, ENXIO, ECONNRESET, a recorded close on
    replay) or the port was closed, possibly from another thread while a
    call was blocked."""


class ReplayMismatch(AssertionError):
    """What a replayed client wrote differs from the recording. ``str()`` is
    the full report (offset, session time, expected and actual bytes as
    hex+ASCII, exchange); ``tx_offset`` is the byte offset in the recorded tx
    stream, ``session_time_ns`` the session time in ns, ``exchange`` the
    exchange number (0-based: in request mode the matched exchange, in sequence
    mode the run of recorded writes), or None where there is none."""

    def __init__(self, message="", tx_offset=0, session_time_ns=0, exchange=None):
        super().__init__(message)
        self.tx_offset = tx_offset
        self.session_time_ns = session_time_ns
        self.exchange = exchange

    def __reduce__(self):
        return (type(self), (str(self), self.tx_offset, self.session_time_ns, self.exchange))


class SessionError(ValueError):
    """A session file that cannot be read: bad magic, newer major version, a
    truncated or corrupt record. ``offset`` is the byte offset of the
    problem in the file."""

    def __init__(self, message="", offset=0):
        super().__init__(message)
        self.offset = offset

    def __reduce__(self):
        return (type(self), (str(self), self.offset))


for _cls in (OptionError, PortError, PortClosed, ReplayMismatch, SessionError):
    _cls.__module__ = "wiretape"
del _cls
)PY";

// Strong references, deliberately never released: the classes live as long
// as the interpreter, and a static nb::object would be destroyed after it.
struct ExceptionClasses {
  PyObject* option_error = nullptr;
  PyObject* port_error = nullptr;
  PyObject* port_closed = nullptr;
  PyObject* replay_mismatch = nullptr;
  PyObject* session_error = nullptr;
};
ExceptionClasses classes;

PyObject* keep(nb::dict& scope, const char* name) {
  nb::object cls = scope[name];
  return cls.release().ptr();
}

// Raises `cls(*args)` as the current Python error.
void set_error(PyObject* cls, nb::tuple args) {
  PyObject* instance = PyObject_CallObject(cls, args.ptr());
  if (instance == nullptr) return;  // the call set an error of its own
  PyErr_SetObject(cls, instance);
  Py_DECREF(instance);
}

nb::object errno_value(const PortError& error) {
  const int value = error.code().value();
  if (value == 0) return nb::none();
  return nb::int_(value);
}

// An error message as str: bytes that are not UTF-8 (a file name, text a
// profile of one's own made from device bytes) as \xNN, so that the error
// raised is the one thrown, never a conversion error.
nb::object message_text(const char* message) {
  PyObject* text = PyUnicode_DecodeUTF8(message, static_cast<Py_ssize_t>(std::strlen(message)),
                                        "backslashreplace");
  if (text == nullptr) throw nb::python_error();
  return nb::steal(text);
}

void translate(const std::exception_ptr& exception, void*) {
  try {
    std::rethrow_exception(exception);
  } catch (const PortClosed& error) {
    set_error(classes.port_closed,
              nb::make_tuple(errno_value(error), message_text(error.what())));
  } catch (const PortError& error) {
    set_error(classes.port_error,
              nb::make_tuple(errno_value(error), message_text(error.what())));
  } catch (const OptionError& error) {
    set_error(classes.option_error, nb::make_tuple(message_text(error.what()), error.key()));
  } catch (const ReplayMismatch& error) {
    nb::object exchange = error.exchange() < 0
                              ? nb::none()
                              : nb::object(nb::int_(error.exchange()));
    set_error(classes.replay_mismatch,
              nb::make_tuple(message_text(error.what()), error.tx_offset(),
                             error.session_time_ns(), exchange));
  } catch (const SessionError& error) {
    set_error(classes.session_error,
              nb::make_tuple(message_text(error.what()), error.offset()));
  }
  // Anything else propagates to the next translator.
}

}  // namespace

void bind_errors(nb::module_& m) {
  nb::dict scope;
  scope["__builtins__"] = nb::borrow(PyEval_GetBuiltins());
  scope["__name__"] = "wiretape";
  nb::exec(exception_classes, scope);
  classes.option_error = keep(scope, "OptionError");
  classes.port_error = keep(scope, "PortError");
  classes.port_closed = keep(scope, "PortClosed");
  classes.replay_mismatch = keep(scope, "ReplayMismatch");
  classes.session_error = keep(scope, "SessionError");
  m.attr("OptionError") = nb::borrow(classes.option_error);
  m.attr("PortError") = nb::borrow(classes.port_error);
  m.attr("PortClosed") = nb::borrow(classes.port_closed);
  m.attr("ReplayMismatch") = nb::borrow(classes.replay_mismatch);
  m.attr("SessionError") = nb::borrow(classes.session_error);
  nb::register_exception_translator(translate);
}

}  // namespace wiretape::python
