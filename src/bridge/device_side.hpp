// The bridge's device side: the device port and what happens to it (open,
// loss, reopen, restart), the queue of client data waiting for it, its line
// state as clients see it, and the session file everything is recorded
// into. Client endpoints and the RFC 2217 adapter act on the device through
// this class alone; it is the one place that writes records.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "bridge/byte_queue.hpp"
#include "bridge/status.hpp"
#include "posix/poll_set.hpp"
#include "session/record_kinds.hpp"
#include "wiretape/bridge.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

namespace wiretape::detail::bridge {

using Clock = std::chrono::steady_clock;

// The device's modem inputs (record_kinds.hpp: they are recorded).
using detail::ModemInputs;

enum class ModemOutput { dtr, rts };

class DeviceSide {
 public:
  // Called after the device went away and was closed, with the reason.
  using LostHandler = std::function<void(const std::string& reason)>;

  DeviceSide(const BridgeOptions& options, Status& status)
      : options_(options), status_(status) {}

  // --- the device ------------------------------------------------------------
  // Opens the device from the options and records an open event (`why` names
  // a reopen or restart); the first open is time zero. Throws when the device
  // cannot be opened.
  void open(bool first, const char* why);
  // Starts the session file (if the options name one); call after the first
  // open.
  void open_session_file();
  bool is_open() const { return device_ != nullptr; }
  // The device is a recording played back: a virtual device (DESIGN.md
  // section 12).
  bool is_virtual() const {
    return device_ != nullptr && device_->capabilities().played_recording;
  }
  Port& port() { return *device_; }
  PortCapabilities capabilities() const;
  const std::string& description() const { return description_; }
  void on_lost(LostHandler handler) { on_lost_ = std::move(handler); }
  // The device went away: recorded, counted, closed; then the lost handler.
  void lost(const std::string& reason);
  // The last device lost was a replay's injected fault (faults=): TCP
  // clients see it as a reset (docs/faults.md).
  bool lost_by_fault() const { return lost_by_fault_; }
  // The replay's injected silence (KIND@WHERE) when one fired, as the
  // device was when shut_down() closed it; empty otherwise.
  const std::string& silenced_by_fault() const { return silenced_by_fault_; }
  // Closes the device and opens it again (a replay starts over).
  void restart();
  // Closes the device and the session file when the bridge ends, turning a
  // replay's mismatch at close or a failed file into the bridge's outcome.
  void shut_down(BridgeOutcome& outcome, std::string& message);
  // Undoes a start that failed: nothing is left open, and no session file
  // that holds nothing.
  void abandon();

  // --- recording -----------------------------------------------------------
  std::uint64_t now_ns() const;
  // Records an event or data into the session file, if there is one. Never
  // throws for the file: the first write that fails (full disk, file-size
  // limit) is reported once, recording stops there and forwarding goes on;
  // the file keeps the whole records before the failure, and shut_down()
  // turns the failure into the bridge's result.
  // A recorder's channel is stamped as the record enters the file, so that
  // the channels of several bridges are in time order across channels.
  void record(RecordKind kind, std::string_view data);
  // One read of the device now, of up to `size` bytes, recorded (rx): the
  // bytes read, none when none wait. Where the bridge has a file of its own
  // they are read straight into its buffer (no copy; `in_place` lets them
  // be used until the next record, which the caller makes sure of), else
  // into `buffer`. Raises PortClosed when the device went away.
  std::string_view read_and_record(char* buffer, std::size_t size, bool in_place);
  void record_at(RecordKind kind, std::uint64_t t_ns, std::string_view data);
  // A client arriving and leaving, as every endpoint reports it. A
  // controlling client's arrival begins a client session of a replayed
  // device (DESIGN.md section 12); true when that session starts afresh,
  // so that device data still queued for an earlier client or for nobody
  // is dropped.
  bool client_connected(const std::string& peer, const char* role);
  void client_disconnected(const std::string& peer, const std::string& reason);

  // --- client -> device ------------------------------------------------------
  // How many more client bytes the queue to the device takes.
  std::size_t room_for_client_data() const;
  bool has_data_for_device() const { return !to_device_.empty(); }
  // Client bytes for the device: recorded (tx), queued and written as far as
  // the device takes them now. Dropped while the device is away.
  void send(const char* data, std::size_t size);
  // Writes what is queued, as far as the device takes it now.
  void flush();
  // A datagram endpoint's datagram for the device: as send(), and an empty
  // one is recorded and sent as an empty datagram to a datagram port.
  void send_datagram(const char* data, std::size_t size);
  // One read of the device for a datagram endpoint, now: the size of the
  // next datagram (0 for an empty one from a datagram port), or nothing
  // when none waits. Raises PortClosed when the device went away.
  std::optional<std::size_t> read_datagram(char* buffer, std::size_t size);
  // poll() shows a datagram port's bounced datagram (ICMP port unreachable
  // from the device) as an error: taken here, and no longer a hang-up.
  void take_datagram_bounce(Readiness& ready);

  // --- the line ----------------------------------------------------------------
  // The device's line settings, or for a device without any (tcp) the ones
  // clients set.
  SerialSettings current_settings();
  // Applies `target` to the device (or to the virtual line), records it;
  // false if the device refused. `source` names who asked, for the record.
  bool apply_settings(const SerialSettings& target, const char* source);
  bool output_level(ModemOutput line) const { return line == ModemOutput::dtr ? dtr_ : rts_; }
  void set_output_level(ModemOutput line, bool level);
  bool break_on() const { return break_since_.has_value(); }
  void start_break();
  // Sends a break as long as it was on, and records it.
  void end_break();
  // Sends a break of `on` and records it (a timed break: tcsendbreak).
  void send_break_for(std::chrono::milliseconds on);
  void purge(bool from_device, bool for_device);
  // The device's modem inputs; nothing where it has none.
  std::optional<ModemInputs> modem_inputs();
  // Whether watching the modem inputs for changes makes sense.
  bool modem_inputs_watchable() const;
  // True when the modem inputs changed since the last call; a change is
  // recorded (DESIGN.md section 20), the first reading too.
  bool modem_inputs_changed();

 private:
  // Appends at `t_ns`, or stamped by the recorder as it enters the file.
  void append_record(RecordKind kind, std::optional<std::uint64_t> t_ns, std::string_view data);

  const BridgeOptions& options_;
  Status& status_;
  std::unique_ptr<Port> device_;
  bool lost_by_fault_ = false;
  std::string silenced_by_fault_;
  std::string description_;
  // What the bridge records into: a file of its own (output, one unnamed
  // channel; owns_file_) or a channel of the options' recorder.
  std::optional<RecordingChannel> recording_;
  bool owns_file_ = false;
  bool recording_failed_ = false;
  // The records_written last put in the status, which is locked only when
  // the file's count has moved (at a flush, not at every record).
  std::uint64_t records_in_status_ = 0;
  Clock::time_point t0_;
  ByteQueue to_device_{options_.buffer_limit};
  LostHandler on_lost_;
  // Line state for devices that have none (tcp): what clients set.
  SerialSettings virtual_settings_;
  bool dtr_ = true;
  bool rts_ = true;
  std::optional<Clock::time_point> break_since_;
  std::optional<ModemInputs> last_modem_inputs_;
  bool modem_inputs_unreadable_ = false;
  bool bounce_reported_ = false;
  // The controlling client whose session a replayed device serves.
  std::optional<std::string> session_peer_;

  void recording_stopped(const PortError& error);
  void record_modem_inputs(const ModemInputs& inputs);
  // Adds what the device's port dropped (a udp device side: datagrams from
  // other senders) to the stats; call before the port closes.
  void count_what_the_port_dropped();
};

}  // namespace wiretape::detail::bridge
