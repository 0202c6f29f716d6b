// Fault plans from Python (DESIGN.md section 17): faults= parsed by the
// replay's own parser, and the table of fault kinds, so that campaigns
// (python/wiretape/faults.py) never split a plan themselves.
#include <optional>
#include <string>
#include <vector>

#include <nanobind/stl/optional.h>
#include <nanobind/stl/vector.h>

#include "open/port_types.hpp"
#include "python/bindings.hpp"
#include "python/text_caster.hpp"
#include "replay/exchanges.hpp"
#include "replay/faults.hpp"
#include "wiretape/options.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace wiretape::python {

namespace {

using detail::FaultAmount;
using detail::FaultKindInfo;
using detail::FaultPlan;
using detail::FaultSpec;

const char* amount_name(FaultAmount amount) {
  switch (amount) {
    case FaultAmount::none:
      return "none";
    case FaultAmount::optional:
      return "optional";
    case FaultAmount::required:
      return "required";
  }
  return "none";
}

std::string spec_repr(const FaultSpec& spec) {
  return "<FaultSpec " + spec.kind_text + "@" + spec.where_text + ">";
}

}  // namespace

void bind_faults(nb::module_& m) {
  nb::class_<FaultKindInfo>(m, "FaultKind", "A kind of fault (docs/faults.md).")
      .def_prop_ro("name", [](const FaultKindInfo& info) { return std::string(info.name); },
                   "Its name in KIND (drop, delay, ...).")
      .def_prop_ro("amount",
                   [](const FaultKindInfo& info) { return std::string(amount_name(info.amount)); },
                   "Whether it takes ':N': 'none', 'optional' or 'required'.")
      .def_prop_ro("campaign", &detail::campaign_kind_text,
                   "The KIND a campaign injects (delay:500 for delay, drop for drop).")
      .def("__repr__", [](const FaultKindInfo& info) {
        return "<FaultKind " + detail::campaign_kind_text(info) + ">";
      });

  nb::class_<FaultSpec>(m, "FaultSpec", "One KIND@WHERE of a fault plan.")
      .def_prop_ro(
          "kind", [](const FaultSpec& spec) { return std::string(detail::fault_kind_info(spec.kind).name); },
          "The kind's name (drop, corrupt, ...).")
      .def_ro("amount", &FaultSpec::amount, "The :N or :MS given, or None.")
      .def_prop_ro(
          "where", [](const FaultSpec& spec) { return std::string(detail::fault_place_info(spec.where).name); },
          "The place's name: exchange, rx, t, every or p.")
      .def_prop_ro(
          "number",
          [](const FaultSpec& spec) -> std::optional<std::uint64_t> {
            if (!detail::fault_place_info(spec.where).counted) return std::nullopt;
            return spec.where_number;
          },
          "N of exchange:N, rx:N and every:N; None for t: and p:.")
      .def_prop_ro(
          "value",
          [](const FaultSpec& spec) -> std::optional<double> {
            if (detail::fault_place_info(spec.where).counted) return std::nullopt;
            return spec.where_value;
          },
          "The seconds of t: or the probability of p:; None for the others.")
      .def_ro("kind_text", &FaultSpec::kind_text, "KIND in its normal spelling (corrupt:4).")
      .def_ro("where_text", &FaultSpec::where_text,
              "WHERE in its normal spelling (exchange:3; exchange:3@channel:gps).")
      .def_ro("channel", &FaultSpec::channel,
              "The channel of @channel:NAME; \"\" for a fault of every channel.")
      .def_ro("text", &FaultSpec::text, "The item as written (without surrounding spaces).")
      .def("__repr__", &spec_repr);

  nb::class_<FaultPlan>(m, "FaultPlan", "faults= parsed: its items in order, and the seed.")
      .def_ro("faults", &FaultPlan::faults, "The items (FaultSpec), in order.")
      .def_ro("seed", &FaultPlan::seed, "seed=, for the faults' random choices.")
      .def(
          "check_against",
          [](const FaultPlan& plan, const std::string& path,
             const std::optional<std::string>& profile, const std::optional<std::string>& match,
             const std::string& options) {
            Options keys = Options::parse(options);
            if (profile) keys.set("profile", *profile);
            if (match) keys.set("match", *match);
            const std::string text = keys.to_string();
            nb::gil_scoped_release release;
            plan.check_against(
                detail::session_places_file(path, text, detail::datagram_port_types()));
          },
          "path"_a, "profile"_a = nb::none(), "match"_a = nb::none(), "options"_a = "",
          "Raises OptionError (key 'faults') for a fault naming a channel the session "
          "file at `path` lacks, or placed past the end of what its replay (with "
          "profile=, match= and further replay keys `options`) serves: exchange:N, rx:N, "
          "t:S (after the last rx recorded on the session's clock); a fault without "
          "@channel: past every channel's end.")
      .def("__len__", [](const FaultPlan& plan) { return plan.faults.size(); })
      // Iterable by the sequence protocol (__getitem__ to IndexError): an
      // __iter__ of make_iterator would add a class to FaultPlan on first use.
      .def("__getitem__",
           [](const FaultPlan& plan, std::size_t index) -> const FaultSpec& {
             if (index >= plan.faults.size()) throw nb::index_error("fault plan index out of range");
             return plan.faults[index];
           },
           nb::rv_policy::reference_internal)
      .def("__repr__", [](const FaultPlan& plan) {
        std::string text = "<FaultPlan";
        for (const FaultSpec& spec : plan.faults) text += " " + spec.kind_text + "@" + spec.where_text;
        return text + " seed=" + std::to_string(plan.seed) + ">";
      });

  m.def(
      "fault_kinds",
      [] { return std::vector<FaultKindInfo>(std::begin(detail::kFaultKinds), std::end(detail::kFaultKinds)); },
      "Every fault kind, in the order a campaign injects them.");
  m.def("parse_faults", &detail::parse_faults, "text"_a, "seed"_a = 0,
        "Parses faults= (KIND@WHERE[;KIND@WHERE...]) as a replay does. Raises OptionError "
        "naming the key 'faults', the item and the grammar.");
  m.def("normal_fault_kind", &detail::normal_fault_kind, "kind"_a,
        "One KIND (drop, corrupt:4, delay:500) in its normal spelling. Raises OptionError "
        "naming the kind and the grammar.");
}

}  // namespace wiretape::python
