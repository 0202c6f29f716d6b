// wiretape._core.Bridge: the record proxy, port server and virtual devices.
// python/wiretape/bridge.py builds the CLI's calls on it.
//
// start() and wait() release the GIL; wait() runs in short slices and checks
// Python's signals between them, so Ctrl-C interrupts a wait.
#include <chrono>
#include <map>
#include <string>

#include <nanobind/stl/map.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include "python/bindings.hpp"
#include "wiretape/bridge.hpp"
#include "wiretape/errors.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace wiretape::python {

Timeout timeout_from_python(nb::handle value);  // bind_port.cpp

namespace {

nb::dict stats_dict(const BridgeStats& s) {
  nb::dict d;
  d["bytes_to_device"] = s.bytes_to_device;
  d["bytes_from_device"] = s.bytes_from_device;
  d["bytes_dropped"] = s.bytes_dropped;
  d["clients_accepted"] = s.clients_accepted;
  d["clients_refused"] = s.clients_refused;
  d["settings_changes"] = s.settings_changes;
  d["device_losses"] = s.device_losses;
  d["device_reopens"] = s.device_reopens;
  d["records_written"] = s.records_written;
  return d;
}

BridgeOptions make_options(const std::string& device, const std::string& client_side,
                           const std::string& pty_link, const std::string& listen_host,
                           int listen_port, const std::string& protocol, bool shared,
                           const std::string& output,
                           const std::map<std::string, std::string>& metadata,
                           int flush_ms, bool mirror_settings, bool reopen, bool restart,
                           nb::handle duration, std::size_t buffer_limit, bool quiet) {
  BridgeOptions o;
  o.device = device;
  if (client_side == "pty") o.client_side = BridgeClientSide::pty;
  else if (client_side == "tcp") o.client_side = BridgeClientSide::tcp;
  else throw OptionError("client_side", "client_side must be 'pty' or 'tcp', not '" + client_side + "'");
  o.pty_link = pty_link;
  o.listen_host = listen_host;
  o.listen_port = listen_port;
  if (protocol == "raw") o.protocol = BridgeProtocol::raw;
  else if (protocol == "rfc2217") o.protocol = BridgeProtocol::rfc2217;
  else throw OptionError("protocol", "protocol must be 'raw' or 'rfc2217', not '" + protocol + "'");
  o.shared = shared;
  o.output = output;
  o.metadata = metadata;
  o.flush_ms = flush_ms;
  o.mirror_settings = mirror_settings;
  o.reopen = reopen;
  o.restart = restart;
  o.duration = timeout_from_python(duration);
  o.buffer_limit = buffer_limit;
  o.quiet = quiet;
  return o;
}

}  // namespace

void bind_bridge(nb::module_& m) {
  nb::class_<Bridge>(m, "Bridge",
                     "Forwards bytes between a device port and a pty or TCP clients, "
                     "optionally recording them (see wiretape.bridge).")
      .def(
          "__init__",
          [](Bridge* self, const std::string& device, const std::string& client_side,
             const std::string& pty_link, const std::string& listen_host, int listen_port,
             const std::string& protocol, bool shared, const std::string& output,
             const std::map<std::string, std::string>& metadata, int flush_ms,
             bool mirror_settings, bool reopen, bool restart, nb::handle duration,
             std::size_t buffer_limit, bool quiet) {
            new (self) Bridge(make_options(device, client_side, pty_link, listen_host,
                                           listen_port, protocol, shared, output, metadata,
                                           flush_ms, mirror_settings, reopen, restart,
                                           duration, buffer_limit, quiet));
          },
          "device"_a, nb::kw_only(), "client_side"_a = "pty", "pty_link"_a = "",
          "listen_host"_a = "127.0.0.1", "listen_port"_a = 0, "protocol"_a = "raw",
          "shared"_a = false, "output"_a = "",
          "metadata"_a = std::map<std::string, std::string>{}, "flush_ms"_a = 100,
          "mirror_settings"_a = true, "reopen"_a = false, "restart"_a = false,
          "duration"_a = nb::none(), "buffer_limit"_a = std::size_t{1} << 20,
          "quiet"_a = false)
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
      .def(
          "result",
          [](const Bridge& bridge) {
            const BridgeResult r = bridge.result();
            nb::dict d;
            d["outcome"] = std::string(to_string(r.outcome));
            d["ok"] = r.ok();
            d["message"] = r.message;
            d["stats"] = stats_dict(r.stats);
            return d;
          },
          "{'outcome', 'ok', 'message', 'stats'}: outcome is running, stopped, "
          "finished, device_closed, mismatch or failed.")
      .def("stats", [](const Bridge& bridge) { return stats_dict(bridge.stats()); })
      .def_prop_ro("pty_path", &Bridge::pty_path)
      .def_prop_ro("listen_address", &Bridge::listen_address)
      .def_prop_ro("device_description", &Bridge::device_description)
      .def("messages", &Bridge::messages);
}

}  // namespace wiretape::python
