// The pty endpoint: a pseudo-terminal that a program opens as if it were the
// device. One client at a time by nature; where the system can tell (Linux),
// its first open and last close are the client arriving and leaving, and its
// reads show that device data reached it. The terminal settings the client
// programs are mirrored onto the device. The terminal's node gets a serial
// device's mode and group, so that a client that drops root can open it.
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "bridge/endpoint.hpp"
#include "bridge/line_channel.hpp"
#include "posix/platform.hpp"
#include "posix/pty_terminal.hpp"
#include "posix/syscalls.hpp"
#include "replay/replay_port.hpp"
#include "session/record_kinds.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail::bridge {

namespace {

constexpr auto kSettingsPollInterval = std::chrono::milliseconds(50);

class PtyEndpoint final : public ClientEndpoint {
 public:
  PtyEndpoint(const BridgeOptions& options, DeviceSide& device, Status& status)
      : options_(options), device_(device), status_(status) {
    // Without its link: the link is the announcement that the terminal is
    // served, made last (below).
    pty_ = open_port("type=pty");
    pty_->set_timeout(std::chrono::nanoseconds(0));
    // The client's flushes show only in packet mode.
    set_packet_mode(*pty_);
    terminal_path_ = pty_terminal_path(*pty_);
    grant_access();
    // Best effort: without it, a pty client's coming and going goes unseen.
    opens_and_closes_ = sys::UniqueFd(platform::watch_opens_and_closes(terminal_path_));
    watching_reads_ = static_cast<bool>(opens_and_closes_);
    try {
      last_settings_ = pty_->serial_settings();
    } catch (const PortError&) {
    }
    next_settings_check_ = Clock::now() + kSettingsPollInterval;
    if (!options_.line_channel.empty()) {
      line_channel_ = std::make_unique<LineChannel>(
          options_.line_channel, device_, status_,
          [this] {
            if (options_.mirror_settings) check_settings();
          },
          // Bytes written before a hello: held here, or still in the terminal.
          [this] { return static_cast<std::uint64_t>(held_bytes_ + client_bytes_in_terminal()); });
    }
    // The announcements, last: a client may open the terminal the moment
    // its link appears (a script waiting for the path), and by now the
    // watch sees its open, packet mode its opening flush, and the terminal
    // has its mode (DESIGN.md section 12).
    if (!options_.pty_link.empty()) publish_terminal_link(*pty_, options_.pty_link);
    status_.set(&Status::pty_path, terminal_path_);
  }

  void add_to_poll(PollSet& poll_set) override {
    // A line change due before the next byte is applied before it is read.
    const bool change_due =
        line_channel_ && line_channel_->bytes_before_next_change(read_from_client_) == 0;
    pty_slot_ = poll_set.add(pty_->native_handle(),
                             device_.room_for_client_data() > 0 && !change_due, !to_pty_.empty());
    if (line_channel_) line_channel_->add_to_poll(poll_set);
    watch_slot_ = opens_and_closes_ ? poll_set.add(opens_and_closes_.get(), true, false)
                                    : PollSet::none;
  }

  void handle_events(const PollSet& poll_set) override {
    // A line change the shim made before bytes now in the terminal is in
    // the channel already: taken first, it holds those bytes back.
    if (line_channel_) line_channel_->handle_events(poll_set, relayed_);
    const bool pty_readable = poll_set.ready(pty_slot_).readable;
    if (!opens_and_closes_) {
      if (pty_readable) read_pty();
    } else if (pty_readable || unread_write_ || poll_set.ready(watch_slot_).any()) {
      // What the client wrote is read (until the terminal is empty, so that
      // what it holds at the client's close is newer than this look) and
      // held until the watch is read again: every open and close before
      // those bytes were written is in the watch by then (an open is
      // reported before it returns), so each byte goes to the client session
      // it was written in (DESIGN.md section 12: a close and a reopen at
      // once are two client sessions).
      holding_ = true;
      if (pty_readable || unread_write_) drain_pty();
      holding_ = false;
      watch_clients();  // passes on what it held
    }
    if (!to_pty_.empty()) write_pty();
  }

  Clock::time_point next_timer() const override {
    Clock::time_point next =
        polls_settings() ? next_settings_check_ : Clock::time_point::max();
    if (line_channel_) next = std::min(next, line_channel_->next_timer());
    return next;
  }

  void run_timers(Clock::time_point now) override {
    if (line_channel_) line_channel_->run_timers(now);
    if (polls_settings() && now >= next_settings_check_) {
      check_settings();
      next_settings_check_ = Clock::now() + kSettingsPollInterval;
    }
  }

  bool wants_device_data() const override { return !to_pty_.full(); }

  // Every path below writes `data` to the terminal or copies it into the
  // queue before anything (a read of the client's bytes) is recorded.
  bool delivers_without_recording() const override { return true; }

  void deliver_from_device(const char* data, std::size_t size) override {
    // Written from the caller's buffer while nothing waits before it: only
    // what the terminal does not take now is copied into the queue (the
    // profile of record --pty showed that copy as its one user-space
    // memmove, docs/benchmarks.md). A retaining virtual device goes through
    // write_pty(), which must see the client's flushes first.
    if (to_pty_.empty() && !retaining()) {
      const std::size_t n = pty_->write(data, size);
      if (n > 0) wrote_device_data_ = true;
      // A short write: the terminal is full, and the poll says when it
      // takes the rest.
      if (n < size) to_pty_.append(data + n, size - n);
      return;
    }
    to_pty_.append(data, size);
    write_pty();
  }

  void device_lost() override { dropped_input_logged_ = false; }

  void device_reopened() override {
    if (!options_.mirror_settings) return;
    // The client set its line before the device went away: carry it over.
    SerialSettings target = device_.current_settings();
    target.baud = last_settings_.baud;
    target.stop_bits = last_settings_.stop_bits;
    if (target != device_.current_settings()) {
      device_.apply_settings(target, "client's terminal settings");
    }
  }

  bool has_clients() const override { return openers_ > 0; }

  // Without a watch on the terminal its reads go unseen: data written to it
  // counts as taken, so that a replay is not failed for what cannot be known.
  bool served_device_data() const override {
    return opens_and_closes_ ? client_read_ : wrote_device_data_;
  }

  // The terminal closes last, after the device (see the destructor). A
  // client that read just before the end was served: its last reads may
  // still wait in the watch.
  void shut_down() override {
    if (!opens_and_closes_) return;
    for (const platform::TerminalEvent event :
         platform::read_opens_and_closes(opens_and_closes_.get())) {
      if (event == platform::TerminalEvent::read) client_read();
    }
  }

  ~PtyEndpoint() override {
    try {
      pty_->close();
    } catch (const std::exception&) {
    }
  }

 private:
  // Room for the client's bytes: the device's, less what is held.
  std::size_t room_for_client_data() const {
    const std::size_t room = device_.room_for_client_data();
    return room > held_bytes_ ? room - held_bytes_ : 0;
  }

  // The shim tells settings changes in their place among the bytes; without
  // it they are polled, and read before each read of the terminal.
  bool polls_settings() const {
    return options_.mirror_settings && !(line_channel_ && line_channel_->has_clients());
  }

  // Client bytes in the terminal, not yet read by the bridge.
  std::size_t client_bytes_in_terminal() const {
    int waiting = 0;
    if (sys::ioctl(pty_->native_handle(), FIONREAD, &waiting) != 0 || waiting < 0) return 0;
    return static_cast<std::size_t>(waiting);
  }

  void read_pty() {
    if (polls_settings()) check_settings();
    std::array<char, kChunk + 1> buffer;
    std::size_t room = std::min(room_for_client_data(), kChunk);
    if (line_channel_) {
      // Up to the next held line change: a read never spans one, so that the
      // change is applied once the read before it is passed on.
      const std::uint64_t before_change =
          line_channel_->bytes_before_next_change(read_from_client_);
      room = static_cast<std::size_t>(std::min<std::uint64_t>(room, before_change));
      if (room == 0) {
        last_read_took_data_ = false;
        line_channel_->apply_due(relayed_);
        return;
      }
    }
    // One more for packet mode's control byte.
    const std::size_t got = pty_->read(buffer.data(), room + 1, std::chrono::nanoseconds(0));
    last_read_took_data_ = got > 0;
    if (got == 0) {
      // The terminal is empty: every write so far was read.
      unread_write_ = false;
      found_empty_since_data_ = true;
      return;
    }
    if (buffer[0] != TIOCPKT_DATA) {
      take_from_client(static_cast<unsigned char>(buffer[0]), {});
      return;
    }
    const std::size_t n = got - 1;
    if (n == 0) return;
    read_data_since_wrote_event_ = true;
    found_empty_since_data_ = false;
    read_from_client_ += n;
    take_from_client(TIOCPKT_DATA, std::string_view(buffer.data() + 1, n));
  }

  // What a read of the terminal brought: a packet mode control byte (a
  // flush) or the client's bytes. Held while handle_events() holds them.
  void take_from_client(unsigned control, std::string_view data) {
    if (holding_) {
      held_.push_back({control, std::string(data)});
      held_bytes_ += data.size();
      return;
    }
    pass_on(control, data);
  }

  // The held reads, for the client session they belong to.
  void pass_on_held() {
    std::vector<HeldRead> held;
    held.swap(held_);
    held_bytes_ = 0;
    for (const HeldRead& read : held) pass_on(read.control, read.data);
  }

  void pass_on(unsigned control, std::string_view data) {
    if (control != TIOCPKT_DATA) {
      client_flushed(control);
      return;
    }
    relayed_ += data.size();
    if (!client_wrote_) {
      client_wrote_ = true;
      watch_reads_while_needed();
    }
    retained_.clear();
    if (!device_.is_open()) {
      if (!dropped_input_logged_) {
        status_.message("the device is away: input from the client is dropped until it is back");
        dropped_input_logged_ = true;
      }
      return;
    }
    device_.send(data.data(), data.size());
    if (line_channel_) line_channel_->apply_due(relayed_);
  }

  void write_pty() {
    // A flush the client made before these bytes must be seen before they
    // are written: seen after, it would look as if it had dropped them (the
    // terminal's count of unread bytes lags behind the writes to it), and
    // they would be delivered twice.
    if (retaining() && !to_pty_.empty()) read_pty();
    while (!to_pty_.empty()) {
      const std::size_t offered = to_pty_.size();
      const std::size_t n = pty_->write(to_pty_.data(), offered);
      if (n == 0) return;
      if (retaining()) retain(to_pty_.data(), n);
      to_pty_.consume(n);
      wrote_device_data_ = true;
      // The terminal is full: the poll says when it takes more, sparing a
      // write that would fail and a poll of its own each time.
      if (n < offered) return;
    }
  }

  // A virtual device keeps what it wrote to the terminal until its client
  // has written (and so is past its opening flushes), to deliver it again
  // should the client flush it unread (DESIGN.md section 12).
  bool retaining() const { return openers_ > 0 && !client_wrote_ && device_.is_virtual(); }

  void retain(const char* data, std::size_t size) {
    retained_.append(data, size);
    // Bounded like the queue to the terminal: a client that reads nothing
    // can be flushed its last bytes again, no more.
    if (retained_.size() > options_.buffer_limit) {
      retained_.erase(0, retained_.size() - options_.buffer_limit);
    }
  }

  // The client read: what it took is no longer retained.
  void client_read() {
    client_read_ = true;
    const std::size_t unread = terminal_unread(*pty_);
    if (unread < retained_.size()) retained_.erase(0, retained_.size() - unread);
    watch_reads_while_needed();
  }

  // The client's reads matter until it has read once (the replay's verdict,
  // served_device_data) and, on a virtual device, until it has written
  // (retaining). After that, each of its reads would only wake the bridge
  // for nothing, costing it a third of its CPU time on a busy terminal.
  void watch_reads_while_needed() {
    if (!opens_and_closes_) return;
    const bool needed = !client_read_ || retaining();
    if (needed == watching_reads_) return;
    if (platform::watch_reads(opens_and_closes_.get(), terminal_path_, needed)) {
      watching_reads_ = needed;
    }
  }

  // The client flushed its input or output (seen in packet mode). Recorded
  // as events, so that a replay can wait for the same flush (DESIGN.md
  // section 12).
  void client_flushed(unsigned control) {
    const bool input = (control & TIOCPKT_FLUSHREAD) != 0;
    const bool output = (control & TIOCPKT_FLUSHWRITE) != 0;
    if (!input && !output) return;
    if (input) device_.record(RecordKind::flush_input, "{}");
    if (output) device_.record(RecordKind::flush_output, "{}");
    if (!device_.is_virtual()) return;
    if (output) replay_client_flushed(device_.port());
    if (!input) return;
    if (client_wrote_) {
      // DESIGN.md section 7: a flush drops released rx the client has not
      // read (and the replay counts the flush).
      to_pty_.clear();
      device_.port().flush_input();
      return;
    }
    // Opening flushes (pyserial, gpsd) must not eat a greeting. What the
    // terminal still holds was written after the flush (the flush is seen
    // late): only the retained bytes before it were discarded. The client's
    // reads so far must be seen first: a flush seen late may have come
    // before a greeting the client has read since (its read is in the watch
    // already, put there before its read() returned, though the poll that
    // brought this packet may not have shown it). Not while a close is
    // handled: the flush is the leaving client's, and the watch may show the
    // next client's open by now, which must wait until the leaving client
    // has been disconnected from the replay.
    if (opens_and_closes_ && !passing_on_leaving_client_) watch_clients();
    const std::size_t kept = std::min(terminal_unread(*pty_), retained_.size());
    std::string again = retained_.substr(0, retained_.size() - kept);
    retained_.erase(0, retained_.size() - kept);
    again.append(to_pty_.data(), to_pty_.size());
    to_pty_.clear();
    to_pty_.append(again);
    write_pty();
    replay_client_flushed(device_.port());
  }

  // Everything the client wrote before it closed the terminal, so that its
  // last bytes are recorded before it leaves. A non-blocking read of the
  // master waits for the terminal's pending input to be pushed through
  // first, so what the client's write() returned for is all here.
  // (Bounded by the queue to the device: a device that takes nothing leaves
  // the rest for after the disconnect.)
  void drain_pty() {
    do {
      read_pty();
    } while (last_read_took_data_ && room_for_client_data() > 0);
  }

  void grant_access() {
    const mode_t mode = static_cast<mode_t>(options_.pty_mode);
    if (!options_.pty_group.empty()) {
      // Checked by the Bridge's constructor; a group removed since is a
      // runtime error like any refusal.
      const std::optional<gid_t> group = find_group(options_.pty_group);
      if (!group) {
        throw PortError(ENOENT, "pty: there is no group " + options_.pty_group);
      }
      set_terminal_access(*pty_, mode, *group);
      return;
    }
    const std::optional<gid_t> serial_group = find_group(kSerialDeviceGroup);
    if (serial_group) {
      try {
        set_terminal_access(*pty_, mode, *serial_group);
        return;
      } catch (const PortError& refused) {
        // A user outside that group may not give it the terminal.
        status_.message(std::string("the terminal keeps this process's group: ") +
                        refused.what());
      }
    }
    set_terminal_access(*pty_, mode, sys::getegid());
  }

  // Whether the client's last close (at `closed` in `events`) was followed
  // by an open already: reads from the watch until now, so that the answer is
  // as late as can be.
  bool reopened_after(std::vector<platform::TerminalEvent>& events, std::size_t closed) {
    for (const platform::TerminalEvent event :
         platform::read_opens_and_closes(opens_and_closes_.get())) {
      events.push_back(event);
    }
    return std::find(events.begin() + static_cast<std::ptrdiff_t>(closed) + 1, events.end(),
                     platform::TerminalEvent::opened) != events.end();
  }

  // The first opener of the terminal is a client arriving, the last close
  // its leaving (a program may open the terminal more than once, and tools
  // such as stty open and close it too). A close and a reopen at once
  // (pyserial's close() then Serial(), to change the baud rate) are two
  // client sessions: every byte written after the reopen belongs to the
  // second (DESIGN.md section 12).
  void watch_clients() {
    std::vector<platform::TerminalEvent> events =
        platform::read_opens_and_closes(opens_and_closes_.get());
    for (std::size_t i = 0; i < events.size(); ++i) {
      const platform::TerminalEvent event = events[i];
      if (event == platform::TerminalEvent::read) {
        client_read();
        continue;
      }
      if (event == platform::TerminalEvent::wrote) {
        // A write is reported after it returned, so its bytes may have been
        // read (and the terminal found empty) before the report: then the
        // report is stale. Else its bytes wait in the terminal still.
        const bool stale = read_data_since_wrote_event_ && found_empty_since_data_;
        if (openers_ > 0 && !stale) unread_write_ = true;
        read_data_since_wrote_event_ = false;
        continue;
      }
      if (event == platform::TerminalEvent::opened) {
        if (openers_++ > 0) continue;
        if (options_.restart && had_client_ && device_.is_open()) {
          pty_->flush_output();  // what the previous client left unread
          to_pty_.clear();
          device_.restart();
        }
        had_client_ = true;
        client_wrote_ = false;
        retained_.clear();
        watch_reads_while_needed();
        if (device_.client_connected("pty", "control")) {
          // A replay's new client session: what waits in the terminal was
          // meant for nobody, or for the previous client.
          pty_->flush_output();
          to_pty_.clear();
        }
        status_.message("client connected to " + pty_->description());
      } else if (openers_ > 0 && --openers_ == 0) {
        // What the terminal holds is the leaving client's when the watch
        // saw it write since the terminal was last found empty, or when
        // nobody opened the terminal since; else it was written after a
        // reopen, for the next session. (Both wrote before the bridge
        // looked: the bytes cannot be told apart, and go to the first.)
        // The terminal is read first, then the watch: a reopen the watch
        // does not show yet came after every byte read. Held bytes were
        // read before this look too.
        const bool leaving_client_wrote = unread_write_;
        const bool was_holding = holding_;
        holding_ = true;
        drain_pty();
        holding_ = was_holding;
        if (leaving_client_wrote || !reopened_after(events, i)) {
          passing_on_leaving_client_ = true;
          pass_on_held();
          passing_on_leaving_client_ = false;
        }
        device_.client_disconnected("pty", "closed the terminal");
        status_.message("client closed " + pty_->description());
      }
    }
    // Bytes kept for the session after a close belong to it now.
    if (!holding_) pass_on_held();
  }

  void check_settings() {
    SerialSettings seen;
    try {
      seen = pty_->serial_settings();
    } catch (const PortError&) {
      return;
    }
    if (seen == last_settings_) return;
    const SerialSettings before = last_settings_;
    last_settings_ = seen;
    if (!device_.is_open()) return;
    // Only what the client changed is carried over: a pty cannot show data
    // bits or parity (Linux forces 8N), so the device keeps its own there.
    SerialSettings target = device_.current_settings();
    if (seen.baud != before.baud) target.baud = seen.baud;
    if (seen.data_bits != before.data_bits) target.data_bits = seen.data_bits;
    if (seen.stop_bits != before.stop_bits) target.stop_bits = seen.stop_bits;
    if (seen.parity != before.parity) target.parity = seen.parity;
    if (seen.flow != before.flow) target.flow = seen.flow;
    device_.apply_settings(target, "client's terminal settings");
  }

  const BridgeOptions& options_;
  DeviceSide& device_;
  Status& status_;
  std::unique_ptr<Port> pty_;
  // Opens and closes of the terminal by any process (invalid where the
  // system cannot tell).
  sys::UniqueFd opens_and_closes_;
  std::string terminal_path_;
  bool watching_reads_ = false;  // the watch reports the client's reads
  int openers_ = 0;
  bool had_client_ = false;
  bool dropped_input_logged_ = false;
  bool last_read_took_data_ = false;
  bool wrote_device_data_ = false;
  bool client_read_ = false;
  // The current client has written to the terminal.
  bool client_wrote_ = false;
  // Reads of the terminal held by handle_events() (see there).
  struct HeldRead {
    unsigned control = TIOCPKT_DATA;
    std::string data;
  };
  bool holding_ = false;
  // The held reads are the leaving client's, passed on before its close.
  bool passing_on_leaving_client_ = false;
  std::vector<HeldRead> held_;
  std::size_t held_bytes_ = 0;
  // The watch saw the client write since a read found the terminal empty.
  bool unread_write_ = false;
  // Bytes were read since the watch last reported a write, and a read found
  // the terminal empty after them: the next report may be of those bytes.
  bool read_data_since_wrote_event_ = false;
  bool found_empty_since_data_ = true;
  // See retaining().
  std::string retained_;
  ByteQueue to_pty_{options_.buffer_limit};
  // Client bytes read from the terminal, and passed on to the device (or
  // dropped while it was away): the line channel holds a client's line
  // change until the bytes it wrote before it are passed on, and no read
  // spans one.
  std::uint64_t read_from_client_ = 0;
  std::uint64_t relayed_ = 0;
  std::unique_ptr<LineChannel> line_channel_;
  SerialSettings last_settings_;
  Clock::time_point next_settings_check_;
  PollSet::Slot pty_slot_ = PollSet::none;
  PollSet::Slot watch_slot_ = PollSet::none;
};

}  // namespace

std::unique_ptr<ClientEndpoint> make_pty_endpoint(const BridgeOptions& options,
                                                  DeviceSide& device, Status& status) {
  return std::make_unique<PtyEndpoint>(options, device, status);
}

}  // namespace wiretape::detail::bridge
