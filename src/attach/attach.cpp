// The attached recording (DESIGN §26): the descriptors chosen and the
// program seized before anything is written, then its system calls
// recorded into an ordinary session file (capture=client, header member
// `attached`) until stop(), the program's exit or exec.
#include "wiretape/attach.hpp"

#include <cerrno>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <thread>

#include "attach/process.hpp"
#include "attach/syscall_recorder.hpp"
#include "attach/tracer.hpp"
#include "session/header.hpp"
#include "session/record_kinds.hpp"
#include "wiretape/options.hpp"

namespace wiretape {

namespace {

// Room for the warnings added to the header while recording.
constexpr std::size_t attach_header_room = 8 * 1024;

std::string port_type_of(detail::DeviceKind kind) {
  switch (kind) {
    case detail::DeviceKind::tty: return "serial";
    case detail::DeviceKind::tcp: return "tcp";
    case detail::DeviceKind::udp: return "udp";
    default: return "attach";
  }
}

std::string descriptor_list(const std::vector<int>& fds) {
  std::string out;
  for (const int fd : fds) out += (out.empty() ? "" : ", ") + std::to_string(fd);
  return out;
}

const char* end_name(detail::TraceEnd end) {
  switch (end) {
    case detail::TraceEnd::exited: return "exited";
    case detail::TraceEnd::execed: return "execed";
    case detail::TraceEnd::stopped: break;
  }
  return "stopped";
}

}  // namespace

struct Attachment::Impl : detail::AttachSink, detail::SyscallHandler {
  AttachOptions options;
  std::string output;
  detail::Tracer tracer;
  std::unique_ptr<SessionWriter> writer;
  std::unique_ptr<detail::SyscallRecorder> recorder;
  SessionHeader header;
  std::chrono::steady_clock::time_point started_at;
  std::thread thread;

  mutable std::mutex mutex;
  std::condition_variable changed;
  bool started = false;
  bool done = false;
  std::exception_ptr startup_error;
  std::optional<PortError> failure;
  AttachSummary summary;

  Impl(const AttachOptions& given, std::string path)
      : options(given), output(std::move(path)), tracer(static_cast<pid_t>(given.pid)) {}

  // --- AttachSink
  std::uint64_t now_ns() override {
    return static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::nanoseconds>(
                                          std::chrono::steady_clock::now() - started_at)
                                          .count());
  }
  void write(RecordKind kind, std::uint64_t t_ns, const std::string& data) override {
    if (failure) return;
    try {
      writer->write(kind, t_ns, data);
      std::lock_guard<std::mutex> lock(mutex);
      ++summary.records;
    } catch (const PortError& error) {
      // The program must not be held up by a recording that cannot go on.
      std::lock_guard<std::mutex> lock(mutex);
      failure = error;
      tracer.request_stop();
    }
  }

  // --- SyscallHandler: the recorder's, with its warnings put in the header
  void entered(pid_t tid, const detail::SyscallCall& call) override {
    recorder->entered(tid, call);
  }
  void returned(pid_t tid, const detail::SyscallCall& call, std::int64_t result) override {
    recorder->returned(tid, call, result);
    if (recorder->take_new_warnings()) update_warnings();
    std::lock_guard<std::mutex> lock(mutex);
    summary.rx_bytes = recorder->rx_bytes();
    summary.tx_bytes = recorder->tx_bytes();
  }
  void first_stop(detail::Injector& injector) override { recorder->first_stop(injector); }

  void update_warnings() {
    if (failure) return;
    SessionHeader updated = header;
    updated.attached->warnings = recorder->warnings();
    try {
      writer->rewrite_header(updated);
      std::lock_guard<std::mutex> lock(mutex);
      header = writer->header();
      summary.warnings = recorder->warnings();
    } catch (const std::exception&) {
      std::lock_guard<std::mutex> lock(mutex);
      summary.warnings = recorder->warnings();  // the summary says them still
    }
  }

  void start() {
    const pid_t pid = static_cast<pid_t>(options.pid);
    if (options.pid <= 0 || options.pid != pid) {
      throw OptionError("attach", "cannot attach: " + std::to_string(options.pid) +
                                      " is not a process id");
    }
    // Every refusal comes before anything is seized or written.
    detail::AttachTarget target = detail::choose_descriptors(pid, options.path, options.fd);
    if (detail::process_tracer(pid) != 0) throw detail::attach_refusal(pid, EPERM);
    tracer.seize();
    header = SessionHeader::starting_now();
    header.port_type = port_type_of(target.device.kind);
    Options port;
    port.set("type", header.port_type);
    if (target.device.kind == detail::DeviceKind::tty) port.set("device", target.device.target);
    header.port_options = port.to_string();
    header.capture = Capture::client;
    header.user_metadata = options.user_metadata;
    AttachedProgram attached;
    attached.pid = options.pid;
    attached.command = detail::process_command(pid);
    attached.utc = header.start_utc;
    attached.descriptors = target.fds;
    attached.device = target.device.target;
    header.attached = attached;
    try {
      writer = std::make_unique<SessionWriter>(output, header, options.flush, attach_header_room);
    } catch (...) {
      struct Nothing : detail::SyscallHandler {
        void entered(pid_t, const detail::SyscallCall&) override {}
        void returned(pid_t, const detail::SyscallCall&, std::int64_t) override {}
        void first_stop(detail::Injector&) override {}
      } nothing;
      tracer.request_stop();
      tracer.run(nothing);  // detaches at once
      throw;
    }
    header = writer->header();
    started_at = std::chrono::steady_clock::now();
    write(RecordKind::open, 0,
          detail::event_payload(
              RecordKind::open,
              {{detail::event_field::description,
                "attached to process " + std::to_string(options.pid) + " (" + attached.command +
                    "), descriptors " + descriptor_list(target.fds) + ": " + attached.device}}));
    recorder = std::make_unique<detail::SyscallRecorder>(pid, std::move(target), *this);
    if (recorder->take_new_warnings()) update_warnings();
  }

  void run() {
    try {
      start();
    } catch (...) {
      std::lock_guard<std::mutex> lock(mutex);
      startup_error = std::current_exception();
      done = true;
      changed.notify_all();
      return;
    }
    // The constructor returns once every thread is traced at each call: a
    // request made after it is recorded whole.
    const detail::TraceEnd end = tracer.run(*this, [this] {
      std::lock_guard<std::mutex> lock(mutex);
      started = true;
      changed.notify_all();
    });
    recorder->flush();
    try {
      writer->close();
    } catch (const PortError& error) {
      if (!failure) failure = error;
    }
    std::lock_guard<std::mutex> lock(mutex);
    summary.ended_by = end_name(end);
    summary.exit_status = tracer.exit_status();
    summary.rx_bytes = recorder->rx_bytes();
    summary.tx_bytes = recorder->tx_bytes();
    summary.warnings = recorder->warnings();
    done = true;
    changed.notify_all();
  }
};

Attachment::Attachment(const AttachOptions& options, const std::string& output)
    : impl_(std::make_unique<Impl>(options, output)) {
  Impl* impl = impl_.get();
  impl->thread = std::thread([impl] { impl->run(); });
  std::unique_lock<std::mutex> lock(impl->mutex);
  impl->changed.wait(lock, [impl] { return impl->started || impl->done; });
  if (impl->startup_error) {
    lock.unlock();
    impl->thread.join();
    std::rethrow_exception(impl->startup_error);
  }
}

Attachment::~Attachment() {
  if (!impl_) return;
  stop();
  if (impl_->thread.joinable()) impl_->thread.join();
}

void Attachment::stop() {
  std::unique_lock<std::mutex> lock(impl_->mutex);
  // The tracer's thread may be waiting in waitpid when the wake-up signal
  // arrives just before it: asked again until it has ended.
  while (!impl_->done) {
    impl_->tracer.request_stop();
    if (impl_->changed.wait_for(lock, std::chrono::milliseconds(20),
                                [this] { return impl_->done; })) {
      break;
    }
  }
}

bool Attachment::wait(std::optional<std::chrono::milliseconds> timeout) {
  std::unique_lock<std::mutex> lock(impl_->mutex);
  const auto ended = [this] { return impl_->done; };
  if (!timeout) {
    impl_->changed.wait(lock, ended);
    return true;
  }
  return impl_->changed.wait_for(lock, *timeout, ended);
}

bool Attachment::finished() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->done;
}

AttachSummary Attachment::summary() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  if (impl_->failure) throw *impl_->failure;
  return impl_->summary;
}

SessionHeader Attachment::header() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->header;
}

const std::string& Attachment::path() const { return impl_->output; }

}  // namespace wiretape
