// wiretape._core: the C++ library as seen from Python. The thin package in
// python/wiretape/ re-exports it; each bind_*.cpp file binds one area.
#include <nanobind/nanobind.h>

#include "python/bindings.hpp"
#include "wiretape/version.hpp"

namespace nb = nanobind;

NB_MODULE(_core, m) {
  m.doc() = "wiretape's C++ core";
  m.attr("__version__") = wiretape::version;
  wiretape::python::bind_errors(m);
  wiretape::python::bind_port(m);
  wiretape::python::bind_session(m);
  wiretape::python::bind_bridge(m);
}
