// How text crosses between Python and C++: the std::string and
// std::string_view casters of every binding, in place of nanobind's own
// (nanobind/stl/string.h and string_view.h, which no binding includes: the
// two together do not compile).
//
// A Python str goes to C++ as its UTF-8, with the lone surrogates that
// Python's surrogateescape makes of bytes that are not UTF-8 (PEP 383: how
// os.listdir, sys.argv and os.fsdecode hold a file name such as
// b"n\xff.wtape") as the bytes they stand for; a std::string comes back
// decoded the same way. So a path that is not UTF-8 reaches the file
// system as the bytes it names, in a path argument and inside an option
// string (file=..., log=...) alike, and text that is UTF-8 crosses as
// before. Where a value must be UTF-8 (a session header, a recorded port's
// options), C++ refuses what is not, naming it.
#pragma once

#include <nanobind/nanobind.h>

#include <string>
#include <string_view>

NAMESPACE_BEGIN(NB_NAMESPACE)
NAMESPACE_BEGIN(detail)

// The bytes a str stands for: its UTF-8, or (lone surrogates) the bytes
// surrogateescape encodes, held by `*owner` (a new reference), which the
// caller releases. Null, with no Python error set, for what is not a str or
// holds a surrogate no byte stands for.
inline const char* wiretape_text_bytes(handle src, Py_ssize_t* size, PyObject** owner) noexcept {
  *owner = nullptr;
  if (!PyUnicode_Check(src.ptr())) return nullptr;
  if (const char* text = PyUnicode_AsUTF8AndSize(src.ptr(), size)) return text;
  PyErr_Clear();
  PyObject* bytes = PyUnicode_AsEncodedString(src.ptr(), "utf-8", "surrogateescape");
  if (bytes == nullptr) {
    PyErr_Clear();
    return nullptr;
  }
  *owner = bytes;
  *size = PyBytes_Size(bytes);
  return PyBytes_AsString(bytes);
}

inline handle wiretape_text_of(const char* data, std::size_t size) noexcept {
  return PyUnicode_DecodeUTF8(data, static_cast<Py_ssize_t>(size), "surrogateescape");
}

template <>
struct type_caster<std::string> {
  NB_TYPE_CASTER(std::string, const_name("str"))

  bool from_python(handle src, uint32_t, cleanup_list*) noexcept {
    Py_ssize_t size = 0;
    PyObject* owner = nullptr;
    const char* text = wiretape_text_bytes(src, &size, &owner);
    if (text == nullptr) return false;
    value.assign(text, static_cast<std::size_t>(size));
    Py_XDECREF(owner);
    return true;
  }

  static handle from_cpp(const std::string& value, rv_policy, cleanup_list*) noexcept {
    return wiretape_text_of(value.data(), value.size());
  }
};

template <>
struct type_caster<std::string_view> {
  NB_TYPE_CASTER(std::string_view, const_name("str"))

  // A view needs its bytes to outlive the call: a str's own UTF-8 does; the
  // bytes of surrogateescape go to the call's cleanup list (none outside a
  // call: such a str is then refused).
  bool from_python(handle src, uint32_t, cleanup_list* cleanup) noexcept {
    Py_ssize_t size = 0;
    PyObject* owner = nullptr;
    const char* text = wiretape_text_bytes(src, &size, &owner);
    if (text == nullptr) return false;
    if (owner != nullptr) {
      if (cleanup == nullptr) {
        Py_DECREF(owner);
        return false;
      }
      cleanup->append(owner);  // the list takes the reference
    }
    value = std::string_view(text, static_cast<std::size_t>(size));
    return true;
  }

  static handle from_cpp(std::string_view value, rv_policy, cleanup_list*) noexcept {
    return wiretape_text_of(value.data(), value.size());
  }
};

NAMESPACE_END(detail)
NAMESPACE_END(NB_NAMESPACE)
