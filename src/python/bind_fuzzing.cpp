// Fuzzing plans from Python (DESIGN.md section 27): FuzzedReplay, the
// recording read once that each plan (bytes from atheris or `wiretape fuzz`)
// mutates into a replay Port or a written session. wiretape.fuzzing is the
// Python face of it.
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <nanobind/stl/unique_ptr.h>
#include <nanobind/stl/vector.h>

#include "python/bindings.hpp"
#include "python/text_caster.hpp"
#include "wiretape/fuzzing.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace wiretape::python {

namespace {

std::string_view plan_of(const nb::bytes& plan) { return {plan.c_str(), plan.size()}; }

}  // namespace

void bind_fuzzing(nb::module_& m) {
  nb::class_<FuzzedReplay>(m, "FuzzedReplay",
                           "A recording read once, that fuzzing plans mutate (docs/fuzzing.md): "
                           "open(plan) a replay Port of it, write(path, plan) a .wtape session.")
      .def(nb::init<const std::string&, const std::string&, const std::string&>(), "session"_a,
           "profile"_a = "", "options"_a = "",
           "session: the recording; profile: a profile name whose frames plans mutate ('' : "
           "plans act on rx records); options: replay keys over the fuzzing defaults "
           "timing=none,at_end=closed,unused=ignore. OptionError for bad options or a profile "
           "that does not fit the recording; SessionError for a session with no device bytes.")
      .def(
          "open",
          [](const FuzzedReplay& replay, const nb::bytes& plan) { return replay.open(plan_of(plan)); },
          "plan"_a, "A replay Port of the recording mutated by `plan` (any bytes).")
      .def(
          "edits", [](const FuzzedReplay& replay, const nb::bytes& plan) { return replay.edits(plan_of(plan)); },
          "plan"_a, "What `plan` changes, one line a change; [] for a plan that changes nothing.")
      .def(
          "write",
          [](const FuzzedReplay& replay, const std::string& path, const nb::bytes& plan) {
            return replay.write(path, plan_of(plan));
          },
          "path"_a, "plan"_a,
          "Writes the recording mutated by `plan` as a .wtape session at `path` (the edits "
          "appended to its header's edits); returns the edits.")
      .def(
          "inert", [](const FuzzedReplay& replay, const nb::bytes& plan) { return replay.inert(plan_of(plan)); },
          "plan"_a,
          "Whether `plan` only splits frames across reads or delays them within the replay's "
          "tolerance: a driver failing on it, even with a clean error, has a finding.")
      .def_prop_ro("units", &FuzzedReplay::units,
                   "How many rx frames (with a profile) or rx records a plan's steps index.");
}

}  // namespace wiretape::python
