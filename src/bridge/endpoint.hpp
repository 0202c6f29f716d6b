// The bridge's client side: where the programs that talk to the device come
// from. Today a pseudo-terminal (pty_endpoint.cpp) or a TCP listener and its
// connections (tcp_endpoint.cpp); the interface assumes neither a stream nor
// a terminal, so that a datagram endpoint fits the same loop.
//
// Each round of the bridge's loop asks the endpoint what to poll, hands it
// what poll() saw, and runs its timers. Client data goes to the device
// through DeviceSide::send(); device data comes in through
// deliver_from_device(). Clients arriving and leaving are reported through
// DeviceSide::client_connected()/client_disconnected().
#pragma once

#include <memory>
#include <string>

#include "bridge/device_side.hpp"
#include "bridge/status.hpp"
#include "posix/poll_set.hpp"
#include "wiretape/bridge.hpp"

namespace wiretape::detail::bridge {

class ClientEndpoint {
 public:
  virtual ~ClientEndpoint() = default;

  // Adds this round's descriptors (and what to wait for on each) to `poll_set`.
  virtual void add_to_poll(PollSet& poll_set) = 0;
  // Acts on what poll() saw on the descriptors added this round.
  virtual void handle_events(const PollSet& poll_set) = 0;
  // When the endpoint's next timer is due (Clock::time_point::max(): none),
  // and the timer work, run once per round after the events.
  virtual Clock::time_point next_timer() const { return Clock::time_point::max(); }
  virtual void run_timers(Clock::time_point /*now*/) {}

  // Whether device data is wanted now; when not, the bridge stops reading
  // the device (backpressure).
  virtual bool wants_device_data() const = 0;
  virtual void deliver_from_device(const char* data, std::size_t size) = 0;
  // Whether deliver_from_device() records nothing (DeviceSide::record)
  // before it is done with `data`, which may then be the record itself in
  // the session file's buffer, valid until the next record is written.
  virtual bool delivers_without_recording() const { return false; }
  // Whether each read of the device must be delivered on its own (a
  // datagram endpoint: one read is one datagram) rather than joined with
  // the reads after it.
  virtual bool keeps_datagram_boundaries() const { return false; }
  // The device went away (it is closed already): clients learn it as the
  // endpoint's medium allows.
  virtual void device_lost() {}
  // The device is back after a loss.
  virtual void device_reopened() {}
  // Whether any client is connected (the device's modem inputs are watched
  // only then).
  virtual bool has_clients() const = 0;
  // Whether a client has taken any of the device's data so far (read it from
  // the terminal, or its connection accepted it): a replay that served its
  // clients nothing is no success.
  virtual bool served_device_data() const = 0;
  // Why nothing was served when the endpoint knows better than the bridge
  // (a UDP peer that refused every datagram); "" otherwise.
  virtual std::string why_nothing_was_served() const { return ""; }
  // The device's modem inputs changed (RFC 2217 clients are told).
  virtual void modem_inputs_changed() {}
  // The bridge ends: flush what can be flushed, say goodbye, close.
  virtual void shut_down() = 0;
};

// The pty endpoint: opens the pseudo-terminal (and its link) at once.
std::unique_ptr<ClientEndpoint> make_pty_endpoint(const BridgeOptions& options,
                                                  DeviceSide& device, Status& status);
// The TCP endpoint: listens at once (before the device opens, so that a
// busy address fails the start early).
std::unique_ptr<ClientEndpoint> make_tcp_endpoint(const BridgeOptions& options,
                                                  DeviceSide& device, Status& status);

// The UDP endpoint: binds its socket at once (a busy address fails the
// start early).
std::unique_ptr<ClientEndpoint> make_udp_endpoint(const BridgeOptions& options,
                                                  DeviceSide& device, Status& status);

}  // namespace wiretape::detail::bridge
