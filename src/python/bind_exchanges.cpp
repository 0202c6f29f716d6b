// The one segmentation of a session into exchanges and client sessions
// (replay/exchanges.hpp), for the Python tools that count or cut sessions:
// wiretape.faults, `wiretape edit --cut Ne`, the exports.
#include <string>
#include <utility>
#include <vector>

#include <nanobind/nanobind.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "open/port_types.hpp"
#include "python/bindings.hpp"
#include "replay/exchanges.hpp"
#include "wiretape/options.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace wiretape::python {

namespace {

nb::list bytes_list(const std::vector<std::string>& items) {
  nb::list out;
  for (const std::string& item : items) out.append(nb::bytes(item.data(), item.size()));
  return out;
}

}  // namespace

void bind_exchanges(nb::module_& m) {
  using detail::ClientSession;
  using detail::Exchange;
  nb::class_<Exchange>(m, "Exchange",
                       "One exchange of a session: a request of the client's (a run of tx "
                       "records; with a profile one request frame; in a udp session one "
                       "datagram) and what the device sent until the next request. "
                       "Numbered from 0 per file, as replay numbers them in mismatch "
                       "reports and faults=exchange:N.")
      .def_ro("index", &Exchange::index)
      .def_ro("client_session", &Exchange::client_session,
              "the client session (0-based) it began in, or None outside any")
      .def_ro("first_record", &Exchange::first_record,
              "the index of its first record in the file (every kind counted)")
      .def_ro("end_record", &Exchange::end_record, "one past the index of its last record")
      .def_ro("request_first_t_ns", &Exchange::request_first_t_ns)
      .def_ro("request_last_t_ns", &Exchange::request_last_t_ns)
      .def_ro("response_first_t_ns", &Exchange::response_first_t_ns)
      .def_ro("response_last_t_ns", &Exchange::response_last_t_ns)
      .def_ro("request_bytes", &Exchange::request_bytes)
      .def_ro("response_bytes", &Exchange::response_bytes)
      .def_ro("response_records", &Exchange::response_records)
      .def_prop_ro(
          "request_frames", [](const Exchange& e) { return bytes_list(e.request_frames); },
          "with a profile: its request frame (a list of one); else empty")
      .def_prop_ro(
          "response_frames", [](const Exchange& e) { return bytes_list(e.response_frames); },
          "with a profile: the response frames that began in it")
      .def("__repr__", [](const Exchange& e) {
        return "<Exchange " + std::to_string(e.index) + ": records " +
               std::to_string(e.first_record) + ".." + std::to_string(e.end_record) + ", " +
               std::to_string(e.request_bytes) + " bytes tx, " +
               std::to_string(e.response_bytes) + " bytes rx>";
      });
  nb::class_<ClientSession>(m, "ClientSession",
                            "A controlling client's connection to a virtual device or "
                            "proxy: from its client_connect to its client_disconnect (a "
                            "read-only monitor's connect is none).")
      .def_ro("index", &ClientSession::index)
      .def_ro("first_record", &ClientSession::first_record, "the index of its client_connect")
      .def_ro("end_record", &ClientSession::end_record,
              "one past its client_disconnect (or the last record before the next session)")
      .def_ro("connect_t_ns", &ClientSession::connect_t_ns)
      .def_ro("disconnect_t_ns", &ClientSession::disconnect_t_ns);

  m.def(
      "session_exchanges",
      [](const std::string& path, const std::optional<std::string>& profile,
         const std::optional<std::string>& match, const std::string& options) {
        Options keys = Options::parse(options);
        if (profile) keys.set("profile", *profile);
        if (match) keys.set("match", *match);
        const std::string text = keys.to_string();
        nb::gil_scoped_release release;
        return detail::segment_session_file(path, text, detail::datagram_port_types()).exchanges;
      },
      "path"_a, "profile"_a = nb::none(), "match"_a = nb::none(), "options"_a = "",
      "The exchanges of the session file at `path`, as a replay with profile= and "
      "match= (default sequence) numbers them (under match=request a greeting is "
      "exchange 0 of its own). `options`: the replay's keys, e.g. a declared "
      "profile's 'framing=...,echo=...' (profile and match, when given, override "
      "them). OptionError for a bad or non-replay key.");
  nb::class_<detail::ClientSessionTracker>(
      m, "ClientSessionTracker",
      "Follows client sessions through a session's records in order, by the bridge's "
      "rule: a controlling client's client_connect while none is open begins one (a "
      "read-only monitor's, or a second client's, does not); that client's "
      "client_disconnect ends it.")
      .def(nb::init<>())
      .def(
          "feed",
          [](detail::ClientSessionTracker& self, const std::string& kind, nb::bytes payload) {
            const std::optional<RecordKind> known = record_kind_from_string(kind);
            if (!known) return std::string();
            switch (self.feed(*known, std::string_view(payload.c_str(), payload.size()))) {
              case detail::ClientSessionTracker::Change::began: return std::string("began");
              case detail::ClientSessionTracker::Change::ended: return std::string("ended");
              default: return std::string();
            }
          },
          "kind"_a, "payload"_a,
          "One record: 'began' if it begins a client session, 'ended' if it ends one, "
          "else ''.")
      .def_prop_ro("open", &detail::ClientSessionTracker::open,
                   "whether a client session is open");
  m.def(
      "session_client_sessions",
      [](const std::string& path) {
        nb::gil_scoped_release release;
        return detail::segment_session_file(path, "", detail::datagram_port_types())
            .client_sessions;
      },
      "path"_a, "The client sessions of the session file at `path`, in order.");
}

}  // namespace wiretape::python
