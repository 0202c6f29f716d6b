// The bridge engine: one thread, one poll() over the device's native handle,
// the client side (pty master or TCP listener and its clients) and a wake
// pipe for stop(). Data moves in large chunks through bounded queues; the
// only per-byte work is RFC 2217's IAC escaping when that protocol is on.
#include "wiretape/bridge.hpp"

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <deque>
#include <mutex>
#include <thread>
#include <utility>

#include "util/json.hpp"
#include "posix/platform.hpp"
#include "posix/syscalls.hpp"
#include "bridge/rfc2217.hpp"
#include "session/record_kinds.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

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

using Clock = std::chrono::steady_clock;
using detail::sys::UniqueFd;
namespace json = detail::json;
namespace event_field = detail::event_field;
namespace rfc = detail::rfc2217;

constexpr std::size_t kChunk = 64 * 1024;
// A read of a terminal hands out about one line-discipline buffer (Linux: 4 KiB
// less one byte) at a time; a read at least this large means more is waiting.
constexpr std::size_t kLineDisciplineBuffer = 4095;
constexpr auto kSettingsPollInterval = std::chrono::milliseconds(50);
constexpr auto kWriteRetryInterval = std::chrono::milliseconds(2);
constexpr auto kModemPollInterval = std::chrono::milliseconds(250);
constexpr std::size_t kMaxMessages = 1000;


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

// Bytes waiting to be written, consumed from the front without moving the
// rest on every write.
class ByteQueue {
 public:
  std::size_t size() const { return data_.size() - start_; }
  bool empty() const { return size() == 0; }
  const char* data() const { return data_.data() + start_; }
  void append(const char* bytes, std::size_t n) { data_.append(bytes, n); }
  void append(const std::string& bytes) { data_.append(bytes); }
  void consume(std::size_t n) {
    start_ += n;
    if (start_ == data_.size()) {
      data_.clear();
      start_ = 0;
    } else if (start_ > kChunk && start_ * 2 > data_.size()) {
      data_.erase(0, start_);
      start_ = 0;
    }
  }
  void clear() {
    data_.clear();
    start_ = 0;
  }

 private:
  std::string data_;
  std::size_t start_ = 0;
};

std::string address_of(const sockaddr* address, socklen_t length) {
  char host[NI_MAXHOST] = "";
  char service[NI_MAXSERV] = "";
  if (::getnameinfo(address, length, host, sizeof host, service, sizeof service,
                    NI_NUMERICHOST | NI_NUMERICSERV) != 0) {
    return "?";
  }
  if (address->sa_family == AF_INET6) {
    return std::string("[") + host + "]:" + service;
  }
  return std::string(host) + ":" + service;
}

[[noreturn]] void raise_errno(const std::string& what) {
  const int error = errno;
  throw PortError(error, what + ": " + std::strerror(error));
}

}  // namespace

struct Bridge::Impl {
  struct Client;
  class ComPortAdapter;

  explicit Impl(BridgeOptions options) : options_(std::move(options)) {}

  // --- configuration ---------------------------------------------------------
  BridgeOptions options_;

  // --- status shared with other threads ---------------------------------------
  mutable std::mutex status_mutex_;
  std::condition_variable finished_cv_;
  bool started_ = false;
  bool finished_ = false;
  BridgeResult result_;
  std::deque<std::string> messages_;
  std::string pty_path_;
  std::string listen_address_;
  std::string device_description_;
  std::atomic<bool> stop_requested_{false};
  UniqueFd wake_read_;
  UniqueFd wake_write_;
  std::thread thread_;

  // --- owned by the forwarding thread once started -----------------------------
  std::unique_ptr<Port> device_;
  std::unique_ptr<Port> pty_;
  // Opens and closes of the pty's terminal by any process: how a pty client
  // is seen to arrive and leave (invalid where the system cannot tell).
  UniqueFd pty_watch_;
  int pty_openers_ = 0;
  UniqueFd listener_;
  std::vector<std::unique_ptr<Client>> clients_;
  std::unique_ptr<SessionWriter> writer_;
  Clock::time_point t0_;
  ByteQueue to_device_;
  ByteQueue to_pty_;
  SerialSettings last_pty_settings_;
  Clock::time_point next_settings_check_;
  Clock::time_point next_reopen_;
  Clock::time_point next_modem_poll_;
  std::optional<std::uint8_t> last_modem_state_;
  bool reopen_failure_logged_ = false;
  bool had_client_ = false;
  bool dropped_input_logged_ = false;
  // Line state for devices that have none (tcp, replay): what clients set.
  SerialSettings virtual_settings_;
  bool dtr_ = true;
  bool rts_ = true;
  std::optional<Clock::time_point> break_since_;
  std::optional<Clock::time_point> end_at_;
  std::mutex join_mutex_;
  BridgeOutcome end_outcome_ = BridgeOutcome::running;
  std::string end_message_;

  // --- helpers -----------------------------------------------------------------
  void message(const std::string& text) {
    if (!options_.quiet) std::fprintf(stderr, "wiretape: %s\n", text.c_str());
    std::lock_guard<std::mutex> lock(status_mutex_);
    messages_.push_back(text);
    if (messages_.size() > kMaxMessages) messages_.pop_front();
  }

  template <typename Update>
  void update_stats(Update update) {
    std::lock_guard<std::mutex> lock(status_mutex_);
    update(result_.stats);
  }

  std::uint64_t now_ns() const {
    return static_cast<std::uint64_t>(
        std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - t0_).count());
  }

  void record(RecordKind kind, std::string_view data) { record_at(kind, now_ns(), data); }
  void record_at(RecordKind kind, std::uint64_t t_ns, std::string_view data) {
    if (!writer_) return;
    writer_->write(kind, t_ns, data);
    update_stats([](BridgeStats& s) { ++s.records_written; });
  }

  void end(BridgeOutcome outcome, std::string text) {
    if (end_outcome_ != BridgeOutcome::running) return;
    end_outcome_ = outcome;
    end_message_ = std::move(text);
  }
  bool ending() const { return end_outcome_ != BridgeOutcome::running; }

  // --- start ---------------------------------------------------------------------
  void open_all();
  void open_listener();
  void open_device(bool first, const char* why);
  void run();
  void loop();
  void shutdown();

  // --- forwarding ------------------------------------------------------------------
  Client* controller();
  bool device_sink_has_room();
  void read_device(short revents);
  void deliver_from_device(const char* data, std::size_t n);
  void read_pty();
  void write_pty();
  void watch_pty_clients();
  void client_connected(const std::string& peer, const char* role);
  void client_disconnected(const std::string& peer, const std::string& reason);
  void accept_client();
  void read_client(Client& client);
  void write_client(Client& client);
  void drop_client(Client& client, const std::string& reason);
  void flush_to_device();
  void device_lost(const std::string& reason);
  void try_reopen();
  void restart_device();

  // --- line settings -----------------------------------------------------------------
  void check_pty_settings();
  void poll_modem_lines();
  SerialSettings current_settings();
  // Applies `target` to the device (or to the virtual line), records it;
  // false if the device refused.
  bool apply_settings(const SerialSettings& target, const char* source);
  void record_modem_line(const char* line, bool level, bool applied);
};

struct Bridge::Impl::Client {
  UniqueFd fd;
  std::string peer;
  bool monitor = false;
  ByteQueue outgoing;
  std::unique_ptr<ComPortAdapter> com_port;
  std::unique_ptr<rfc::ServerSession> telnet;
  bool gone = false;
};

// What an RFC 2217 client may do to the device. Monitors see the line's
// state but cannot change it.
class Bridge::Impl::ComPortAdapter final : public rfc::ComPort {
 public:
  ComPortAdapter(Impl& bridge, bool control) : bridge_(bridge), control_(control) {}

  std::uint32_t set_baud(std::uint32_t baud) override {
    if (baud != 0 && control_ && bridge_.device_) {
      SerialSettings target = bridge_.current_settings();
      target.baud = baud;
      bridge_.apply_settings(target, "rfc2217");
    }
    return bridge_.current_settings().baud;
  }
  std::uint8_t set_data_size(std::uint8_t bits) override {
    if (bits >= 5 && bits <= 8 && control_ && bridge_.device_) {
      SerialSettings target = bridge_.current_settings();
      target.data_bits = bits;
      bridge_.apply_settings(target, "rfc2217");
    }
    return static_cast<std::uint8_t>(bridge_.current_settings().data_bits);
  }
  std::uint8_t set_parity(std::uint8_t code) override {
    static constexpr Parity by_code[] = {Parity::none, Parity::none, Parity::odd,
                                         Parity::even, Parity::mark, Parity::space};
    if (code >= 1 && code <= 5 && control_ && bridge_.device_) {
      SerialSettings target = bridge_.current_settings();
      target.parity = by_code[code];
      bridge_.apply_settings(target, "rfc2217");
    }
    switch (bridge_.current_settings().parity) {
      case Parity::none: return 1;
      case Parity::odd: return 2;
      case Parity::even: return 3;
      case Parity::mark: return 4;
      case Parity::space: return 5;
    }
    return 1;
  }
  std::uint8_t set_stop_size(std::uint8_t code) override {
    // Code 3 (1.5 stop bits) has no termios equivalent: refused.
    if ((code == 1 || code == 2) && control_ && bridge_.device_) {
      SerialSettings target = bridge_.current_settings();
      target.stop_bits = code;
      bridge_.apply_settings(target, "rfc2217");
    }
    return static_cast<std::uint8_t>(bridge_.current_settings().stop_bits);
  }
  std::uint8_t set_control(std::uint8_t value) override {
    Impl& b = bridge_;
    const bool act = control_ && b.device_;
    switch (value) {
      case 0:  // flow control, asked
        break;
      case 1: case 2: case 3:
        if (act) {
          SerialSettings target = b.current_settings();
          target.flow = value == 1 ? FlowControl::none
                                   : value == 2 ? FlowControl::xonxoff : FlowControl::rtscts;
          b.apply_settings(target, "rfc2217");
        }
        break;
      case 4: return b.break_since_ ? 5 : 6;
      case 5:
        if (act && !b.break_since_) b.break_since_ = Clock::now();
        return b.break_since_ ? 5 : 6;
      case 6:
        if (act && b.break_since_) {
          // The Port sends a break of a given length: the time it was on.
          auto on = std::chrono::duration_cast<std::chrono::milliseconds>(
              Clock::now() - *b.break_since_);
          on = std::clamp(on, std::chrono::milliseconds(1), std::chrono::milliseconds(2000));
          b.break_since_.reset();
          bool applied = true;
          try {
            b.device_->send_break(on);
          } catch (const PortClosed&) {
            throw;
          } catch (const PortError&) {
            applied = false;
          }
          b.record(RecordKind::line_break, json::ObjectWriter()
                                               .add(event_field::duration_ms, static_cast<std::int64_t>(on.count()))
                                               .add(event_field::applied, applied)
                                               .str());
        }
        return 6;
      case 7: return b.dtr_ ? 8 : 9;
      case 8: case 9:
        if (act) set_line(event_field::dtr, value == 8);
        return b.dtr_ ? 8 : 9;
      case 10: return b.rts_ ? 11 : 12;
      case 11: case 12:
        if (act) set_line(event_field::rts, value == 11);
        return b.rts_ ? 11 : 12;
      case 13: return 14;  // inbound flow control: follows the outbound one
      default: return value;
    }
    switch (b.current_settings().flow) {
      case FlowControl::none: return 1;
      case FlowControl::xonxoff: return 2;
      case FlowControl::rtscts: return 3;
    }
    return 1;
  }
  void purge(std::uint8_t which) override {
    if (!control_ || !bridge_.device_) return;
    if (which & 1) {
      // What is already queued for the client stays: Telnet answers share
      // that queue, and the client drops its own buffer anyway.
      bridge_.device_->flush_input();
      bridge_.record(RecordKind::flush_input, "{}");
    }
    if (which & 2) {
      bridge_.device_->flush_output();
      bridge_.to_device_.clear();
      bridge_.record(RecordKind::flush_output, "{}");
    }
  }
  std::uint8_t modem_state() override {
    if (!bridge_.device_) return 0;
    try {
      Port& d = *bridge_.device_;
      return static_cast<std::uint8_t>((d.cd() ? 0x80 : 0) | (d.ri() ? 0x40 : 0) |
                                       (d.dsr() ? 0x20 : 0) | (d.cts() ? 0x10 : 0));
    } catch (const PortClosed&) {
      throw;
    } catch (const PortError&) {
      return 0;  // no modem lines (tcp, pty, replay)
    }
  }
  std::uint8_t line_state() override { return 0; }

 private:
  void set_line(const char* line, bool level) {
    Impl& b = bridge_;
    bool applied = true;
    try {
      if (line[0] == 'd') b.device_->set_dtr(level);
      else b.device_->set_rts(level);
    } catch (const PortClosed&) {
      throw;
    } catch (const PortError&) {
      applied = false;  // a device without modem lines: acknowledged, noted
    }
    (line[0] == 'd' ? b.dtr_ : b.rts_) = level;
    b.record_modem_line(line, level, applied);
  }

  Impl& bridge_;
  bool control_;
};

// --- opening -------------------------------------------------------------------------

void Bridge::Impl::open_device(bool first, const char* why) {
  device_ = open_port(options_.device);
  // Never block the loop: writes take what the device accepts now.
  device_->set_timeout(std::chrono::nanoseconds(0));
  last_modem_state_.reset();
  if (first) t0_ = Clock::now();
  const std::string description = device_->description();
  {
    std::lock_guard<std::mutex> lock(status_mutex_);
    device_description_ = description;
  }
  try {
    virtual_settings_ = device_->serial_settings();
  } catch (const PortError&) {
  }
  json::ObjectWriter event;
  event.add(event_field::description, description);
  if (why) event.add(why, true);
  // Time zero is the device's first open.
  record_at(RecordKind::open, first ? 0 : now_ns(), event.str());
}

void Bridge::Impl::open_listener() {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
  addrinfo* found = nullptr;
  const std::string port_text = std::to_string(options_.listen_port);
  const std::string where = "listen " + options_.listen_host + ":" + port_text;
  const int status = ::getaddrinfo(
      options_.listen_host.empty() ? nullptr : options_.listen_host.c_str(),
      port_text.c_str(), &hints, &found);
  if (status != 0) {
    throw PortError(EINVAL, where + ": cannot resolve the host: " + ::gai_strerror(status));
  }
  std::unique_ptr<addrinfo, void (*)(addrinfo*)> list(found, ::freeaddrinfo);
  UniqueFd fd(::socket(found->ai_family, found->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC,
                       found->ai_protocol));
  if (!fd) raise_errno(where + ": socket");
  const int on = 1;
  ::setsockopt(fd.get(), SOL_SOCKET, SO_REUSEADDR, &on, sizeof on);
  if (::bind(fd.get(), found->ai_addr, found->ai_addrlen) != 0) raise_errno(where + ": bind");
  if (::listen(fd.get(), 8) != 0) raise_errno(where + ": listen");
  sockaddr_storage bound{};
  socklen_t length = sizeof bound;
  ::getsockname(fd.get(), reinterpret_cast<sockaddr*>(&bound), &length);
  {
    std::lock_guard<std::mutex> lock(status_mutex_);
    listen_address_ = address_of(reinterpret_cast<sockaddr*>(&bound), length);
  }
  listener_ = std::move(fd);
  const std::string host = options_.listen_host;
  if (host == "127.0.0.1" || host == "::1" || host == "localhost") {
    message("listening on " + listen_address_ +
            " (this machine only; give HOST:PORT, e.g. 0.0.0.0:" +
            listen_address_.substr(listen_address_.rfind(':') + 1) +
            ", to accept other machines)");
  } else {
    message("listening on " + listen_address_);
  }
}

void Bridge::Impl::open_all() {
  if (options_.client_side == BridgeClientSide::tcp) open_listener();
  open_device(true, nullptr);
  if (!options_.output.empty()) {
    SessionWriterOptions writer_options;
    writer_options.capture = Capture::wire;
    writer_options.port_options = options_.device;
    writer_options.port_type = device_->type();
    writer_options.metadata = options_.metadata;
    writer_options.flush_ms = options_.flush_ms;
    writer_ = std::make_unique<SessionWriter>(options_.output, std::move(writer_options));
    // Time zero is the device's open, which came just before the file.
    record_at(RecordKind::open, 0,
              json::ObjectWriter().add(event_field::description, device_->description()).str());
  }
  if (options_.client_side == BridgeClientSide::pty) {
    std::string pty_options = "type=pty";
    if (!options_.pty_link.empty()) {
      std::string quoted;
      for (char c : options_.pty_link) {
        if (c == '"' || c == '\\') quoted.push_back('\\');
        quoted.push_back(c);
      }
      pty_options += ",link=\"" + quoted + "\"";
    }
    pty_ = open_port(pty_options);
    pty_->set_timeout(std::chrono::nanoseconds(0));
    const std::string description = pty_->description();
    // "pty /dev/pts/7 (link ...)": the terminal's path is the second word.
    const auto space = description.find(' ');
    const auto end = description.find(' ', space + 1);
    const std::string path =
        description.substr(space + 1, end == std::string::npos ? end : end - space - 1);
    // Best effort: without it, a pty client's coming and going goes unseen.
    pty_watch_ = UniqueFd(detail::platform::watch_opens_and_closes(path));
    std::lock_guard<std::mutex> lock(status_mutex_);
    pty_path_ = path;
  }
  if (pty_) {
    try {
      last_pty_settings_ = pty_->serial_settings();
    } catch (const PortError&) {
    }
  }
  if (options_.duration) end_at_ = Clock::now() + *options_.duration;
}

// --- the loop ---------------------------------------------------------------------------

Bridge::Impl::Client* Bridge::Impl::controller() {
  for (auto& client : clients_) {
    if (!client->monitor && !client->gone) return client.get();
  }
  return nullptr;
}

bool Bridge::Impl::device_sink_has_room() {
  if (pty_) return to_pty_.size() < options_.buffer_limit;
  Client* control = controller();
  if (!control) return false;  // the device waits for a client
  if (control->telnet && control->telnet->suspended()) return false;
  return control->outgoing.size() < options_.buffer_limit;
}

void Bridge::Impl::run() {
  try {
    loop();
  } catch (const ReplayMismatch& mismatch) {
    end(BridgeOutcome::mismatch, mismatch.what());
  } catch (const std::exception& error) {
    end(BridgeOutcome::failed, error.what());
  }
  shutdown();
}

void Bridge::Impl::loop() {
  std::vector<pollfd> fds;
  std::vector<Client*> polled_clients;
  const bool device_polls_output_ready = [&] {
    const std::string type = device_->type();
    return type == "serial" || type == "tcp" || type == "pty" || type == "udp";
  }();
  next_settings_check_ = Clock::now() + kSettingsPollInterval;

  while (!ending()) {
    if (stop_requested_.load()) {
      end(BridgeOutcome::stopped, "stopped");
      break;
    }
    auto now = Clock::now();
    if (end_at_ && now >= *end_at_) {
      end(BridgeOutcome::finished, "the duration elapsed");
      break;
    }
    if (!device_ && options_.reopen && now >= next_reopen_) try_reopen();

    flush_to_device();
    if (ending()) break;

    fds.clear();
    polled_clients.clear();
    fds.push_back({wake_read_.get(), POLLIN, 0});
    int device_index = -1;
    if (device_) {
      short events = 0;
      if (device_sink_has_room()) events |= POLLIN;
      if (!to_device_.empty() && device_polls_output_ready) events |= POLLOUT;
      if (events) {
        device_index = static_cast<int>(fds.size());
        fds.push_back({device_->native_handle(), events, 0});
      }
    }
    int pty_index = -1;
    if (pty_) {
      short events = 0;
      if (to_device_.size() < options_.buffer_limit) events |= POLLIN;
      if (!to_pty_.empty()) events |= POLLOUT;
      pty_index = static_cast<int>(fds.size());
      fds.push_back({pty_->native_handle(), events, 0});
    }
    int pty_watch_index = -1;
    if (pty_watch_) {
      pty_watch_index = static_cast<int>(fds.size());
      fds.push_back({pty_watch_.get(), POLLIN, 0});
    }
    int listener_index = -1;
    if (listener_) {
      listener_index = static_cast<int>(fds.size());
      fds.push_back({listener_.get(), POLLIN, 0});
    }
    const std::size_t first_client = fds.size();
    for (auto& client : clients_) {
      short events = 0;
      if (client->monitor || to_device_.size() < options_.buffer_limit) events |= POLLIN;
      if (!client->outgoing.empty()) events |= POLLOUT;
      fds.push_back({client->fd.get(), events, 0});
      polled_clients.push_back(client.get());
    }

    // How long to sleep: until the next timer.
    auto wake_at = Clock::time_point::max();
    if (end_at_) wake_at = std::min(wake_at, *end_at_);
    if (pty_ && options_.mirror_settings) wake_at = std::min(wake_at, next_settings_check_);
    if (!device_ && options_.reopen) wake_at = std::min(wake_at, next_reopen_);
    const bool watch_modem = options_.protocol == BridgeProtocol::rfc2217 && device_ &&
                             !clients_.empty() && last_modem_state_ != std::uint8_t{0xff};
    if (watch_modem) wake_at = std::min(wake_at, next_modem_poll_);
    if (device_ && !to_device_.empty() && !device_polls_output_ready) {
      wake_at = std::min(wake_at, now + kWriteRetryInterval);
    }
    int timeout_ms = -1;
    if (wake_at != Clock::time_point::max()) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          wake_at - Clock::now() + std::chrono::microseconds(999));
      timeout_ms = static_cast<int>(std::max<std::int64_t>(0, std::min<std::int64_t>(left.count(), 60'000)));
    }
    const int ready = ::poll(fds.data(), fds.size(), timeout_ms);
    if (ready < 0) {
      if (errno == EINTR) continue;
      raise_errno("bridge: poll");
    }
    if (fds[0].revents & POLLIN) {
      char drain[64];
      while (::read(wake_read_.get(), drain, sizeof drain) > 0) {
      }
    }
    if (device_index >= 0 && fds[static_cast<std::size_t>(device_index)].revents) {
      read_device(fds[static_cast<std::size_t>(device_index)].revents);
    }
    if (pty_watch_index >= 0 && fds[static_cast<std::size_t>(pty_watch_index)].revents) {
      watch_pty_clients();
    }
    if (pty_index >= 0) {
      const short revents = fds[static_cast<std::size_t>(pty_index)].revents;
      if (revents & POLLIN) read_pty();
      if (!to_pty_.empty()) write_pty();
    }
    for (std::size_t i = 0; i < polled_clients.size(); ++i) {
      Client& client = *polled_clients[i];
      const short revents = fds[first_client + i].revents;
      if (client.gone) continue;
      if (revents & (POLLIN | POLLHUP | POLLERR)) read_client(client);
      if (!client.gone && !client.outgoing.empty()) write_client(client);
    }
    clients_.erase(std::remove_if(clients_.begin(), clients_.end(),
                                  [](const std::unique_ptr<Client>& c) { return c->gone; }),
                   clients_.end());
    if (listener_index >= 0 && (fds[static_cast<std::size_t>(listener_index)].revents & POLLIN)) {
      accept_client();
    }
    if (watch_modem && Clock::now() >= next_modem_poll_) {
      poll_modem_lines();
      next_modem_poll_ = Clock::now() + kModemPollInterval;
    }
    if (pty_ && options_.mirror_settings && Clock::now() >= next_settings_check_) {
      check_pty_settings();
      next_settings_check_ = Clock::now() + kSettingsPollInterval;
    }
  }
}

void Bridge::Impl::read_device(short revents) {
  std::array<char, kChunk> buffer;
  std::size_t filled = 0;
  try {
    if (revents & POLLIN || revents & (POLLHUP | POLLERR)) {
      // A read that took a whole line-discipline buffer means the device is
      // ahead of us: read on and pass the lot to the clients at once, one
      // send instead of one per read.
      for (;;) {
        const std::size_t n = device_->read(buffer.data() + filled, buffer.size() - filled,
                                            std::chrono::nanoseconds(0));
        if (n > 0) record(RecordKind::rx, std::string_view(buffer.data() + filled, n));
        filled += n;
        if (n < kLineDisciplineBuffer || buffer.size() - filled < kLineDisciplineBuffer) break;
      }
    }
  } catch (const PortClosed& closed) {
    if (filled > 0) {
      update_stats([filled](BridgeStats& s) { s.bytes_from_device += filled; });
      deliver_from_device(buffer.data(), filled);
    }
    device_lost(closed.what());
    return;
  }
  if (filled == 0) {
    if (revents & (POLLHUP | POLLERR)) device_lost("the device hung up");
    return;
  }
  update_stats([filled](BridgeStats& s) { s.bytes_from_device += filled; });
  deliver_from_device(buffer.data(), filled);
}

void Bridge::Impl::deliver_from_device(const char* data, std::size_t n) {
  if (pty_) {
    to_pty_.append(data, n);
    write_pty();
    return;
  }
  std::string escaped;
  for (auto& client : clients_) {
    if (client->gone) continue;
    const char* bytes = data;
    std::size_t size = n;
    if (client->telnet) {
      if (escaped.empty()) rfc::ServerSession::escape(data, n, escaped);
      bytes = escaped.data();
      size = escaped.size();
    }
    if (client->monitor && client->outgoing.size() + size > options_.buffer_limit) {
      update_stats([n](BridgeStats& s) { s.bytes_dropped += n; });
      continue;
    }
    client->outgoing.append(bytes, size);
    write_client(*client);
  }
}

void Bridge::Impl::read_pty() {
  if (options_.mirror_settings) check_pty_settings();
  std::array<char, kChunk> buffer;
  const std::size_t room = options_.buffer_limit - std::min(options_.buffer_limit, to_device_.size());
  const std::size_t n = pty_->read(buffer.data(), std::min(room, buffer.size()),
                                   std::chrono::nanoseconds(0));
  if (n == 0) return;
  if (!device_) {
    if (!dropped_input_logged_) {
      message("the device is away: input from the client is dropped until it is back");
      dropped_input_logged_ = true;
    }
    return;
  }
  record(RecordKind::tx, std::string_view(buffer.data(), n));
  to_device_.append(buffer.data(), n);
  flush_to_device();
}

// The first opener of the terminal is a client arriving, the last close
// its leaving (a program may open the terminal more than once, and tools
// such as stty open and close it too).
void Bridge::Impl::watch_pty_clients() {
  for (const bool opened : detail::platform::read_opens_and_closes(pty_watch_.get())) {
    if (opened) {
      if (pty_openers_++ > 0) continue;
      if (options_.restart && had_client_ && device_) {
        pty_->flush_output();  // what the previous client left unread
        to_pty_.clear();
        restart_device();
      }
      had_client_ = true;
      client_connected("pty", "control");
      message("client connected to " + pty_->description());
    } else if (pty_openers_ > 0 && --pty_openers_ == 0) {
      client_disconnected("pty", "closed the terminal");
      message("client closed " + pty_->description());
    }
  }
}

void Bridge::Impl::client_connected(const std::string& peer, const char* role) {
  record(RecordKind::client_connect, json::ObjectWriter().add(event_field::peer, peer).add(event_field::role, role).str());
  update_stats([](BridgeStats& s) { ++s.clients_accepted; });
}

void Bridge::Impl::client_disconnected(const std::string& peer, const std::string& reason) {
  record(RecordKind::client_disconnect,
         json::ObjectWriter().add(event_field::peer, peer).add(event_field::reason, reason).str());
}

void Bridge::Impl::write_pty() {
  while (!to_pty_.empty()) {
    const std::size_t n = pty_->write(to_pty_.data(), to_pty_.size());
    if (n == 0) return;
    to_pty_.consume(n);
  }
}

void Bridge::Impl::flush_to_device() {
  while (device_ && !to_device_.empty()) {
    std::size_t n = 0;
    try {
      n = device_->write(to_device_.data(), to_device_.size());
    } catch (const PortClosed& closed) {
      device_lost(closed.what());
      return;
    }
    if (n == 0) return;
    to_device_.consume(n);
    update_stats([n](BridgeStats& s) { s.bytes_to_device += n; });
  }
}

void Bridge::Impl::accept_client() {
  for (;;) {
    sockaddr_storage peer_address{};
    socklen_t length = sizeof peer_address;
    UniqueFd fd(::accept4(listener_.get(), reinterpret_cast<sockaddr*>(&peer_address), &length,
                          SOCK_NONBLOCK | SOCK_CLOEXEC));
    if (!fd) {
      if (errno == EINTR || errno == ECONNABORTED) continue;
      return;  // EAGAIN: no more waiting; anything else is retried next time
    }
    const std::string peer = address_of(reinterpret_cast<sockaddr*>(&peer_address), length);
    const auto refuse = [&](const std::string& why) {
      const std::string text = "wiretape: " + why + "\r\n";
      // A short text fits in a fresh socket's buffer: no need to wait.
      (void)::send(fd.get(), text.data(), text.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
      update_stats([](BridgeStats& s) { ++s.clients_refused; });
      message("refused client " + peer + ": " + why);
    };
    if (!device_) {
      refuse("the device (" + device_description_ + ") is unavailable" +
             (options_.reopen ? "; waiting for it to come back, try again later" : ""));
      continue;
    }
    Client* control = controller();
    if (control && !options_.shared) {
      refuse("the device is in use by another client (" + control->peer +
             "); try again later, or start the server with --shared to let "
             "more clients watch");
      continue;
    }
    const int on = 1;
    ::setsockopt(fd.get(), IPPROTO_TCP, TCP_NODELAY, &on, sizeof on);
    auto client = std::make_unique<Client>();
    client->fd = std::move(fd);
    client->peer = peer;
    client->monitor = control != nullptr;
    if (!client->monitor && options_.restart && had_client_) restart_device();
    if (options_.protocol == BridgeProtocol::rfc2217) {
      client->com_port = std::make_unique<ComPortAdapter>(*this, !client->monitor);
      client->telnet = std::make_unique<rfc::ServerSession>(*client->com_port);
      client->outgoing.append(client->telnet->greeting());
    }
    if (!client->monitor) had_client_ = true;
    client_connected(peer, client->monitor ? "monitor" : "control");
    message("client " + peer + " connected" +
            (client->monitor ? " (read-only monitor)" : ""));
    clients_.push_back(std::move(client));
    write_client(*clients_.back());
  }
}

void Bridge::Impl::read_client(Client& client) {
  std::array<char, kChunk> buffer;
  std::size_t want = buffer.size();
  if (!client.monitor) {
    const std::size_t room = options_.buffer_limit - std::min(options_.buffer_limit, to_device_.size());
    want = std::min(want, room);
    if (want == 0) return;
  }
  const ssize_t got = ::recv(client.fd.get(), buffer.data(), want, 0);
  if (got == 0) {
    drop_client(client, "disconnected");
    return;
  }
  if (got < 0) {
    if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) return;
    drop_client(client, std::string("connection failed: ") + std::strerror(errno));
    return;
  }
  const auto n = static_cast<std::size_t>(got);
  std::string for_device;
  const char* data = buffer.data();
  std::size_t size = n;
  if (client.telnet) {
    // Earlier data reaches the device before a setting the client sent after
    // it.
    flush_to_device();
    std::string answers;
    client.telnet->receive(buffer.data(), n, for_device, answers);
    client.outgoing.append(answers);
    data = for_device.data();
    size = for_device.size();
  }
  if (client.monitor || size == 0 || !device_) return;  // a monitor's input is ignored
  record(RecordKind::tx, std::string_view(data, size));
  to_device_.append(data, size);
  flush_to_device();
}

void Bridge::Impl::write_client(Client& client) {
  if (client.gone) return;
  while (!client.outgoing.empty()) {
    const ssize_t sent = ::send(client.fd.get(), client.outgoing.data(), client.outgoing.size(),
                                MSG_NOSIGNAL | MSG_DONTWAIT);
    if (sent < 0) {
      if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) return;
      drop_client(client, std::string("connection failed: ") + std::strerror(errno));
      return;
    }
    client.outgoing.consume(static_cast<std::size_t>(sent));
  }
}

void Bridge::Impl::drop_client(Client& client, const std::string& reason) {
  if (client.gone) return;
  client.gone = true;
  client.fd.reset();
  client.outgoing.clear();
  client_disconnected(client.peer, reason);
  message("client " + client.peer + " " + reason);
}

void Bridge::Impl::device_lost(const std::string& reason) {
  if (!device_) return;
  record(RecordKind::device_lost, json::ObjectWriter().add(event_field::error, reason).str());
  update_stats([](BridgeStats& s) { ++s.device_losses; });
  message("the device (" + device_description_ + ") went away: " + reason);
  try {
    device_->close();
  } catch (const ReplayMismatch&) {
    throw;
  } catch (const std::exception&) {
  }
  device_.reset();
  to_device_.clear();
  // Clients learn it by their connection closing.
  for (auto& client : clients_) drop_client(*client, "closed: the device went away");
  if (!options_.reopen) {
    end(BridgeOutcome::device_closed, "the device went away: " + reason);
    return;
  }
  reopen_failure_logged_ = false;
  dropped_input_logged_ = false;
  next_reopen_ = Clock::now() + options_.reopen_interval;
}

void Bridge::Impl::try_reopen() {
  try {
    open_device(false, event_field::reopened);
    update_stats([](BridgeStats& s) { ++s.device_reopens; });
    message("the device is back: " + device_description_);
    if (pty_ && options_.mirror_settings) {
      // The client set its line before the device went away: carry it over.
      SerialSettings target = current_settings();
      target.baud = last_pty_settings_.baud;
      target.stop_bits = last_pty_settings_.stop_bits;
      if (target != current_settings()) apply_settings(target, "client's terminal settings");
    }
  } catch (const OptionError&) {
    throw;
  } catch (const std::exception& error) {
    if (!reopen_failure_logged_) {
      message(std::string("waiting for the device to come back (") + error.what() + ")");
      reopen_failure_logged_ = true;
    }
    next_reopen_ = Clock::now() + options_.reopen_interval;
  }
}

void Bridge::Impl::restart_device() {
  if (device_) {
    record(RecordKind::close, "{}");
    device_->close();
    device_.reset();
  }
  to_device_.clear();
  open_device(false, event_field::restarted);
  message("a new client: the device starts over");
}

void Bridge::Impl::shutdown() {
  for (auto& client : clients_) {
    if (!client->gone) {
      write_client(*client);
      drop_client(*client, "closed: the bridge stopped");
    }
  }
  clients_.clear();
  listener_.reset();
  if (device_) {
    try {
      record(RecordKind::close, "{}");
    } catch (const std::exception&) {
    }
    try {
      device_->close();
    } catch (const ReplayMismatch& mismatch) {
      if (end_outcome_ != BridgeOutcome::failed) {
        end_outcome_ = BridgeOutcome::mismatch;
        end_message_ = mismatch.what();
      }
    } catch (const std::exception& error) {
      message(std::string("closing the device: ") + error.what());
    }
    device_.reset();
  }
  if (pty_) {
    try {
      pty_->close();
    } catch (const std::exception&) {
    }
    pty_.reset();
  }
  if (writer_) {
    try {
      writer_->close();
    } catch (const std::exception& error) {
      if (end_outcome_ != BridgeOutcome::mismatch) {
        end_outcome_ = BridgeOutcome::failed;
        end_message_ = std::string("writing the session file: ") + error.what();
      }
    }
  }
}

// --- line settings ---------------------------------------------------------------------

SerialSettings Bridge::Impl::current_settings() {
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

bool Bridge::Impl::apply_settings(const SerialSettings& target, const char* source) {
  // RFC 2217 clients send every setting on open: only changes are applied
  // and recorded.
  if (target == current_settings()) return true;
  bool applied = false;
  try {
    device_->configure(target);
    applied = true;
  } catch (const PortClosed&) {
    throw;
  } catch (const PortError& error) {
    if (!is_unsupported(error) || error.code().value() == EINVAL) {
      message(std::string("the device refused ") + settings_text(target) + ": " + error.what());
      return false;
    }
  }
  // A device without line settings (tcp, replay) keeps them as the client's
  // view of the line.
  virtual_settings_ = target;
  update_stats([](BridgeStats& s) { ++s.settings_changes; });
  record(RecordKind::settings, json::ObjectWriter()
                                   .add(event_field::baud, target.baud)
                                   .add(event_field::databits, target.data_bits)
                                   .add(event_field::stopbits, target.stop_bits)
                                   .add(event_field::parity, to_string(target.parity))
                                   .add(event_field::flow, to_string(target.flow))
                                   .add(event_field::applied, applied)
                                   .add(event_field::source, source)
                                   .str());
  message(std::string(applied ? "device set to " : "line set to (device has no line settings) ") +
          settings_text(target) + " by the " + source);
  return true;
}

void Bridge::Impl::record_modem_line(const char* line, bool level, bool applied) {
  record(RecordKind::modem_lines,
         json::ObjectWriter().add(line, level).add(event_field::applied, applied).str());
}

// RFC 2217 clients are told when CTS, DSR, RI or CD change.
void Bridge::Impl::poll_modem_lines() {
  std::uint8_t state = 0;
  try {
    Port& d = *device_;
    state = static_cast<std::uint8_t>((d.cd() ? 0x80 : 0) | (d.ri() ? 0x40 : 0) |
                                      (d.dsr() ? 0x20 : 0) | (d.cts() ? 0x10 : 0));
  } catch (const PortClosed& closed) {
    device_lost(closed.what());
    return;
  } catch (const PortError&) {
    last_modem_state_ = 0xff;  // no modem lines: stop asking
    return;
  }
  if (last_modem_state_ == state) return;
  last_modem_state_ = state;
  for (auto& client : clients_) {
    if (client->gone || !client->telnet) continue;
    client->outgoing.append(client->telnet->modem_state_notification());
    write_client(*client);
  }
}

void Bridge::Impl::check_pty_settings() {
  SerialSettings seen;
  try {
    seen = pty_->serial_settings();
  } catch (const PortError&) {
    return;
  }
  if (seen == last_pty_settings_) return;
  const SerialSettings before = last_pty_settings_;
  last_pty_settings_ = seen;
  if (!device_) return;
  // Only what the client changed is carried over: a pty cannot show data
  // bits or parity (Linux forces 8N), so the device keeps its own there.
  SerialSettings target = current_settings();
  if (seen.baud != before.baud) target.baud = seen.baud;
  if (seen.data_bits != before.data_bits) target.data_bits = seen.data_bits;
  if (seen.stop_bits != before.stop_bits) target.stop_bits = seen.stop_bits;
  if (seen.parity != before.parity) target.parity = seen.parity;
  if (seen.flow != before.flow) target.flow = seen.flow;
  apply_settings(target, "client's terminal settings");
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
  if (o.client_side == BridgeClientSide::pty && o.protocol == BridgeProtocol::rfc2217) {
    throw OptionError("protocol", "protocol rfc2217 needs a TCP listener, not a pty");
  }
  if (o.buffer_limit < kChunk) {
    throw OptionError("buffer_limit", "buffer_limit must be at least 65536 bytes");
  }
  if (o.duration && o.duration->count() <= 0) {
    throw OptionError("duration", "duration must be positive (seconds)");
  }
  if (o.flush_ms < 1) throw OptionError("flush_ms", "flush_ms must be at least 1");
}

Bridge::~Bridge() {
  stop();
  std::lock_guard<std::mutex> join_lock(impl_->join_mutex_);
  if (impl_->thread_.joinable()) impl_->thread_.join();
}

void Bridge::start() {
  Impl& impl = *impl_;
  {
    std::lock_guard<std::mutex> lock(impl.status_mutex_);
    if (impl.started_) throw std::logic_error("Bridge::start: already started");
    impl.started_ = true;
  }
  int pipe_fds[2];
  if (::pipe2(pipe_fds, O_NONBLOCK | O_CLOEXEC) != 0) raise_errno("bridge: pipe");
  impl.wake_read_.reset(pipe_fds[0]);
  impl.wake_write_.reset(pipe_fds[1]);
  std::string failure = "the bridge could not start";
  try {
    try {
      impl.open_all();
    } catch (const std::exception& error) {
      failure = error.what();
      throw;
    }
  } catch (...) {
    impl.pty_.reset();
    impl.device_.reset();
    impl.listener_.reset();
    if (impl.writer_) {
      // Nothing was recorded: leave no file that looks like a session.
      try {
        impl.writer_->close();
      } catch (...) {
      }
      impl.writer_.reset();
      std::remove(impl.options_.output.c_str());
    }
    std::lock_guard<std::mutex> lock(impl.status_mutex_);
    impl.finished_ = true;
    impl.result_.outcome = BridgeOutcome::failed;
    impl.result_.message = failure;
    throw;
  }
  {
    std::lock_guard<std::mutex> lock(impl.status_mutex_);
    impl.result_.outcome = BridgeOutcome::running;
  }
  impl.thread_ = std::thread([&impl] {
    impl.run();
    std::lock_guard<std::mutex> lock(impl.status_mutex_);
    impl.result_.outcome = impl.end_outcome_;
    impl.result_.message = impl.end_message_;
    impl.finished_ = true;
    impl.finished_cv_.notify_all();
  });
}

void Bridge::stop() {
  Impl& impl = *impl_;
  impl.stop_requested_.store(true);
  std::lock_guard<std::mutex> lock(impl.status_mutex_);
  if (impl.wake_write_) {
    const char byte = 1;
    (void)!::write(impl.wake_write_.get(), &byte, 1);
  }
}

bool Bridge::wait(Timeout timeout) {
  Impl& impl = *impl_;
  std::unique_lock<std::mutex> lock(impl.status_mutex_);
  const auto done = [&] { return impl.finished_ || !impl.started_; };
  if (!timeout) {
    impl.finished_cv_.wait(lock, done);
  } else if (!impl.finished_cv_.wait_for(lock, *timeout, done)) {
    return false;
  }
  lock.unlock();
  if (impl.thread_.joinable() && impl.thread_.get_id() != std::this_thread::get_id()) {
    // The thread has set finished_ as its last act; joining is immediate.
    std::lock_guard<std::mutex> join_lock(impl.join_mutex_);
    if (impl.thread_.joinable()) impl.thread_.join();
  }
  return true;
}

bool Bridge::running() const {
  std::lock_guard<std::mutex> lock(impl_->status_mutex_);
  return impl_->started_ && !impl_->finished_;
}

BridgeResult Bridge::result() const {
  std::lock_guard<std::mutex> lock(impl_->status_mutex_);
  return impl_->result_;
}

BridgeStats Bridge::stats() const {
  std::lock_guard<std::mutex> lock(impl_->status_mutex_);
  return impl_->result_.stats;
}

std::string Bridge::pty_path() const {
  std::lock_guard<std::mutex> lock(impl_->status_mutex_);
  return impl_->pty_path_;
}

std::string Bridge::listen_address() const {
  std::lock_guard<std::mutex> lock(impl_->status_mutex_);
  return impl_->listen_address_;
}

std::string Bridge::device_description() const {
  std::lock_guard<std::mutex> lock(impl_->status_mutex_);
  return impl_->device_description_;
}

std::vector<std::string> Bridge::messages() const {
  std::lock_guard<std::mutex> lock(impl_->status_mutex_);
  return {impl_->messages_.begin(), impl_->messages_.end()};
}

}  // namespace wiretape
