// The one segmentation of a session into exchanges and client sessions
// (replay/exchanges.hpp), for the Python tools that count or cut sessions:
// wiretape.faults, `wiretape edit --cut Ne`, the exports, the latencies of
// `wiretape stats`.
#include <string>
#include <utility>
#include <vector>

#include <nanobind/nanobind.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/vector.h>

#include "open/port_types.hpp"
#include "python/bindings.hpp"
#include "python/text_caster.hpp"
#include "replay/exchanges.hpp"
#include "replay/profile.hpp"
#include "replay/replay_port.hpp"
#include "wiretape/session.hpp"
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

// The replay keys `options` with profile=, match= and channel= set over them
// when given.
std::string replay_keys(const std::string& options, const std::optional<std::string>& profile,
                        const std::optional<std::string>& match,
                        const std::optional<std::string>& channel = std::nullopt) {
  Options keys = Options::parse(options);
  if (profile) keys.set("profile", *profile);
  if (match) keys.set("match", *match);
  if (channel) keys.set("channel", *channel);
  return keys.to_string();
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
      .def_ro("request_end_t_ns", &Exchange::request_end_t_ns,
              "when its request was complete: the time of the record holding its last "
              "byte (with a profile, the one completing its request frame); None: no "
              "request")
      .def_ro("response_start_t_ns", &Exchange::response_start_t_ns,
              "the time of its first rx record after request_end_t_ns; None: unanswered")
      .def_ro("channel_id", &Exchange::channel_id, "the id of the channel it was said on")
      .def_ro("channel_name", &Exchange::channel_name,
              "the name of that channel (\"\" in a session without named channels)")
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
        const std::string text = replay_keys(options, profile, match);
        nb::gil_scoped_release release;
        return detail::segment_session_file(path, text, detail::datagram_port_types()).exchanges;
      },
      "path"_a, "profile"_a = nb::none(), "match"_a = nb::none(), "options"_a = "",
      "The exchanges of the session file at `path`, as a replay with profile= and "
      "match= (default sequence) numbers them (under match=request a greeting is "
      "exchange 0 of its own). `options`: the replay's keys, e.g. a declared "
      "profile's 'framing=...,echo=...' (profile and match, when given, override "
      "them). OptionError for a bad or non-replay key.");
  nb::class_<detail::SessionShape>(
      m, "SessionShape",
      "Where faults can fire in what a replay serves (every client session of a proxy "
      "recording): its exchanges, rx bytes and the session time of its last rx.")
      .def_ro("first_exchange", &detail::SessionShape::first_exchange,
              "the number of the first exchange served (numbered per file)")
      .def_ro("exchanges", &detail::SessionShape::exchange_end,
              "one past the last exchange with rx (0: none)")
      .def_ro("rx_bytes", &detail::SessionShape::rx_bytes, "the rx bytes served")
      .def_ro("last_rx_t_ns", &detail::SessionShape::last_rx_t_ns,
              "the session time of the last rx record served (0: none)")
      .def_prop_ro(
          "seconds",
          [](const detail::SessionShape& shape) {
            return static_cast<double>(shape.last_rx_t_ns) / 1e9;
          },
          "last_rx_t_ns in seconds: t:S past it never fires")
      .def("__repr__", [](const detail::SessionShape& shape) {
        return "<SessionShape exchanges " + std::to_string(shape.first_exchange) + ".." +
               std::to_string(shape.exchange_end) + ", " + std::to_string(shape.rx_bytes) +
               " rx bytes, last rx at " + std::to_string(shape.last_rx_t_ns) + " ns>";
      });
  m.def(
      "session_shape",
      [](const std::string& path, const std::optional<std::string>& profile,
         const std::optional<std::string>& match, const std::string& options,
         const std::optional<std::string>& channel) {
        const std::string text = replay_keys(options, profile, match, channel);
        nb::gil_scoped_release release;
        return detail::served_shape(
            detail::segment_session_file(path, text, detail::datagram_port_types()));
      },
      "path"_a, "profile"_a = nb::none(), "match"_a = nb::none(), "options"_a = "",
      "channel"_a = nb::none(),
      "Where faults can fire in what a replay of the session file at `path` (with "
      "profile=, match=, further replay keys `options`, and channel= of a session of "
      "several ports) serves, as the replay counts places: every client session of a "
      "proxy recording.");
  nb::class_<detail::RequestLatency>(m, "RequestLatency",
                                     "A request answered, and how long the answer took.")
      .def_ro("exchange", &detail::RequestLatency::exchange)
      .def_ro("request_name", &detail::RequestLatency::request_name,
              "with a profile its request frame's name ('?': unnamed); else ''")
      .def_ro("wait_ns", &detail::RequestLatency::wait_ns,
              "from the request's end to the first rx record after it")
      .def("__repr__", [](const detail::RequestLatency& latency) {
        return "<RequestLatency exchange " + std::to_string(latency.exchange) + " " +
               latency.request_name + ": " + std::to_string(latency.wait_ns) + " ns>";
      });
  nb::class_<detail::LatencyMeter>(
      m, "LatencyMeter",
      "The latency pairing of `wiretape stats` over the one segmentation: fed one "
      "channel's records in order, it keeps each answered request, from the end of "
      "its request (Exchange.request_end_t_ns) to the first rx after it "
      "(response_start_t_ns), as the replay cuts exchanges.")
      .def(
          "__init__",
          [](detail::LatencyMeter* self, const SessionHeader& header, std::uint16_t channel,
             const std::optional<std::string>& profile) {
            std::optional<Channel> found;
            for (const Channel& each : header.channel_list()) {
              if (each.id == channel) found = each;
            }
            detail::Segmentation how;
            if (profile) how.profile = detail::profile_from_spec(*profile).profile;
            how.datagrams =
                found && detail::recorded_as_datagrams(*found, detail::datagram_port_types());
            new (self) detail::LatencyMeter(how);
          },
          "header"_a, "channel"_a = 0, "profile"_a = nb::none(),
          "For channel `channel` (its id) of the session whose header is `header`; "
          "request frames cut and named by the profile `profile` (a name or a declared "
          "profile, read as every --profile is: profile_from_spec).")
      .def(
          "feed",
          [](detail::LatencyMeter& self, const std::string& kind, std::uint64_t t_ns,
             nb::bytes payload) {
            if (const std::optional<RecordKind> known = record_kind_from_string(kind)) {
              self.feed(*known, t_ns, std::string_view(payload.c_str(), payload.size()));
            }
          },
          "kind"_a, "t_ns"_a, "payload"_a, "One record of the channel, in recorded order.")
      .def_prop_ro("answered", &detail::LatencyMeter::answered,
                   "The answered requests so far (RequestLatency), in order.");
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
