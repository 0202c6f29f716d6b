// The header's start_utc as the session model reads and writes it
// (session/header.hpp), for the exports' clocks and the capture importers:
// no Python module does calendar arithmetic on it.
#include <cstdint>
#include <optional>
#include <string>

#include <nanobind/nanobind.h>
#include <nanobind/stl/optional.h>

#include "python/bindings.hpp"
#include "python/text_caster.hpp"
#include "session/header.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace wiretape::python {

void bind_start_utc(nb::module_& m) {
  m.def("parse_start_utc", &detail::start_utc_epoch_ns, "text"_a,
        "A header's start_utc (2026-11-23T10:00:00.123456Z) as ns since the epoch; None "
        "for '' (not known). Raises OptionError naming start_utc and saying why for text "
        "the header does not allow.");
  m.def(
      "format_start_utc",
      [](std::int64_t epoch_ns) {
        const auto text = detail::format_start_utc(epoch_ns);
        if (!text) {
          const std::string message =
              "start_utc: " + std::to_string(epoch_ns) + " ns since 1970 is outside the years " +
              std::to_string(detail::min_start_year) + " to " +
              std::to_string(detail::max_start_year) + " a session header can hold";
          throw nb::value_error(message.c_str());
        }
        return *text;
      },
      "epoch_ns"_a,
      "EPOCH_NS (ns since 1970, UTC) as a header's start_utc, with nine digits of "
      "fraction (2026-11-23T10:00:00.123456789Z). Raises ValueError when it is outside the "
      "years a header can hold.");
}

}  // namespace wiretape::python
