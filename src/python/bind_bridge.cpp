// wiretape._core.Bridge: the record proxy, port server and virtual devices.
// python/wiretape/bridge.py builds the CLI's calls on it.
//
// start() and wait() release the GIL; wait() runs in short slices and checks
// Python's signals between them, so Ctrl-C interrupts a wait.
#include <chrono>
#include <cstdint>
#include <initializer_list>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <nanobind/stl/map.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/shared_ptr.h>
#include <nanobind/stl/vector.h>

#include "python/bindings.hpp"
#include "python/text_caster.hpp"
#include "wiretape/bridge.hpp"
#include "wiretape/errors.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace wiretape::python {

Timeout timeout_from_python(nb::handle value);  // bind_port.cpp

namespace {

// BridgeStats' counters by name, in declaration order: one list for the
// attributes, items() and repr().
constexpr std::pair<const char*, std::uint64_t BridgeStats::*> kStatFields[] = {
    {"bytes_to_device", &BridgeStats::bytes_to_device},
    {"bytes_from_device", &BridgeStats::bytes_from_device},
    {"bytes_dropped", &BridgeStats::bytes_dropped},
    {"clients_accepted", &BridgeStats::clients_accepted},
    {"clients_refused", &BridgeStats::clients_refused},
    {"settings_changes", &BridgeStats::settings_changes},
    {"device_losses", &BridgeStats::device_losses},
    {"device_reopens", &BridgeStats::device_reopens},
    {"records_written", &BridgeStats::records_written},
    {"datagrams_dropped", &BridgeStats::datagrams_dropped},
    {"datagrams_from_others", &BridgeStats::datagrams_from_others},
    {"datagrams_refused", &BridgeStats::datagrams_refused},
};

std::string stats_repr(const BridgeStats& stats) {
  std::string text = "BridgeStats(";
  const char* separator = "";
  for (const auto& [name, field] : kStatFields) {
    text += separator + std::string(name) + "=" + std::to_string(stats.*field);
    separator = ", ";
  }
  return text + ")";
}

void bind_results(nb::module_& m) {
  auto stats = nb::class_<BridgeStats>(m, "BridgeStats",
                                       "A bridge's counters so far (read-only).");
  for (const auto& [name, field] : kStatFields) stats.def_ro(name, field);
  stats
      .def(
          "items",
          [](const BridgeStats& s) {
            std::vector<std::pair<std::string, std::uint64_t>> items;
            for (const auto& [name, field] : kStatFields) items.emplace_back(name, s.*field);
            return items;
          },
          "(name, count) pairs, in declaration order.")
      .def("__repr__", &stats_repr);

  nb::class_<BridgeResult>(m, "BridgeResult",
                           "How a bridge ended (or that it is running), read-only.")
      .def_prop_ro(
          "outcome", [](const BridgeResult& r) { return std::string(to_string(r.outcome)); },
          "running, stopped, finished, device_closed, mismatch or failed.")
      .def_prop_ro("ok", &BridgeResult::ok, "False for a mismatch or a failure.")
      .def_ro("message", &BridgeResult::message,
              "The mismatch report, the error, or why the device closed.")
      .def_ro("stats", &BridgeResult::stats)
      .def_ro("nothing_served", &BridgeResult::nothing_served,
              "Why a replay with rx served none of it to any client (no client "
              "connected, nothing matched, the greeting was lost); '' otherwise.")
      .def_ro("ended_by_fault", &BridgeResult::ended_by_fault,
              "True when an injected fault (disconnect) lost the replay's device and "
              "that ended the bridge.")
      .def("__repr__", [](const BridgeResult& r) {
        return "BridgeResult(outcome=" + std::string(to_string(r.outcome)) +
               ", ok=" + (r.ok() ? "True" : "False") + ", message=" +
               nb::cast<std::string>(nb::repr(nb::cast(r.message))) +
               ", stats=" + stats_repr(r.stats) + ")";
      });
}

// The value `text` names among `choices`, or OptionError naming `key` and the
// choices.
template <typename Value>
Value one_of(const char* key, const std::string& text,
             std::initializer_list<std::pair<const char*, Value>> choices) {
  std::string names;
  for (const auto& [name, value] : choices) {
    if (text == name) return value;
    names += names.empty() ? "" : " or ";
    names += std::string("'") + name + "'";
  }
  throw OptionError(key, std::string(key) + " must be " + names + ", not '" + text + "'");
}

BridgeOptions make_options(const std::string& device, const std::string& client_side,
                           const std::string& pty_link, long long pty_mode,
                           const std::string& pty_group, const std::string& listen_host,
                           int listen_port, int listen_backlog,
                           const std::string& udp_peer_host, int udp_peer_port, const std::string& protocol, bool shared,
                           std::size_t max_monitors, const std::string& output,
                           const std::map<std::string, std::string>& metadata,
                           int flush_ms, bool mirror_settings, bool reopen, bool restart,
                           nb::handle duration, std::size_t buffer_limit, bool quiet,
                           const std::string& line_channel, std::shared_ptr<Recorder> recorder,
                           const std::string& channel, const std::string& compress) {
  BridgeOptions o;
  o.compression = one_of<Compression>("compress", compress,
                                      {{"none", Compression::none}, {"zstd", Compression::zstd}});
  o.device = device;
  o.client_side = one_of<BridgeClientSide>("client_side", client_side,
                                           {{"pty", BridgeClientSide::pty},
                                            {"tcp", BridgeClientSide::tcp},
                                            {"udp", BridgeClientSide::udp}});
  o.pty_link = pty_link;
  // Python's int has no bound: checked here before it is narrowed.
  if (pty_mode < 0 || pty_mode > 0777) {
    throw OptionError("pty_mode", "pty_mode must be permission bits, 0 to 0o777, not " +
                                      std::to_string(pty_mode));
  }
  o.pty_mode = static_cast<unsigned>(pty_mode);
  o.pty_group = pty_group;
  o.listen_host = listen_host;
  o.listen_port = listen_port;
  o.listen_backlog = listen_backlog;
  o.udp_peer_host = udp_peer_host;
  o.udp_peer_port = udp_peer_port;
  o.protocol = one_of<BridgeProtocol>("protocol", protocol,
                                      {{"raw", BridgeProtocol::raw},
                                       {"rfc2217", BridgeProtocol::rfc2217}});
  o.shared = shared;
  o.max_monitors = max_monitors;
  o.output = output;
  o.metadata = metadata;
  o.flush_ms = flush_ms;
  o.mirror_settings = mirror_settings;
  o.reopen = reopen;
  o.restart = restart;
  o.duration = timeout_from_python(duration);
  o.buffer_limit = buffer_limit;
  o.quiet = quiet;
  o.line_channel = line_channel;
  o.recorder = std::move(recorder);
  o.channel = channel;
  return o;
}

}  // namespace

void bind_bridge(nb::module_& m) {
  bind_results(m);
  nb::class_<Bridge>(m, "Bridge",
                     "Forwards bytes between a device port and a pty, TCP clients or UDP clients, "
                     "optionally recording them (see wiretape.bridge).")
      .def(
          "__init__",
          [](Bridge* self, const std::string& device, const std::string& client_side,
             const std::string& pty_link, long long pty_mode, const std::string& pty_group,
             const std::string& listen_host, int listen_port, int listen_backlog,
             const std::string& udp_peer_host, int udp_peer_port, const std::string& protocol, bool shared, std::size_t max_monitors,
             const std::string& output,
             const std::map<std::string, std::string>& metadata, int flush_ms,
             bool mirror_settings, bool reopen, bool restart, nb::handle duration,
             std::size_t buffer_limit, bool quiet, const std::string& line_channel,
             std::shared_ptr<Recorder> recorder, const std::string& channel,
             const std::string& compress) {
            new (self) Bridge(make_options(device, client_side, pty_link, pty_mode,
                                           pty_group, listen_host,
                                           listen_port, listen_backlog, udp_peer_host,
                                           udp_peer_port,
                                           protocol, shared, max_monitors,
                                           output, metadata,
                                           flush_ms, mirror_settings, reopen, restart,
                                           duration, buffer_limit, quiet, line_channel,
                                           std::move(recorder), channel, compress));
          },
          "device"_a, nb::kw_only(), "client_side"_a = "pty", "pty_link"_a = "",
          "pty_mode"_a = 0660LL, "pty_group"_a = "",
          "listen_host"_a = "127.0.0.1", "listen_port"_a = 0, "listen_backlog"_a = BridgeOptions{}.listen_backlog,
          "udp_peer_host"_a = "",
          "udp_peer_port"_a = 0, "protocol"_a = "raw",
          "shared"_a = false, "max_monitors"_a = std::size_t{16}, "output"_a = "",
          "metadata"_a = std::map<std::string, std::string>{}, "flush_ms"_a = 100,
          "mirror_settings"_a = true, "reopen"_a = false, "restart"_a = false,
          "duration"_a = nb::none(), "buffer_limit"_a = std::size_t{1} << 20,
          "quiet"_a = false, "line_channel"_a = "", "recorder"_a.none() = nb::none(),
          "channel"_a = "", "compress"_a = "none",
          "compress: 'zstd' writes `output` in compressed chunks (format 2.0). "
          "recorder: a Recorder whose channel named `channel` the bridge records into "
          "(capture=wire) instead of opening `output`.")
      .def("start", &Bridge::start, nb::call_guard<nb::gil_scoped_release>(),
           "Opens the device, the client side and the session file and starts forwarding.")
      .def("stop", &Bridge::stop, nb::call_guard<nb::gil_scoped_release>(),
           "Ends forwarding (thread-safe); the session file is closed complete.")
      .def(
          "wait",
          [](Bridge& bridge, nb::handle timeout) {
            using Clock = std::chrono::steady_clock;
            const Timeout limit = timeout_from_python(timeout);
            const Deadline deadline = deadline_after(limit);
            for (;;) {
              std::chrono::nanoseconds slice = std::chrono::milliseconds(100);
              bool last = false;
              if (deadline) {
                const auto left = *deadline - Clock::now();
                if (left <= slice) {
                  slice = std::chrono::duration_cast<std::chrono::nanoseconds>(
                      std::max(left, Clock::duration::zero()));
                  last = true;
                }
              }
              bool done;
              {
                nb::gil_scoped_release release;
                done = bridge.wait(slice);
              }
              if (done) return true;
              if (last) return false;
              if (PyErr_CheckSignals() != 0) throw nb::python_error();
            }
          },
          "timeout"_a = nb::none(),
          "True once the bridge has ended; False if `timeout` (seconds) expired first.")
      .def_prop_ro("running", &Bridge::running)
      .def("result", &Bridge::result,
           "A BridgeResult: outcome (running, stopped, finished, device_closed, "
           "mismatch or failed), ok, message and stats.")
      .def("stats", &Bridge::stats, "A BridgeStats: the counters so far.")
      .def_prop_ro("pty_path", &Bridge::pty_path)
      .def_prop_ro("listen_address", &Bridge::listen_address)
      .def_prop_ro("device_description", &Bridge::device_description)
      .def("messages", &Bridge::messages);
}

}  // namespace wiretape::python
