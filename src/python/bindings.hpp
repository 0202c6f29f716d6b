// One function per area of the API; module.cpp calls them in order (errors
// first: the others translate exceptions into its classes).
#pragma once

#include <nanobind/nanobind.h>

#include "wiretape/timeout.hpp"

namespace wiretape::python {

void bind_errors(nanobind::module_& m);   // bind_errors.cpp
void bind_port(nanobind::module_& m);     // bind_port.cpp
void bind_session(nanobind::module_& m);  // bind_session.cpp: reader, writer, recorder
void bind_header(nanobind::module_& m);   // bind_header.cpp: SessionHeader, Channel
void bind_bridge(nanobind::module_& m);   // bind_bridge.cpp: proxy, serve, virtual devices
void bind_attach(nanobind::module_& m);   // bind_attach.cpp: recording a running program
void bind_profile(nanobind::module_& m);  // bind_profile.cpp: protocol profiles
void bind_util(nanobind::module_& m);     // bind_util.cpp: hex_ascii, escape_bytes
void bind_exchanges(nanobind::module_& m);  // bind_exchanges.cpp: session_exchanges
void bind_fuzzing(nanobind::module_& m);  // bind_fuzzing.cpp: FuzzedReplay
void bind_faults(nanobind::module_& m);   // bind_faults.cpp: fault plans and kinds
void bind_record_check(nanobind::module_& m);  // bind_record_check.cpp: verify's walk
void bind_start_utc(nanobind::module_& m);  // bind_start_utc.cpp: start_utc parse, format

// Helpers shared by the bindings (bind_port.cpp).

// A Python timeout: None blocks (wiretape::forever), a number is seconds
// (0 polls). Raises ValueError for a negative or NaN number, TypeError for
// anything else.
Timeout timeout_from_python(nanobind::handle value);
nanobind::object timeout_to_python(Timeout timeout);

// Runs Python's signal handlers (Ctrl-C); throws nanobind::python_error when
// one raised. Call with the GIL held, between slices of a blocking wait.
void check_signals();

// How long a blocking call waits with the GIL released before it looks at
// Python's signals again.
inline constexpr std::chrono::milliseconds signal_check_interval{50};

}  // namespace wiretape::python
