#include "bridge/device_side.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <exception>

#include "posix/device_identity.hpp"
#include "posix/transports.hpp"
#include "replay/replay_port.hpp"
#include "session/record_kinds.hpp"
#include "session/recorder_file.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"

namespace wiretape::detail::bridge {

namespace event_field = detail::event_field;

namespace {

std::string settings_text(const SerialSettings& s) {
  char text[96];
  std::snprintf(text, sizeof text, "%u %d%c%d flow=%s", s.baud, s.data_bits,
                "NEOMS"[static_cast<int>(s.parity)], s.stop_bits, to_string(s.flow));
  return text;
}

bool is_unsupported(const PortError& error) {
  const int code = error.code().value();
  return code == ENOTSUP || code == ENOTTY || code == EINVAL || code == ENOSYS;
}

// The count is the writer's: records in the file, not records buffered (a
// write failure loses those), so the summary matches what verify finds.
void count_records_written(Status& status, const RecordingChannel& recording) {
  const std::uint64_t in_file = recording.records_written();
  status.update_stats([in_file](BridgeStats& s) { s.records_written = in_file; });
}

}  // namespace

// --- the device ----------------------------------------------------------------------

void DeviceSide::open(bool first, const char* why) {
  device_ = open_port(options_.device);
  // Never block the loop: writes take what the device accepts now.
  device_->set_timeout(std::chrono::nanoseconds(0));
  last_modem_inputs_.reset();
  modem_inputs_unreadable_ = false;
  if (first) t0_ = Clock::now();
  description_ = device_->description();
  status_.set(&Status::device_description, description_);
  // A replayed device serves client sessions: nothing before a client
  // connects (a device reopened while its client stays goes on serving it).
  if (replay_await_client(*device_) && session_peer_ && !first) {
    replay_begin_client_session(*device_);
  }
  try {
    virtual_settings_ = device_->serial_settings();
  } catch (const PortError&) {
  }
  EventMembers event{{event_field::description, description_}};
  if (why) event.emplace_back(why, true);
  // Time zero is the device's first open.
  if (first) {
    record_at(RecordKind::open, 0, event_payload(RecordKind::open, event));
  } else {
    record(RecordKind::open, event_payload(RecordKind::open, event));
  }
}

void DeviceSide::open_session_file() {
  if (options_.output.empty() && !options_.recorder) return;
  Channel channel;
  channel.name = options_.channel;
  channel.capture = Capture::wire;
  channel.port_options = options_.device;
  channel.port_type = device_->type();
  // A serial device's identity (DESIGN §20); a pty or a network device has none.
  for (const auto& entry : parse_options(options_.device)) {
    if (entry.key == "device") channel.device_identity = read_device_identity(entry.value);
  }
  if (options_.recorder) {
    // A network device's address, for the exports (docs/session-format.md).
    std::string host, port;
    for (const auto& entry : parse_options(options_.device)) {
      if (entry.key == "host") host = entry.value;
      if (entry.key == "port") port = entry.value;
    }
    if (!host.empty() && !port.empty()) {
      channel.device_address =
          (host.find(':') != std::string::npos ? "[" + host + "]" : host) + ":" + port;
    }
    recording_ = options_.recorder->add_channel(channel);
    owns_file_ = false;
    record(RecordKind::open,
           event_payload(RecordKind::open, {{event_field::description, description_}}));
    return;
  }
  SessionHeader header = SessionHeader::starting_now();
  header.capture = channel.capture;
  header.port_options = channel.port_options;
  header.port_type = channel.port_type;
  header.device_identity = channel.device_identity;
  header.user_metadata = options_.metadata;
  recording_ = single_channel_file(options_.output, header,
                                   FlushPolicy{std::chrono::milliseconds(options_.flush_ms),
                                               false, options_.compression});
  owns_file_ = true;
  // Time zero is the device's open, which came just before the file.
  record_at(RecordKind::open, 0,
            event_payload(RecordKind::open, {{event_field::description, description_}}));
}

PortCapabilities DeviceSide::capabilities() const {
  return device_ ? device_->capabilities() : PortCapabilities{};
}

void DeviceSide::count_what_the_port_dropped() {
  const auto* datagrams = dynamic_cast<const DatagramPort*>(device_.get());
  const std::uint64_t from_others = datagrams ? datagrams->datagrams_from_others() : 0;
  if (from_others == 0) return;
  status_.update_stats([from_others](BridgeStats& s) { s.datagrams_from_others += from_others; });
  status_.message("dropped " + std::to_string(from_others) +
                  " datagrams that another sender than the device sent to the device side "
                  "(neither recorded nor forwarded)");
}

void DeviceSide::lost(const std::string& reason) {
  if (!device_) return;
  count_what_the_port_dropped();
  lost_by_fault_ = replay_lost_by_fault(*device_);
  record(RecordKind::device_lost,
         event_payload(RecordKind::device_lost, {{event_field::error, reason}}));
  status_.update_stats([](BridgeStats& s) { ++s.device_losses; });
  status_.message("the device (" + description_ + ") went away: " + reason);
  try {
    device_->close();
  } catch (const ReplayMismatch&) {
    throw;
  } catch (const std::exception&) {
  }
  device_.reset();
  to_device_.clear();
  if (on_lost_) on_lost_(reason);
}

void DeviceSide::restart() {
  if (device_) {
    count_what_the_port_dropped();
    record(RecordKind::close, "{}");
    device_->close();
    device_.reset();
  }
  to_device_.clear();
  open(false, event_field::restarted);
  status_.message("a new client: the device starts over");
}

void DeviceSide::shut_down(BridgeOutcome& outcome, std::string& message) {
  if (device_) {
    count_what_the_port_dropped();
    silenced_by_fault_ = replay_silenced_by_fault(*device_);
    try {
      record(RecordKind::close, "{}");
    } catch (const std::exception&) {
    }
    try {
      device_->close();
    } catch (const ReplayMismatch& mismatch) {
      if (outcome != BridgeOutcome::failed) {
        outcome = BridgeOutcome::mismatch;
        message = mismatch.what();
      }
    } catch (const std::exception& error) {
      status_.message(std::string("closing the device: ") + error.what());
    }
    device_.reset();
  }
  if (recording_ && !owns_file_) {
    // The recorder's file stays open for its other channels.
    count_records_written(status_, *recording_);
    recording_.reset();
  }
  if (recording_) {
    try {
      RecordingChannelAccess::file(*recording_).close();
      count_records_written(status_, *recording_);
    } catch (const std::exception& error) {
      count_records_written(status_, *recording_);
      // The session file misses what came after the failure: that is the
      // bridge's result, whatever else ended it.
      if (outcome != BridgeOutcome::mismatch) {
        outcome = BridgeOutcome::failed;
        message = std::string(recording_failed_ ? "the recording stopped early: "
                                                : "writing the session file: ") +
                  error.what();
      }
    }
    recording_.reset();
  }
}

void DeviceSide::abandon() {
  device_.reset();
  if (recording_ && owns_file_) {
    try {
      RecordingChannelAccess::file(*recording_).close();
    } catch (...) {
    }
    std::remove(options_.output.c_str());
  }
  recording_.reset();
}

// --- recording ---------------------------------------------------------------------------

std::uint64_t DeviceSide::now_ns() const {
  // A recorder's channels share its clock.
  if (recording_ && !owns_file_) return recording_->now_ns();
  return static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - t0_).count());
}

void DeviceSide::record(RecordKind kind, std::string_view data) {
  if (recording_ && !owns_file_) {
    append_record(kind, std::nullopt, data);
  } else {
    append_record(kind, now_ns(), data);
  }
}

namespace {

// A device read into the session writer's buffer (write_filled).
struct DeviceRead {
  DeviceSide* side;
  Port* device;
  std::exception_ptr error;  // the device's, raised once the writer is let go
};

SessionWriter::Filled read_into_record(void* context, char* room, std::size_t size) {
  auto& read = *static_cast<DeviceRead*>(context);
  try {
    const std::size_t n = read.device->read(room, size, std::chrono::nanoseconds(0));
    return {n, read.side->now_ns()};
  } catch (...) {
    read.error = std::current_exception();
    return {};
  }
}

}  // namespace

std::string_view DeviceSide::read_and_record(char* buffer, std::size_t size, bool in_place) {
  if (in_place && recording_ && owns_file_ && !recording_failed_) {
    DeviceRead read{this, device_.get(), nullptr};
    std::string_view bytes;
    try {
      RecordingChannelAccess::file(*recording_).writer.write_filled(
          RecordKind::rx, size, &read_into_record, &read, &bytes, recording_->id());
    } catch (const PortError& error) {
      // The file failed (as append_record handles it): recording stops; what
      // was read, if anything, is still the clients'.
      recording_stopped(error);
      count_records_written(status_, *recording_);
      if (read.error) std::rethrow_exception(read.error);
      if (bytes.data() != nullptr) return bytes;
      return read_and_record(buffer, size, false);
    }
    if (read.error) std::rethrow_exception(read.error);
    const std::uint64_t in_file = recording_->records_written();
    if (in_file != records_in_status_) {
      records_in_status_ = in_file;
      status_.update_stats([in_file](BridgeStats& s) { s.records_written = in_file; });
    }
    return bytes;
  }
  const std::size_t n = device_->read(buffer, size, std::chrono::nanoseconds(0));
  if (n > 0) record(RecordKind::rx, std::string_view(buffer, n));
  return std::string_view(buffer, n);
}

void DeviceSide::record_at(RecordKind kind, std::uint64_t t_ns, std::string_view data) {
  append_record(kind, t_ns, data);
}

void DeviceSide::append_record(RecordKind kind, std::optional<std::uint64_t> t_ns,
                               std::string_view data) {
  if (!recording_ || recording_failed_) return;
  try {
    if (t_ns) {
      recording_->write(kind, *t_ns, data);
    } else {
      recording_->write_now(kind, data);
    }
  } catch (const PortError& error) {
    // The recorder was closed under the bridge: the session has ended.
    if (recording_->file_closed() && !owns_file_) return;
    recording_stopped(error);
    count_records_written(status_, *recording_);
    return;
  }
  const std::uint64_t in_file = recording_->records_written();
  if (in_file != records_in_status_) {
    records_in_status_ = in_file;
    status_.update_stats([in_file](BridgeStats& s) { s.records_written = in_file; });
  }
}

void DeviceSide::recording_stopped(const PortError& error) {
  recording_failed_ = true;
  status_.message(std::string("recording stopped: ") + error.what() +
                  "; forwarding goes on without recording");
}

bool DeviceSide::client_connected(const std::string& peer, const char* role) {
  record(RecordKind::client_connect,
         event_payload(RecordKind::client_connect,
                       {{event_field::peer, peer}, {event_field::role, std::string(role)}}));
  status_.update_stats([](BridgeStats& s) { ++s.clients_accepted; });
  if (session_peer_ || std::string_view(role) == "monitor") return false;
  session_peer_ = peer;
  const bool fresh = device_ && replay_begin_client_session(*device_);
  // The device's lines as this client finds them, recorded before anything
  // the client does: a replay checks the client's lines only where the
  // recording holds the device's.
  if (modem_inputs_watchable()) {
    last_modem_inputs_.reset();
    try {
      if (const auto inputs = modem_inputs()) record_modem_inputs(*inputs);
    } catch (const PortClosed&) {
      // The loop's poll notices the loss.
    }
  }
  return fresh;
}

void DeviceSide::client_disconnected(const std::string& peer, const std::string& reason) {
  record(RecordKind::client_disconnect,
         event_payload(RecordKind::client_disconnect,
                       {{event_field::peer, peer}, {event_field::reason, reason}}));
  if (session_peer_ != peer) return;
  session_peer_.reset();
  if (device_) replay_await_client(*device_);
}

// --- client -> device ------------------------------------------------------------------

std::size_t DeviceSide::room_for_client_data() const {
  return to_device_.room();
}

std::optional<std::size_t> DeviceSide::read_datagram(char* buffer, std::size_t size) {
  if (auto* datagrams = dynamic_cast<DatagramPort*>(device_.get())) {
    return datagrams->receive_datagram(buffer, size);
  }
  // A Port's read of 0 bytes means none now: an empty datagram of another
  // port (a replay) does not get through.
  const std::size_t n = device_->read(buffer, size, std::chrono::nanoseconds(0));
  if (n == 0) return std::nullopt;
  return n;
}

void DeviceSide::take_datagram_bounce(Readiness& ready) {
  if (!ready.hung_up || !device_) return;
  auto* datagrams = dynamic_cast<DatagramPort*>(device_.get());
  if (!datagrams) return;
  ready.hung_up = false;
  const int error = datagrams->take_error();
  if (error != 0 && !bounce_reported_) {
    bounce_reported_ = true;
    status_.message(system_error_message(
        "a datagram to the device (" + description_ + ") bounced: it was recorded but not "
        "received", error));
  }
}

void DeviceSide::send_datagram(const char* data, std::size_t size) {
  // Only an empty datagram needs the port's datagram side: the cast costs
  // more than the rest of a datagram's forwarding (a type name compared).
  auto* datagrams = size == 0 && device_ ? dynamic_cast<DatagramPort*>(device_.get()) : nullptr;
  if (datagrams == nullptr) {
    send(data, size);
    return;
  }
  // An empty datagram is a datagram: recorded, and sent as one.
  record(RecordKind::tx, std::string_view());
  try {
    datagrams->send_empty_datagram();
  } catch (const PortClosed& closed) {
    lost(closed.what());
  }
}

void DeviceSide::send(const char* data, std::size_t size) {
  if (!device_ || size == 0) return;
  record(RecordKind::tx, std::string_view(data, size));
  if (to_device_.empty()) {
    // Written from the caller's buffer while nothing waits before it: only
    // what the device does not take now is copied into the queue.
    std::size_t n = 0;
    try {
      n = device_->write(data, size);
    } catch (const PortClosed& closed) {
      lost(closed.what());
      return;
    }
    if (n > 0) status_.add_bytes_to_device(n);
    if (n == size) return;
    to_device_.append(data + n, size - n);
    if (n == 0) return;
  } else {
    to_device_.append(data, size);
  }
  flush();
}

void DeviceSide::flush() {
  while (device_ && !to_device_.empty()) {
    std::size_t n = 0;
    try {
      n = device_->write(to_device_.data(), to_device_.size());
    } catch (const PortClosed& closed) {
      lost(closed.what());
      return;
    }
    if (n == 0) return;
    to_device_.consume(n);
    status_.add_bytes_to_device(n);
  }
}

// --- the line ----------------------------------------------------------------------------

SerialSettings DeviceSide::current_settings() {
  if (device_) {
    try {
      return device_->serial_settings();
    } catch (const PortClosed&) {
      throw;
    } catch (const PortError&) {
    }
  }
  return virtual_settings_;
}

bool DeviceSide::apply_settings(const SerialSettings& target, const char* source) {
  // RFC 2217 clients send every setting on open: only changes are applied
  // and recorded.
  if (target == current_settings()) return true;
  bool applied = false;
  if (capabilities().serial_settings) {
    try {
      device_->configure(target);
      applied = true;
    } catch (const PortClosed&) {
      throw;
    } catch (const PortError& error) {
      if (!is_unsupported(error) || error.code().value() == EINVAL) {
        status_.message(std::string("the device refused ") + settings_text(target) + ": " +
                        error.what());
        return false;
      }
    }
  }
  // A device without line settings (tcp) keeps them as the client's view of
  // the line.
  virtual_settings_ = target;
  status_.update_stats([](BridgeStats& s) { ++s.settings_changes; });
  record(RecordKind::settings,
         event_payload(RecordKind::settings,
                       {{event_field::baud, std::int64_t{target.baud}},
                        {event_field::databits, std::int64_t{target.data_bits}},
                        {event_field::stopbits, std::int64_t{target.stop_bits}},
                        {event_field::parity, std::string(to_string(target.parity))},
                        {event_field::flow, std::string(to_string(target.flow))},
                        {event_field::applied, applied},
                        {event_field::source, std::string(source)}}));
  status_.message(std::string(applied ? "device set to "
                                      : "line set to (device has no line settings) ") +
                  settings_text(target) + " by the " + source);
  return true;
}

void DeviceSide::set_output_level(ModemOutput line, bool level) {
  // The bytes the client sent before the change reach the device before it.
  flush();
  bool applied = false;
  if (capabilities().modem_lines) {
    try {
      if (line == ModemOutput::dtr) device_->set_dtr(level);
      else device_->set_rts(level);
      applied = true;
    } catch (const PortClosed&) {
      throw;
    } catch (const PortError&) {
      // Acknowledged and noted, as for a device without modem lines.
    }
  }
  (line == ModemOutput::dtr ? dtr_ : rts_) = level;
  record(RecordKind::modem_lines,
         event_payload(RecordKind::modem_lines,
                       {{line == ModemOutput::dtr ? event_field::dtr : event_field::rts, level},
                        {event_field::applied, applied}}));
}

void DeviceSide::start_break() {
  if (!break_since_) break_since_ = Clock::now();
}

void DeviceSide::end_break() {
  if (!break_since_) return;
  // The Port sends a break of a given length: the time it was on.
  auto on = std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - *break_since_);
  on = std::clamp(on, std::chrono::milliseconds(1), std::chrono::milliseconds(2000));
  break_since_.reset();
  send_break_for(on);
}

void DeviceSide::send_break_for(std::chrono::milliseconds on) {
  flush();
  bool applied = false;
  if (capabilities().send_break) {
    try {
      device_->send_break(on);
      applied = true;
    } catch (const PortClosed&) {
      throw;
    } catch (const PortError&) {
    }
  }
  record(RecordKind::line_break,
         event_payload(RecordKind::line_break,
                       {{event_field::duration_ms, std::int64_t{on.count()}},
                        {event_field::applied, applied}}));
}

void DeviceSide::purge(bool from_device, bool for_device) {
  if (from_device) {
    // What is already queued for a client stays: Telnet answers share that
    // queue, and the client drops its own buffer anyway.
    device_->flush_input();
    record(RecordKind::flush_input, "{}");
  }
  if (for_device) {
    device_->flush_output();
    to_device_.clear();
    record(RecordKind::flush_output, "{}");
  }
}

std::optional<ModemInputs> DeviceSide::modem_inputs() {
  if (!capabilities().modem_lines) return std::nullopt;
  try {
    ModemInputs inputs;
    inputs.cd = device_->cd();
    inputs.ri = device_->ri();
    inputs.dsr = device_->dsr();
    inputs.cts = device_->cts();
    return inputs;
  } catch (const PortClosed&) {
    throw;
  } catch (const PortError&) {
    return std::nullopt;
  }
}

bool DeviceSide::modem_inputs_watchable() const {
  return device_ && capabilities().modem_lines && !modem_inputs_unreadable_;
}

bool DeviceSide::modem_inputs_changed() {
  std::optional<ModemInputs> inputs;
  try {
    inputs = modem_inputs();
  } catch (const PortClosed& closed) {
    lost(closed.what());
    return false;
  }
  if (!inputs) {
    modem_inputs_unreadable_ = true;  // stop asking
    return false;
  }
  if (last_modem_inputs_ == inputs) return false;
  record_modem_inputs(*inputs);
  return true;
}

void DeviceSide::record_modem_inputs(const ModemInputs& inputs) {
  last_modem_inputs_ = inputs;
  record(RecordKind::modem_lines, modem_inputs_payload(inputs));
}

}  // namespace wiretape::detail::bridge
