// The bridge's end of the side channel of the `--as` shim (DESIGN §20;
// protocol in src/shim/line_protocol.h): what a program does to the serial
// lines of its redirected descriptor, which its pty cannot carry. A
// listening Unix socket; the pty endpoint polls it with the terminal.
//
// Line changes are held until the pty endpoint has relayed as many of the
// client's bytes as the client had written when it made them, then applied
// to the device through DeviceSide (a recording port applies and records,
// a replay port serves and checks) and answered: so a change falls exactly
// where the client made it among its bytes.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <list>
#include <string>

#include "bridge/device_side.hpp"
#include "bridge/status.hpp"
#include "posix/poll_set.hpp"
#include "posix/syscalls.hpp"
#include "shim/line_protocol.h"

namespace wiretape::detail::bridge {

class LineChannel {
 public:
  // The client changed its terminal's settings: read and apply them.
  using SettingsHandler = std::function<void()>;
  // Client bytes written to the terminal but not yet read from it.
  using UnreadCounter = std::function<std::uint64_t()>;

  // Listens at `path` (which must not exist). Throws PortError.
  LineChannel(const std::string& path, DeviceSide& device, Status& status,
              SettingsHandler on_settings, UnreadCounter unread);
  ~LineChannel();
  LineChannel(const LineChannel&) = delete;
  LineChannel& operator=(const LineChannel&) = delete;

  void add_to_poll(PollSet& poll_set);
  // Accepts and reads requests; answers those that need not wait.
  void handle_events(const PollSet& poll_set, std::uint64_t relayed);
  // How many more client bytes may be relayed before a held change is due
  // (UINT64_MAX: none is held).
  std::uint64_t bytes_before_next_change(std::uint64_t relayed) const;
  // Applies and answers what is due once `relayed` client bytes are relayed.
  void apply_due(std::uint64_t relayed);
  // A shim is connected: it reports the client's settings changes itself.
  bool has_clients() const { return !connections_.empty(); }
  // The device's inputs are watched while a shim is connected (for
  // TIOCMIWAIT and TIOCGICOUNT).
  Clock::time_point next_timer() const;
  void run_timers(Clock::time_point now);

 private:
  struct Connection {
    sys::UniqueFd fd;
    std::uint64_t base = 0;  // relayed client bytes at its hello
    std::deque<wt_line_request> pending;
    PollSet::Slot slot = PollSet::none;
    bool waiting = false;  // a WAIT is answered when the inputs change
    std::uint32_t wait_mask = 0;
    std::uint32_t wait_from = 0;  // the inputs when it began waiting
  };

  void accept_all();
  // False when the connection closed.
  bool receive(Connection& connection, std::uint64_t relayed);
  // Answers what can be answered, in order, up to the first held change.
  void serve(Connection& connection, std::uint64_t relayed);
  bool apply(const wt_line_request& request, wt_line_reply& reply);
  void answer(Connection& connection, const wt_line_reply& reply);
  std::uint32_t lines();
  void watch_inputs();
  wt_line_reply reply_of(std::int32_t error);

  std::string path_;
  DeviceSide& device_;
  Status& status_;
  SettingsHandler on_settings_;
  UnreadCounter unread_;
  sys::UniqueFd listener_;
  PollSet::Slot listener_slot_ = PollSet::none;
  std::list<Connection> connections_;
  std::uint32_t last_inputs_ = 0;
  bool inputs_known_ = false;
  std::uint32_t changes_[4] = {0, 0, 0, 0};  // cts, dsr, ri, cd
  Clock::time_point next_watch_;
};

}  // namespace wiretape::detail::bridge
