// The bridge engine: one thread, one poll() over the device's native handle,
// the client endpoint's descriptors and a wake-up pipe for stop(). Data moves
// in large chunks through bounded queues; the only per-byte work is RFC
// 2217's IAC escaping when that protocol is on.
//
// The pieces: DeviceSide (device_side.hpp) owns the device, the queue to it,
// its line state and the session file; a ClientEndpoint (endpoint.hpp: pty,
// TCP or UDP) owns the clients; ComPortAdapter (com_port_adapter.hpp) is RFC
// 2217's view of the device. This file is the loop that ties them together
// and the public Bridge.
#include "wiretape/bridge.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>

#include "bridge/device_side.hpp"
#include "bridge/endpoint.hpp"
#include "bridge/status.hpp"
#include "session/record_kinds.hpp"
#include "posix/poll_set.hpp"
#include "posix/pty_terminal.hpp"
#include "posix/wake_pipe.hpp"
#include "replay/replay_port.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"

namespace wiretape {

std::string_view to_string(BridgeOutcome outcome) {
  switch (outcome) {
    case BridgeOutcome::running: return "running";
    case BridgeOutcome::stopped: return "stopped";
    case BridgeOutcome::finished: return "finished";
    case BridgeOutcome::device_closed: return "device_closed";
    case BridgeOutcome::mismatch: return "mismatch";
    case BridgeOutcome::failed: return "failed";
  }
  return "unknown";
}

namespace {

using detail::PollSet;
using detail::Readiness;
using detail::WakePipe;
using detail::bridge::ClientEndpoint;
using detail::bridge::Clock;
using detail::bridge::DeviceSide;
using detail::bridge::kChunk;
using detail::bridge::Status;

// A device whose descriptor cannot tell when it takes data again is retried
// this often while data waits for it.
constexpr auto kWriteRetryInterval = std::chrono::milliseconds(2);
constexpr auto kModemPollInterval = std::chrono::milliseconds(10);
constexpr auto kLongestSleep = std::chrono::milliseconds(60'000);

std::string octal(unsigned value) {
  char text[16];
  std::snprintf(text, sizeof text, "0%o", value);
  return text;
}

}  // namespace

struct Bridge::Impl {
  explicit Impl(BridgeOptions options)
      : options_(std::move(options)), status_(options_.quiet), device_(options_, status_) {
    device_.on_lost([this](const std::string& reason) { device_lost(reason); });
  }

  BridgeOptions options_;
  Status status_;
  std::atomic<bool> stop_requested_{false};
  // Created by start(); guarded by status_.mutex for stop().
  std::optional<WakePipe> wake_;
  std::thread thread_;
  std::mutex join_mutex_;

  // --- owned by the forwarding thread once started -----------------------------
  DeviceSide device_;
  std::unique_ptr<ClientEndpoint> endpoint_;
  std::optional<Clock::time_point> end_at_;
  Clock::time_point next_reopen_;
  Clock::time_point next_modem_poll_;
  bool reopen_failure_logged_ = false;
  BridgeOutcome end_outcome_ = BridgeOutcome::running;
  std::string end_message_;
  // The device is a replay whose recording has rx for the clients.
  bool replay_has_rx_ = false;
  bool replay_greets_ = false;
  std::string nothing_served_;
  bool ended_by_fault_ = false;

  void end(BridgeOutcome outcome, std::string text) {
    if (end_outcome_ != BridgeOutcome::running) return;
    end_outcome_ = outcome;
    end_message_ = std::move(text);
  }
  bool ending() const { return end_outcome_ != BridgeOutcome::running; }

  void open_all();
  void run();
  void loop();
  void read_device(Readiness ready);
  void device_lost(const std::string& reason);
  void try_reopen();
  void shut_down();
  std::string why_nothing_was_served() const;
};

void Bridge::Impl::open_all() {
  // A busy listen address fails before the device is touched.
  if (options_.client_side == BridgeClientSide::tcp) {
    endpoint_ = detail::bridge::make_tcp_endpoint(options_, device_, status_);
  }
  device_.open(true, nullptr);
  replay_has_rx_ = detail::replay_recording_has_rx(device_.port());
  replay_greets_ = detail::replay_recording_greets(device_.port());
  device_.open_session_file();
  if (options_.client_side == BridgeClientSide::pty) {
    endpoint_ = detail::bridge::make_pty_endpoint(options_, device_, status_);
  }
  if (options_.client_side == BridgeClientSide::udp) {
    endpoint_ = detail::bridge::make_udp_endpoint(options_, device_, status_);
  }
  if (options_.duration) end_at_ = Clock::now() + *options_.duration;
}

void Bridge::Impl::run() {
  try {
    loop();
  } catch (const ReplayMismatch& mismatch) {
    end(BridgeOutcome::mismatch, mismatch.what());
  } catch (const std::exception& error) {
    end(BridgeOutcome::failed, error.what());
  }
  shut_down();
}

void Bridge::Impl::loop() {
  PollSet poll_set("bridge");
  while (!ending()) {
    if (stop_requested_.load()) {
      end(BridgeOutcome::stopped, "stopped");
      break;
    }
    const auto now = Clock::now();
    if (end_at_ && now >= *end_at_) {
      end(BridgeOutcome::finished, "the duration elapsed");
      break;
    }
    if (!device_.is_open() && options_.reopen && now >= next_reopen_) try_reopen();

    device_.flush();
    if (ending()) break;

    const bool output_pollable = device_.capabilities().output_pollable;
    poll_set.clear();
    const PollSet::Slot wake_slot = poll_set.add(wake_->fd(), true, false);
    PollSet::Slot device_slot = PollSet::none;
    bool device_read_wanted = false;
    if (device_.is_open()) {
      device_read_wanted = endpoint_->wants_device_data();
      const bool want_write = device_.has_data_for_device() && output_pollable;
      // Polled even when neither is wanted: poll() reports a hang-up or an
      // error (adapter unplugged, connection reset) anyway, so a loss is
      // noticed while no client is connected, not by the next client, who
      // would be accepted only to be cut off.
      device_slot = poll_set.add(device_.port().native_handle(), device_read_wanted, want_write);
    }
    endpoint_->add_to_poll(poll_set);

    // How long to sleep: until the next timer.
    auto wake_at = endpoint_->next_timer();
    if (end_at_) wake_at = std::min(wake_at, *end_at_);
    if (!device_.is_open() && options_.reopen) wake_at = std::min(wake_at, next_reopen_);
    // Watched (and recorded) for every client, often enough to catch the
    // answer to a reset pulse (DESIGN.md section 20).
    const bool watch_modem = endpoint_->has_clients() && device_.modem_inputs_watchable();
    if (watch_modem) wake_at = std::min(wake_at, next_modem_poll_);
    if (device_.is_open() && device_.has_data_for_device() && !output_pollable) {
      wake_at = std::min(wake_at, now + kWriteRetryInterval);
    }
    std::optional<std::chrono::milliseconds> sleep;
    if (wake_at != Clock::time_point::max()) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          wake_at - Clock::now() + std::chrono::microseconds(999));
      sleep = std::clamp(left, std::chrono::milliseconds(0), kLongestSleep);
    }
    poll_set.wait(sleep);

    if (poll_set.ready(wake_slot).readable) wake_->drain();
    Readiness device_ready = poll_set.ready(device_slot);
    device_.take_datagram_bounce(device_ready);
    if (device_ready.hung_up && !device_read_wanted) {
      // Reading now would overfill the clients' queues; what the device
      // still holds goes with it.
      device_.lost("the device hung up");
    } else if (device_ready.any()) {
      read_device(device_ready);
    }
    endpoint_->handle_events(poll_set);
    if (watch_modem && Clock::now() >= next_modem_poll_) {
      if (device_.modem_inputs_changed()) endpoint_->modem_inputs_changed();
      next_modem_poll_ = Clock::now() + kModemPollInterval;
    }
    endpoint_->run_timers(Clock::now());
  }
}

void Bridge::Impl::read_device(Readiness ready) {
  std::array<char, kChunk> buffer;
  // What was read: in `buffer`, or in the session file's buffer.
  const char* data = buffer.data();
  std::size_t filled = 0;
  const auto deliver = [&] {
    status_.add_bytes_from_device(filled);
    endpoint_->deliver_from_device(data, filled);
  };
  const bool one_read_per_delivery = endpoint_->keeps_datagram_boundaries();
  try {
    if (ready.readable || ready.hung_up) {
      if (one_read_per_delivery) {
        for (;;) {
          // One read is one datagram (an empty one too): recorded and
          // delivered alone, and read on while the client side takes more.
          const std::optional<std::size_t> n =
              device_.read_datagram(buffer.data(), buffer.size());
          if (!n) break;
          device_.record(RecordKind::rx, std::string_view(buffer.data(), *n));
          filled = *n;
          deliver();
          filled = 0;
          if (!endpoint_->wants_device_data() || !device_.is_open()) break;
        }
      } else {
        // One read per wake-up, even when it took a whole line-discipline
        // buffer (4095 bytes) and more is waiting: a read or a poll that
        // finds a terminal's line discipline empty waits for the tty layer's
        // flip work (Linux n_tty_read/n_tty_poll -> __flush_work, a task
        // switch), and reading on until a short read emptied it before every
        // poll. Left for the poll, which then returns at once, the rest costs
        // less: record --pty's CPU per MB fell by a fifth (docs/benchmarks.md,
        // "Where the cycles go").
        // Read into the session file's buffer where the endpoint records
        // nothing before it is done with the bytes: the record is the
        // read, not a copy of it (docs/benchmarks.md).
        const std::string_view got = device_.read_and_record(
            buffer.data(), buffer.size(), endpoint_->delivers_without_recording());
        data = got.data();
        filled = got.size();
      }
    }
  } catch (const PortClosed& closed) {
    if (filled > 0) deliver();
    device_.lost(closed.what());
    return;
  }
  if (filled == 0) {
    if (ready.hung_up) device_.lost("the device hung up");
    return;
  }
  deliver();
}

// DeviceSide has closed the device and recorded the loss.
void Bridge::Impl::device_lost(const std::string& reason) {
  endpoint_->device_lost();
  if (!options_.reopen) {
    if (!ending()) ended_by_fault_ = device_.lost_by_fault();
    end(BridgeOutcome::device_closed, "the device went away: " + reason);
    return;
  }
  reopen_failure_logged_ = false;
  next_reopen_ = Clock::now() + options_.reopen_interval;
}

void Bridge::Impl::try_reopen() {
  try {
    device_.open(false, detail::event_field::reopened);
    status_.update_stats([](BridgeStats& s) { ++s.device_reopens; });
    status_.message("the device is back: " + device_.description());
    endpoint_->device_reopened();
  } catch (const OptionError&) {
    throw;
  } catch (const std::exception& error) {
    if (!reopen_failure_logged_) {
      status_.message(std::string("waiting for the device to come back (") + error.what() + ")");
      reopen_failure_logged_ = true;
    }
    next_reopen_ = Clock::now() + options_.reopen_interval;
  }
}

// Runs on the bridge's thread, where an exception would terminate the
// process: whatever the clients' side does, the device and the session file
// are closed.
void Bridge::Impl::shut_down() {
  try {
    endpoint_->shut_down();
  } catch (const std::exception& error) {
    status_.message(std::string("closing the clients' side: ") + error.what());
  }
  device_.shut_down(end_outcome_, end_message_);
  nothing_served_ = why_nothing_was_served();
  endpoint_.reset();
}

// Asked once the bridge has ended. A mismatch or failure has its own report.
std::string Bridge::Impl::why_nothing_was_served() const {
  if (!replay_has_rx_ || endpoint_->served_device_data()) return "";
  if (end_outcome_ == BridgeOutcome::mismatch || end_outcome_ == BridgeOutcome::failed) return "";
  BridgeStats stats;
  {
    std::lock_guard<std::mutex> lock(status_.mutex);
    stats = status_.stats();
  }
  const std::string none = "no client was served any of the recording's rx: ";
  // A fault wiretape injected is never the client's doing.
  if (ended_by_fault_) {
    return none + "an injected fault ended the replay before any was served (" +
           end_message_ + ")";
  }
  if (const std::string& silence = device_.silenced_by_fault(); !silence.empty()) {
    return none + "an injected fault ended the replay before any was served (fault " +
           silence + ": the device stopped answering)";
  }
  if (std::string why = endpoint_->why_nothing_was_served(); !why.empty()) return none + why;
  if (stats.clients_accepted == 0) return none + "no client connected before the end";
  if (stats.bytes_from_device == 0 && stats.bytes_to_device == 0 && replay_greets_) {
    // A client session releases the greeting at the client's connect; a
    // client that closes at once can leave before the bridge passed it on.
    return none + "the client read none of the recording's rx: it closed before any was "
                  "passed to it (the greeting was lost)";
  }
  if (stats.bytes_from_device == 0) {
    return none + "nothing the client sent matched what the recording answers, so no rx was "
                  "released";
  }
  return none + "the client read none of the " + std::to_string(stats.bytes_from_device) +
         " bytes released to it (the greeting was lost: flushed, or left unread when the "
         "client closed)";
}

// --- Bridge ------------------------------------------------------------------------------

Bridge::Bridge(BridgeOptions options) : impl_(std::make_unique<Impl>(std::move(options))) {
  const BridgeOptions& o = impl_->options_;
  if (o.device.empty()) {
    throw OptionError("device", "the bridge needs a device: a port option string such as "
                                "\"type=serial,device=/dev/ttyUSB0\"");
  }
  if (o.client_side == BridgeClientSide::tcp && (o.listen_port < 0 || o.listen_port > 65535)) {
    throw OptionError("listen", "listen port " + std::to_string(o.listen_port) +
                                    " is out of range (0 to 65535; 0 picks a free port)");
  }
  if (o.client_side == BridgeClientSide::udp) {
    if (o.listen_port < 0 || o.listen_port > 65535) {
      throw OptionError("udp", "udp port " + std::to_string(o.listen_port) +
                                   " is out of range (0 to 65535; 0 picks a free port)");
    }
    if (o.protocol == BridgeProtocol::rfc2217) {
      throw OptionError("protocol", "protocol rfc2217 needs a TCP listener, not udp");
    }
    if (!o.udp_peer_host.empty() && (o.udp_peer_port < 1 || o.udp_peer_port > 65535)) {
      throw OptionError("peer", "udp peer port " + std::to_string(o.udp_peer_port) +
                                    " is out of range (1 to 65535)");
    }
  }
  if (o.client_side != BridgeClientSide::udp && !o.udp_peer_host.empty()) {
    throw OptionError("peer", "a udp peer needs the udp client side");
  }
  if (o.client_side == BridgeClientSide::pty && o.protocol == BridgeProtocol::rfc2217) {
    throw OptionError("protocol", "protocol rfc2217 needs a TCP listener, not a pty");
  }
  if (o.client_side == BridgeClientSide::tcp && o.listen_backlog < 1) {
    throw OptionError("backlog", "the listen backlog must be at least 1, not " +
                                     std::to_string(o.listen_backlog));
  }
  if (o.client_side == BridgeClientSide::tcp && o.shared && o.max_monitors < 1) {
    throw OptionError("max_monitors", "max_monitors must be at least 1 with shared");
  }
  if (o.buffer_limit < kChunk) {
    throw OptionError("buffer_limit", "buffer_limit must be at least 65536 bytes");
  }
  if (o.duration && o.duration->count() <= 0) {
    throw OptionError("duration", "duration must be positive (seconds)");
  }
  if (o.flush_ms < 1) throw OptionError("flush_ms", "flush_ms must be at least 1");
  if (o.recorder && !o.output.empty()) {
    throw OptionError("output", "the bridge records either into its own file (output) or into "
                                "a recorder's channel (recorder), not both");
  }
  if (o.recorder && !o.metadata.empty()) {
    throw OptionError("metadata", "metadata goes into the header of the recorder's file (" +
                                      o.recorder->path() + "), which the recorder was made "
                                      "with, not into one of its channels");
  }
  if (o.recorder) {
    if (const auto problem = channel_name_problem(o.channel)) {
      throw OptionError("channel", "the bridge's channel in " + o.recorder->path() + ": " +
                                       *problem);
    }
  } else if (!o.channel.empty()) {
    throw OptionError("channel", "channel \"" + o.channel +
                                     "\" names a channel of a recorder, and no recorder is given");
  }
  if (o.pty_mode > 0777) {
    throw OptionError("pty_mode", "pty_mode " + octal(o.pty_mode) +
                                      " has bits beyond the permission bits 0777");
  }
  if (!o.pty_group.empty() && !detail::find_group(o.pty_group)) {
    throw OptionError("pty_group", "pty_group: there is no group " + o.pty_group);
  }
}

Bridge::~Bridge() {
  stop();
  std::lock_guard<std::mutex> join_lock(impl_->join_mutex_);
  if (impl_->thread_.joinable()) impl_->thread_.join();
}

void Bridge::start() {
  Impl& impl = *impl_;
  Status& status = impl.status_;
  {
    std::lock_guard<std::mutex> lock(status.mutex);
    if (status.started) throw std::logic_error("Bridge::start: already started");
    status.started = true;
  }
  std::string failure = "the bridge could not start";
  try {
    try {
      {
        WakePipe wake("bridge");
        std::lock_guard<std::mutex> lock(status.mutex);
        impl.wake_.emplace(std::move(wake));
      }
      impl.open_all();
    } catch (const std::exception& error) {
      failure = error.what();
      throw;
    }
  } catch (...) {
    impl.endpoint_.reset();
    impl.device_.abandon();
    std::lock_guard<std::mutex> lock(status.mutex);
    status.finished = true;
    status.result.outcome = BridgeOutcome::failed;
    status.result.message = failure;
    throw;
  }
  {
    std::lock_guard<std::mutex> lock(status.mutex);
    status.result.outcome = BridgeOutcome::running;
  }
  impl.thread_ = std::thread([&impl] {
    impl.run();
    std::lock_guard<std::mutex> lock(impl.status_.mutex);
    impl.status_.result.outcome = impl.end_outcome_;
    impl.status_.result.message = impl.end_message_;
    impl.status_.result.nothing_served = impl.nothing_served_;
    impl.status_.result.ended_by_fault = impl.ended_by_fault_;
    impl.status_.finished = true;
    impl.status_.finished_cv.notify_all();
  });
}

void Bridge::stop() {
  Impl& impl = *impl_;
  impl.stop_requested_.store(true);
  std::lock_guard<std::mutex> lock(impl.status_.mutex);
  if (impl.wake_) impl.wake_->wake();
}

bool Bridge::wait(Timeout timeout) {
  Impl& impl = *impl_;
  std::unique_lock<std::mutex> lock(impl.status_.mutex);
  const auto done = [&] { return impl.status_.finished || !impl.status_.started; };
  if (!timeout) {
    impl.status_.finished_cv.wait(lock, done);
  } else if (!impl.status_.finished_cv.wait_for(lock, *timeout, done)) {
    return false;
  }
  lock.unlock();
  if (impl.thread_.joinable() && impl.thread_.get_id() != std::this_thread::get_id()) {
    // The thread has set finished as its last act; joining is immediate.
    std::lock_guard<std::mutex> join_lock(impl.join_mutex_);
    if (impl.thread_.joinable()) impl.thread_.join();
  }
  return true;
}

bool Bridge::running() const {
  std::lock_guard<std::mutex> lock(impl_->status_.mutex);
  return impl_->status_.started && !impl_->status_.finished;
}

BridgeResult Bridge::result() const {
  std::lock_guard<std::mutex> lock(impl_->status_.mutex);
  BridgeResult result = impl_->status_.result;
  result.stats = impl_->status_.stats();
  return result;
}

BridgeStats Bridge::stats() const {
  std::lock_guard<std::mutex> lock(impl_->status_.mutex);
  return impl_->status_.stats();
}

std::string Bridge::pty_path() const {
  std::lock_guard<std::mutex> lock(impl_->status_.mutex);
  return impl_->status_.pty_path;
}

std::string Bridge::listen_address() const {
  std::lock_guard<std::mutex> lock(impl_->status_.mutex);
  return impl_->status_.listen_address;
}

std::string Bridge::device_description() const {
  std::lock_guard<std::mutex> lock(impl_->status_.mutex);
  return impl_->status_.device_description;
}

std::vector<std::string> Bridge::messages() const {
  std::lock_guard<std::mutex> lock(impl_->status_.mutex);
  return {impl_->status_.messages.begin(), impl_->status_.messages.end()};
}

}  // namespace wiretape
