// wiretape._core.Attachment: recording a running program (DESIGN §26);
// wiretape.attach() and `wiretape record --attach` stand on it.
//
// The constructor and stop() release the GIL; wait() runs in short slices
// and checks Python's signals between them, so Ctrl-C interrupts a wait.
#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <string>

#include <nanobind/stl/map.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/unique_ptr.h>
#include <nanobind/stl/vector.h>

#include "python/bindings.hpp"
#include "wiretape/attach.hpp"
#include "wiretape/timeout.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace wiretape::python {

Timeout timeout_from_python(nb::handle value);  // bind_port.cpp

void bind_attach(nb::module_& m) {
  nb::class_<AttachSummary>(m, "AttachSummary", "How an attached recording ended (read-only).")
      .def_ro("ended_by", &AttachSummary::ended_by,
              "stopped (stop(), Ctrl-C, a duration), exited (the program ended) or execed "
              "(it executed another program, which is not followed)")
      .def_ro("exit_status", &AttachSummary::exit_status,
              "the program's exit status as waitpid reports it, when it exited")
      .def_ro("rx_bytes", &AttachSummary::rx_bytes, "bytes the program read from the device")
      .def_ro("tx_bytes", &AttachSummary::tx_bytes, "bytes the program wrote to the device")
      .def_ro("records", &AttachSummary::records, "records written")
      .def_ro("warnings", &AttachSummary::warnings,
              "what the recording cannot hold (splice, sendfile, io_uring...)");

  nb::class_<Attachment>(
      m, "Attachment",
      "Records a running program's session with its device through ptrace into an "
      "ordinary session file, and lets it go as it was (docs/recording.md, \"Attaching to "
      "a running program\"). A refusal raises OptionError naming why; nothing is written.")
      .def(
          "__init__",
          [](Attachment* self, std::int64_t pid, const std::string& output,
             const std::string& path, std::optional<int> fd,
             const std::map<std::string, std::string>& meta, int flush_ms) {
            AttachOptions options;
            options.pid = pid;
            options.path = path;
            options.fd = fd;
            options.user_metadata = meta;
            options.flush.interval = std::chrono::milliseconds(flush_ms);
            nb::gil_scoped_release release;
            new (self) Attachment(options, output);
          },
          "pid"_a, "output"_a, "path"_a = "", "fd"_a = nb::none(),
          "meta"_a = std::map<std::string, std::string>{}, "flush_ms"_a = 100,
          "Attaches to process PID and records the device (PATH, matched by stat; "
          "descriptor FD; or its only tty or socket) into OUTPUT.")
      .def("stop", &Attachment::stop, nb::call_guard<nb::gil_scoped_release>(),
           "Ends the recording: every thread is detached (returns once done).")
      .def(
          "wait",
          [](Attachment& attachment, nb::handle timeout) {
            using Clock = std::chrono::steady_clock;
            const Deadline deadline = deadline_after(timeout_from_python(timeout));
            for (;;) {
              auto slice = std::chrono::milliseconds(100);
              bool last = false;
              if (deadline) {
                const auto left = *deadline - Clock::now();
                if (left <= slice) {
                  slice = std::chrono::duration_cast<std::chrono::milliseconds>(
                      std::max(left, Clock::duration::zero()));
                  last = true;
                }
              }
              bool done;
              {
                nb::gil_scoped_release release;
                done = attachment.wait(slice);
              }
              if (done) return true;
              if (last) return false;
              if (PyErr_CheckSignals() != 0) throw nb::python_error();
            }
          },
          "timeout"_a = nb::none(),
          "True once the recording ended (stop(), the program's exit or exec); False if "
          "`timeout` (seconds) expired first.")
      .def_prop_ro("finished", &Attachment::finished)
      .def("summary", &Attachment::summary,
           "An AttachSummary; raises the write failure that ended the recording early.")
      .def_prop_ro("header", &Attachment::header, "The session header as written.")
      .def_prop_ro("path", &Attachment::path, "The session file.");

  m.def(
      "attach",
      [](std::int64_t pid, const std::string& output, const std::string& path,
         std::optional<int> fd, const std::map<std::string, std::string>& meta, int flush_ms) {
        AttachOptions options;
        options.pid = pid;
        options.path = path;
        options.fd = fd;
        options.user_metadata = meta;
        options.flush.interval = std::chrono::milliseconds(flush_ms);
        nb::gil_scoped_release release;
        return std::make_unique<Attachment>(options, output);
      },
      "pid"_a, "output"_a, "path"_a = "", "fd"_a = nb::none(),
      "meta"_a = std::map<std::string, std::string>{}, "flush_ms"_a = 100,
      "Attaches to running process PID and records its session with the device (PATH, "
      "matched by stat; descriptor FD; or its only tty or socket) into OUTPUT, an ordinary "
      "session file; returns the Attachment (stop() it, or wait() for the program's end). "
      "A refusal raises OptionError saying why (no such process, permission, "
      "kernel.yama.ptrace_scope, already traced, a descriptor or path it does not hold); "
      "nothing is written then.");
}

}  // namespace wiretape::python
