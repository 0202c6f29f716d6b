// What bind_session.cpp and bind_header.cpp share: the header a writer or a
// recorder writes, made from Python's members, and type names for messages.
#pragma once

#include <optional>
#include <string>

#include <nanobind/nanobind.h>

#include "wiretape/session.hpp"

namespace wiretape::python {

// The Python type name of `value`, for error messages.
std::string python_type_name(nanobind::handle value);

// What SessionWriter and Recorder write: `header`, or with none a session
// recorded now on this machine, with `members` set (checked: a member
// SessionHeader lacks, or of the wrong type, is an error naming it).
SessionHeader header_to_write(const std::optional<SessionHeader>& header,
                              nanobind::kwargs members);

}  // namespace wiretape::python
