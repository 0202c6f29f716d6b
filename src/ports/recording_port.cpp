// The recording port (`log=FILE`, and each port of a Recorder): a decorator
// that forwards every call to the port under it unchanged and records what crossed it into a session
// file (capture=client): each successful read's bytes as one rx when the
// read returned (a compound read is one read, however many reads of the port
// under it it took), each write's bytes as tx stamped when the write call entered,
// and the events (open, close, flushes, drain, settings, modem lines, break,
// device loss). Reads that time out are not recorded. It records into a
// channel of a recorder's file; `log=FILE` is a file of one unnamed channel
// that the port owns (its close closes the file).
#include <atomic>
#include <chrono>
#include <cstdio>
#include <mutex>
#include <optional>
#include <string>

#include "core/fault_hook.hpp"
#include "ports/ports.hpp"
#include "session/recorder_file.hpp"
#include "util/json.hpp"
#include "session/record_kinds.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/session.hpp"

namespace wiretape::detail {

namespace {


class RecordingPort final : public Port {
 public:
  RecordingPort(std::unique_ptr<Port> inner, RecordingChannel channel, RecordingTarget target)
      : inner_(std::move(inner)), target_(target), channel_(std::move(channel)) {
    set_timeout(inner_->timeout());
    set_access(inner_->access());
    record(RecordKind::open, target_.opens_the_clock ? 0 : now_ns(),
           event_payload(RecordKind::open, {{event_field::description, inner_->description()}}));
    // The device's lines as they were at open: a replay checks the client's
    // lines only in recordings that hold the device's (DESIGN.md section 20).
    if (inner_->capabilities().modem_lines) read_modem_inputs();
  }

  ~RecordingPort() override {
    try {
      finish_recording();
    } catch (...) {
      // A destructor never throws; the file keeps what was written.
    }
  }

  // An event the port under this one reports (a replay's injected fault).
  void record_event(RecordKind kind, std::string_view payload) {
    record(kind, now_ns(), payload);
  }

  std::size_t available() override {
    report_failure();
    return inner_->available();
  }

  void flush_input() override {
    report_failure();
    inner_->flush_input();
    record(RecordKind::flush_input, now_ns(), "{}");
  }

  void flush_output() override {
    report_failure();
    inner_->flush_output();
    record(RecordKind::flush_output, now_ns(), "{}");
  }

  void drain() override {
    report_failure();
    inner_->drain();
    record(RecordKind::drain, now_ns(), "{}");
  }

  // The session file is released whatever happens to the port under it (a
  // replay's mismatch at close, an OS error): a close that throws must not
  // leave the file open until the port object goes away.
  void close() override {
    closing_ = true;
    try {
      inner_->close();
    } catch (...) {
      try {
        finish_recording();
      } catch (const PortError&) {
        // The port's own failure is the one to report.
      }
      throw;
    }
    finish_recording();
  }

  bool is_open() const override { return inner_->is_open(); }
  std::string description() const override { return inner_->description(); }
  std::string type() const override { return inner_->type(); }
  PortCapabilities capabilities() const override { return inner_->capabilities(); }
  std::string left_unused() const override { return inner_->left_unused(); }
  int native_handle() const override { return inner_->native_handle(); }

  void set_baud(unsigned baud) override {
    report_failure();
    inner_->set_baud(baud);
    record(RecordKind::settings, now_ns(),
           event_payload(RecordKind::settings, {{event_field::baud, std::int64_t{baud}}}));
  }

  void configure(const SerialSettings& settings) override {
    report_failure();
    inner_->configure(settings);
    record(RecordKind::settings, now_ns(),
           event_payload(RecordKind::settings,
                         {{event_field::baud, std::int64_t{settings.baud}},
                          {event_field::databits, std::int64_t{settings.data_bits}},
                          {event_field::stopbits, std::int64_t{settings.stop_bits}},
                          {event_field::parity, std::string(to_string(settings.parity))},
                          {event_field::flow, std::string(to_string(settings.flow))}}));
  }

  SerialSettings serial_settings() const override { return inner_->serial_settings(); }

  void set_dtr(bool level) override {
    report_failure();
    inner_->set_dtr(level);
    record(RecordKind::modem_lines, now_ns(), event_payload(RecordKind::modem_lines, {{event_field::dtr, level}}));
  }

  void set_rts(bool level) override {
    report_failure();
    inner_->set_rts(level);
    record(RecordKind::modem_lines, now_ns(), event_payload(RecordKind::modem_lines, {{event_field::rts, level}}));
  }

  // Reading one input reads all four, and a change is recorded as it was
  // seen: the client saw the device's lines only when it asked.
  bool cts() override { return input(&ModemInputs::cts, &Port::cts); }
  bool dsr() override { return input(&ModemInputs::dsr, &Port::dsr); }
  bool ri() override { return input(&ModemInputs::ri, &Port::ri); }
  bool cd() override { return input(&ModemInputs::cd, &Port::cd); }

  void send_break(std::chrono::milliseconds duration) override {
    report_failure();
    inner_->send_break(duration);
    record(RecordKind::line_break, now_ns(),
           event_payload(RecordKind::line_break,
                         {{event_field::duration_ms, std::int64_t{duration.count()}}}));
  }

 protected:
  // A simple read is recorded as it returns; the bytes of a compound read
  // collect in pending_rx_ until it returns: one rx record however many
  // read_some calls it took.
  std::size_t read_some(void* buffer, std::size_t size, Deadline deadline) override {
    report_failure();
    std::size_t n = 0;
    try {
      n = read_some_of(*inner_, buffer, size, deadline);
    } catch (const PortClosed& e) {
      record_pending_rx();
      device_lost(e);
      throw;
    }
    if (n == 0) return 0;
    if (in_compound_read()) {
      pending_rx_.append(static_cast<const char*>(buffer), n);
    } else {
      record(RecordKind::rx, now_ns(), std::string_view(static_cast<const char*>(buffer), n));
    }
    return n;
  }

  std::optional<std::size_t> peek_some(void* buffer, std::size_t size,
                                       Deadline deadline) override {
    try {
      return peek_some_of(*inner_, buffer, size, deadline);
    } catch (const PortClosed& e) {
      record_pending_rx();
      device_lost(e);
      throw;
    }
  }

  void read_returned() override { record_pending_rx(); }

  std::size_t write_some(const void* data, std::size_t size, Deadline deadline) override {
    report_failure();
    const std::uint64_t entered = now_ns();
    std::size_t n = 0;
    try {
      n = write_some_of(*inner_, data, size, deadline);
    } catch (const PortClosed& e) {
      device_lost(e);
      throw;
    }
    if (n > 0) {
      record(RecordKind::tx, entered, std::string_view(static_cast<const char*>(data), n));
    }
    return n;
  }

  bool wait_readable_until(Deadline deadline) override {
    report_failure();
    return wait_readable_until_of(*inner_, deadline);
  }

 private:
  std::uint64_t now_ns() const { return channel_.now_ns(); }

  // A device that went away is recorded once (replays as PortClosed there);
  // a close() of ours is recorded as close instead.
  void device_lost(const PortClosed& error) {
    if (closing_) return;
    bool expected = false;
    if (!lost_.compare_exchange_strong(expected, true)) return;
    record(RecordKind::device_lost, now_ns(),
           event_payload(RecordKind::device_lost,
                         {{event_field::error, std::string(error.what())},
                          {event_field::error_number, std::int64_t{error.code().value()}}}));
  }

  // The device's four inputs, recorded when they differ from the last ones
  // recorded; nothing where the device cannot tell them (a pty).
  std::optional<ModemInputs> read_modem_inputs() {
    ModemInputs inputs;
    try {
      inputs.cts = inner_->cts();
      inputs.dsr = inner_->dsr();
      inputs.ri = inner_->ri();
      inputs.cd = inner_->cd();
    } catch (const PortClosed&) {
      throw;
    } catch (const PortError&) {
      return std::nullopt;
    }
    std::lock_guard<std::mutex> lock(inputs_mutex_);
    if (recorded_inputs_ != inputs) {
      recorded_inputs_ = inputs;
      record(RecordKind::modem_lines, now_ns(), modem_inputs_payload(inputs));
    }
    return inputs;
  }

  bool input(bool ModemInputs::*level, bool (Port::*read_one)()) {
    report_failure();
    if (inner_->capabilities().modem_lines) {
      if (const auto inputs = read_modem_inputs()) return (*inputs).*level;
    }
    return ((*inner_).*read_one)();  // says why it has none, or answers unrecorded
  }

  // rx is stamped when the read returned (capture=client).
  void record_pending_rx() {
    if (pending_rx_.empty()) return;
    record(RecordKind::rx, now_ns(), pending_rx_);
    pending_rx_.clear();
  }

  void record(RecordKind kind, std::uint64_t t_ns, std::string_view data) {
    if (!recording_.load(std::memory_order_acquire)) return;
    try {
      channel_.write(kind, t_ns, data);
    } catch (const PortError& e) {
      // A read or write racing with close() may come after the file was
      // closed (by this port, or by its Recorder): that is the end of the
      // session, not a recording failure.
      if (finished_.load(std::memory_order_acquire) || channel_.file_closed()) return;
      recording_failed(e);
    }
  }

  // Stops recording; the failure is raised once from the next port call
  // (log_errors=raise) or printed once (log_errors=warn).
  void recording_failed(const PortError& error) {
    std::lock_guard<std::mutex> lock(failure_mutex_);
    if (!recording_.exchange(false)) return;
    if (target_.raise_errors) {
      pending_failure_.emplace(error);
      has_pending_failure_.store(true, std::memory_order_release);
    } else {
      std::fprintf(stderr,
                   "wiretape: warning: recording stopped: %s (the port goes on; "
                   "log_errors=warn)\n",
                   error.what());
    }
  }

  void report_failure() {
    if (recording_.load(std::memory_order_acquire)) {
      // A failure in the writer's background flush shows up here.
      if (auto failure = channel_.failure()) recording_failed(*failure);
    }
    if (!has_pending_failure_.load(std::memory_order_acquire)) return;
    std::lock_guard<std::mutex> lock(failure_mutex_);
    if (!pending_failure_) return;
    const PortError error = *pending_failure_;
    pending_failure_.reset();
    has_pending_failure_.store(false, std::memory_order_release);
    throw error;
  }

  void finish_recording() {
    std::lock_guard<std::mutex> lock(finish_mutex_);
    if (closed_recorded_) return;
    closed_recorded_ = true;
    record(RecordKind::close, now_ns(), "{}");
    finished_.store(true, std::memory_order_release);
    // A Recorder's file stays open for its other channels.
    if (!target_.owns_file) return;
    RecorderFile& file = RecordingChannelAccess::file(channel_);
    if (!recording_.load()) {
      // Recording stopped at a failure that was already reported: the file
      // is released all the same.
      try {
        file.close();
      } catch (const PortError&) {
      }
      return;
    }
    try {
      file.close();
    } catch (const PortError& e) {
      recording_failed(e);
      report_failure();
    }
  }

  std::unique_ptr<Port> inner_;
  RecordingTarget target_;
  RecordingChannel channel_;
  std::atomic<bool> recording_{true};
  std::atomic<bool> closing_{false};
  std::atomic<bool> lost_{false};
  std::mutex failure_mutex_;
  std::atomic<bool> has_pending_failure_{false};
  std::optional<PortError> pending_failure_;
  std::mutex finish_mutex_;
  bool closed_recorded_ = false;
  std::atomic<bool> finished_{false};
  std::mutex inputs_mutex_;
  std::optional<ModemInputs> recorded_inputs_;
  // Touched by the reading thread only (one reader at a time).
  std::string pending_rx_;
};

}  // namespace

std::unique_ptr<Port> record_port_into(std::unique_ptr<Port> inner, RecordingChannel channel,
                                       RecordingTarget target) {
  Port* wrapped = inner.get();
  auto port = std::make_unique<RecordingPort>(std::move(inner), std::move(channel), target);
  // A recorded port that injects faults (a faulty replay): each fault is
  // also a `fault` event.
  RecordingPort* recorder = port.get();
  report_faults_to(*wrapped, [recorder](const FaultEvent& event) {
    std::fprintf(stderr, "wiretape: fault %s@%s: %s\n", event.kind.c_str(), event.where.c_str(),
                 event.detail.c_str());
    recorder->record_event(RecordKind::fault, json::ObjectWriter()
                                                  .add(event_field::fault_kind, event.kind)
                                                  .add(event_field::where, event.where)
                                                  .add(event_field::detail, event.detail)
                                                  .str());
  });
  return port;
}

std::unique_ptr<Port> record_port(std::unique_ptr<Port> inner, RecordingConfig config) {
  SessionHeader header = SessionHeader::starting_now();
  header.capture = Capture::client;
  header.port_options = config.options_text;
  header.port_type = config.port_type.empty() ? inner->type() : config.port_type;
  header.user_metadata = config.metadata;
  const FlushPolicy flush{std::chrono::milliseconds(config.flush_ms), config.fsync,
                          config.compress ? Compression::zstd : Compression::none};
  // The clock starts when the file is made, just after the port opened.
  RecordingChannel channel = single_channel_file(config.path, header, flush);
  return record_port_into(std::move(inner), std::move(channel),
                          RecordingTarget{/*owns_file=*/true, config.raise_errors,
                                          /*opens_the_clock=*/true});
}

}  // namespace wiretape::detail
