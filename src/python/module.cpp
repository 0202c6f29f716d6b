// wiretape._core: the C++ library as seen from Python. The thin package in
// python/wiretape/ re-exports it; each bind_*.cpp file binds one area.
#include <cstdlib>

#include <nanobind/nanobind.h>

#include "python/bindings.hpp"
#include "wiretape/version.hpp"

namespace nb = nanobind;

NB_MODULE(_core, m) {
  m.doc() = "wiretape's C++ core";
  m.attr("__version__") = wiretape::version;
  // A port still held at exit by a daemon thread blocked in read() is not a
  // leak worth a screenful of warnings; WIRETAPE_DEBUG_LEAKS=1 turns them on
  // when hunting reference-counting bugs.
  nb::set_leak_warnings(std::getenv("WIRETAPE_DEBUG_LEAKS") != nullptr);
  wiretape::python::bind_errors(m);
  wiretape::python::bind_port(m);
  wiretape::python::bind_header(m);
  wiretape::python::bind_session(m);
  wiretape::python::bind_bridge(m);
  wiretape::python::bind_attach(m);
  wiretape::python::bind_profile(m);
  wiretape::python::bind_util(m);
  wiretape::python::bind_exchanges(m);
  wiretape::python::bind_faults(m);
  wiretape::python::bind_fuzzing(m);
  wiretape::python::bind_record_check(m);
  wiretape::python::bind_start_utc(m);
}
