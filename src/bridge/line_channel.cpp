#include "bridge/line_channel.hpp"

#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <limits>

#include "wiretape/errors.hpp"

namespace wiretape::detail::bridge {

namespace {

// The device's inputs are read this often while a shim is connected.
constexpr auto kInputWatchInterval = std::chrono::milliseconds(20);
// A break longer than this is cut (a client's TCSBRKP can ask for minutes).
constexpr std::uint32_t kLongestBreakMs = 2000;

bool held_for_bytes(std::uint32_t op) {
  return op == WT_LINE_SET_OUTPUTS || op == WT_LINE_BREAK || op == WT_LINE_BREAK_ON ||
         op == WT_LINE_BREAK_OFF || op == WT_LINE_SETTINGS || op == WT_LINE_DRAIN;
}

}  // namespace

LineChannel::LineChannel(const std::string& path, DeviceSide& device, Status& status,
                         SettingsHandler on_settings, UnreadCounter unread)
    : path_(path),
      device_(device),
      status_(status),
      on_settings_(std::move(on_settings)),
      unread_(std::move(unread)) {
  sockaddr_un address{};
  if (path.empty() || path.size() >= sizeof address.sun_path) {
    throw OptionError("line_channel", "line_channel: the socket path " + path +
                                          " is empty or longer than " +
                                          std::to_string(sizeof address.sun_path - 1) +
                                          " bytes");
  }
  listener_ = sys::UniqueFd(sys::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_NONBLOCK | SOCK_CLOEXEC, 0));
  if (!listener_) throw PortError(errno, "line channel " + path + ": socket");
  address.sun_family = AF_UNIX;
  std::memcpy(address.sun_path, path.data(), path.size());
  if (sys::bind(listener_.get(), reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
    throw PortError(errno, "line channel " + path + ": bind");
  }
  if (sys::listen(listener_.get(), 16) != 0) {
    const int error = errno;
    sys::unlink(path_.c_str());
    throw PortError(error, "line channel " + path + ": listen");
  }
}

LineChannel::~LineChannel() { sys::unlink(path_.c_str()); }

void LineChannel::add_to_poll(PollSet& poll_set) {
  listener_slot_ = poll_set.add(listener_.get(), true, false);
  for (Connection& connection : connections_) {
    connection.slot = poll_set.add(connection.fd.get(), true, false);
  }
}

void LineChannel::handle_events(const PollSet& poll_set, std::uint64_t relayed) {
  for (auto it = connections_.begin(); it != connections_.end();) {
    const Readiness ready = poll_set.ready(it->slot);
    if (ready.any() && !receive(*it, relayed)) {
      it = connections_.erase(it);
    } else {
      ++it;
    }
  }
  if (poll_set.ready(listener_slot_).readable) accept_all();
  apply_due(relayed);
}

void LineChannel::accept_all() {
  for (;;) {
    sys::UniqueFd fd(sys::accept4(listener_.get(), nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC));
    if (!fd) return;
    Connection connection;
    connection.fd = std::move(fd);
    connections_.push_back(std::move(connection));
    // Its first request may be waiting already.
    if (!receive(connections_.back(), 0)) connections_.pop_back();
  }
}

bool LineChannel::receive(Connection& connection, std::uint64_t relayed) {
  for (;;) {
    wt_line_request request{};
    const ssize_t got = sys::recv(connection.fd.get(), &request, sizeof request, 0);
    if (got == 0) return false;
    if (got < 0) return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR;
    if (got != static_cast<ssize_t>(sizeof request) || request.magic != WT_LINE_MAGIC) {
      status_.message("line channel: a message that is not the shim's; connection closed");
      return false;
    }
    connection.pending.push_back(request);
    (void)relayed;
  }
}

std::uint64_t LineChannel::bytes_before_next_change(std::uint64_t relayed) const {
  std::uint64_t fewest = std::numeric_limits<std::uint64_t>::max();
  for (const Connection& connection : connections_) {
    // A connection waiting for the inputs holds no bytes back: the shim
    // sends nothing more on it.
    if (connection.pending.empty() || connection.waiting) continue;
    const wt_line_request& next = connection.pending.front();
    if (!held_for_bytes(next.op)) continue;
    const std::uint64_t due_at = connection.base + next.written;
    fewest = std::min(fewest, due_at > relayed ? due_at - relayed : 0);
  }
  return fewest;
}

void LineChannel::apply_due(std::uint64_t relayed) {
  for (auto it = connections_.begin(); it != connections_.end(); ++it) serve(*it, relayed);
}

void LineChannel::serve(Connection& connection, std::uint64_t relayed) {
  while (!connection.pending.empty() && !connection.waiting) {
    const wt_line_request request = connection.pending.front();
    if (request.op == WT_LINE_HELLO) {
      // The shim waits for this answer before it writes: what the terminal
      // holds now was written before, by whoever wrote it.
      connection.base = relayed + unread_();
    } else if (held_for_bytes(request.op) && connection.base + request.written > relayed) {
      return;
    }
    connection.pending.pop_front();
    if (request.op == WT_LINE_WAIT) {
      connection.waiting = true;
      connection.wait_mask = request.set;
      connection.wait_from = lines();
      return;
    }
    wt_line_reply reply = reply_of(0);
    if (!apply(request, reply)) reply.error = EIO;
    answer(connection, reply);
  }
}

bool LineChannel::apply(const wt_line_request& request, wt_line_reply& reply) {
  if (!device_.is_open()) return request.op == WT_LINE_HELLO || request.op == WT_LINE_GET;
  try {
    switch (request.op) {
      case WT_LINE_SET_OUTPUTS:
        for (const auto& [bit, line] : {std::pair{TIOCM_DTR, ModemOutput::dtr},
                                        std::pair{TIOCM_RTS, ModemOutput::rts}}) {
          const std::uint32_t mask = static_cast<std::uint32_t>(bit);
          const bool level = (request.set & mask) ? true
                             : (request.clear & mask) ? false
                                                      : device_.output_level(line);
          if (level != device_.output_level(line)) device_.set_output_level(line, level);
        }
        break;
      case WT_LINE_BREAK:
        device_.send_break_for(std::chrono::milliseconds(
            std::min(std::max(request.value, std::uint32_t{1}), kLongestBreakMs)));
        break;
      case WT_LINE_BREAK_ON: device_.start_break(); break;
      case WT_LINE_BREAK_OFF: device_.end_break(); break;
      case WT_LINE_SETTINGS: on_settings_(); break;
      default: break;
    }
  } catch (const PortClosed& closed) {
    device_.lost(closed.what());
    return false;
  }
  reply.lines = lines();
  return true;
}

void LineChannel::answer(Connection& connection, const wt_line_reply& reply) {
  // The shim waits for it: a full socket (it cannot be, one request at a
  // time) would only drop the answer and leave the shim to time out.
  (void)sys::send(connection.fd.get(), &reply, sizeof reply, MSG_NOSIGNAL);
}

wt_line_reply LineChannel::reply_of(std::int32_t error) {
  wt_line_reply reply{};
  reply.error = error;
  reply.lines = lines();
  reply.cts_changes = changes_[0];
  reply.dsr_changes = changes_[1];
  reply.ri_changes = changes_[2];
  reply.cd_changes = changes_[3];
  return reply;
}

// The device's inputs as TIOCMGET shows them; a device without modem lines
// (a pty, a recording without line events) shows CTS, DSR and CD asserted.
std::uint32_t LineChannel::lines() {
  std::uint32_t bits = 0;
  std::optional<ModemInputs> inputs;
  if (device_.is_open()) {
    try {
      inputs = device_.modem_inputs();
    } catch (const PortClosed& closed) {
      device_.lost(closed.what());
    }
  }
  if (inputs) {
    if (inputs->cts) bits |= TIOCM_CTS;
    if (inputs->dsr) bits |= TIOCM_DSR;
    if (inputs->ri) bits |= TIOCM_RI;
    if (inputs->cd) bits |= TIOCM_CD;
  } else {
    bits = TIOCM_CTS | TIOCM_DSR | TIOCM_CD;
  }
  if (device_.output_level(ModemOutput::dtr)) bits |= TIOCM_DTR;
  if (device_.output_level(ModemOutput::rts)) bits |= TIOCM_RTS;
  return bits;
}

Clock::time_point LineChannel::next_timer() const {
  return connections_.empty() ? Clock::time_point::max() : next_watch_;
}

void LineChannel::run_timers(Clock::time_point now) {
  if (connections_.empty() || now < next_watch_) return;
  watch_inputs();
  next_watch_ = Clock::now() + kInputWatchInterval;
}

void LineChannel::watch_inputs() {
  const std::uint32_t now = lines();
  if (inputs_known_) {
    const std::uint32_t changed = now ^ last_inputs_;
    const std::uint32_t order[4] = {TIOCM_CTS, TIOCM_DSR, TIOCM_RI, TIOCM_CD};
    for (int i = 0; i < 4; ++i) {
      if (changed & order[i]) ++changes_[i];
    }
  }
  last_inputs_ = now;
  inputs_known_ = true;
  for (Connection& connection : connections_) {
    if (!connection.waiting) continue;
    if (((now ^ connection.wait_from) & connection.wait_mask) == 0) continue;
    connection.waiting = false;
    answer(connection, reply_of(0));
  }
}

}  // namespace wiretape::detail::bridge
