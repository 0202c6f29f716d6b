// One function per area of the API; module.cpp calls them in order (errors
// first: the others translate exceptions into its classes).
#pragma once

#include <nanobind/nanobind.h>

namespace wiretape::python {

void bind_errors(nanobind::module_& m);   // bind_errors.cpp
void bind_port(nanobind::module_& m);     // bind_port.cpp
void bind_session(nanobind::module_& m);  // bind_session.cpp
void bind_bridge(nanobind::module_& m);   // bind_bridge.cpp: proxy, serve, virtual devices

}  // namespace wiretape::python
