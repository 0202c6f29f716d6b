// type=rfc2217: a serial line exported over the network by an RFC 2217
// server (ser2net, a labgrid exporter, pyserial's server, wiretape serve),
// spoken to through the client session of src/core/rfc2217.hpp over a TCP
// connection (the tcp port's). The Port's line API maps onto COM-PORT-OPTION
// requests, each waited for until the server answers, so that a recording
// through log= records them as a serial port's events.
//
// One thread reads the connection: it decodes the Telnet stream, keeps the
// device's data for read(), answers the server's negotiations and takes its
// answers and notifications. The caller's threads read from that buffer
// (native_handle() is a pipe readable exactly while it holds data or the
// server is gone) and write to the connection directly.
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <thread>

#include "core/rfc2217.hpp"
#include "posix/transports.hpp"
#include "posix/wake_pipe.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

namespace {

using rfc2217::Answer;
using rfc2217::ClientSession;

std::string seconds_text(std::chrono::nanoseconds duration) {
  char text[32];
  std::snprintf(text, sizeof text, "%g s", std::chrono::duration<double>(duration).count());
  return text;
}

class Rfc2217Port final : public Port {
 public:
  Rfc2217Port(std::unique_ptr<Port> connection, std::string where,
              std::chrono::nanoseconds answer_timeout)
      : connection_(std::move(connection)),
        where_(std::move(where)),
        answer_timeout_(answer_timeout),
        readable_("rfc2217 port") {}
  ~Rfc2217Port() override { close(); }

  // Agrees COM-PORT-OPTION and BINARY, then sets the line.
  void negotiate(const SerialSettings& settings) {
    // Our offers are on record before the reader takes the server's first
    // byte, which may be an answer to them.
    const std::string greeting = session_.greeting();
    reader_ = std::thread([this] { read_connection(); });
    send(greeting);
    const Deadline deadline = deadline_after(answer_timeout_);
    std::unique_lock<std::mutex> lock(mutex_);
    const bool settled = changed_.wait_until(lock, *deadline, [&] {
      return gone_ || session_.com_port_refused() ||
             (session_.com_port_agreed() && session_.binary_settled());
    });
    if (gone_) {
      throw PortClosed(where_ + ": the server closed the connection during the Telnet "
                                "negotiation (" + gone_reason_ + ")");
    }
    if (session_.com_port_refused()) {
      throw PortError(EPROTO, where_ + ": the server refused COM-PORT-OPTION: it is a "
                                       "Telnet server without RFC 2217 (in ser2net, "
                                       "give the port the telnet(rfc2217) accepter)",
                      PortError::OwnExplanation{});
    }
    if (session_.binary_refused()) {
      throw PortError(EPROTO, where_ + ": the server refused Telnet BINARY mode, so "
                                       "bytes 13 and 255 would not pass unchanged",
                      PortError::OwnExplanation{});
    }
    if (!settled) {
      std::string what = session_.heard_telnet()
                             ? "it spoke Telnet but did not agree to COM-PORT-OPTION"
                             : "it sent no Telnet negotiation at all";
      if (!received_.empty()) {
        what += ", and " + std::to_string(received_.size()) +
                " bytes of data: is it a plain TCP port?";
      }
      throw PortError(ETIMEDOUT, where_ + ": no RFC 2217 answer within " +
                                     seconds_text(answer_timeout_) + " (" + what + ")",
                      PortError::OwnExplanation{});
    }
    lock.unlock();
    configure(settings);
  }

  std::string type() const override { return "rfc2217"; }
  std::string description() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return where_ + " @ " + std::to_string(settings_.baud) + " " +
           std::to_string(settings_.data_bits) +
           static_cast<char>(std::toupper(to_string(settings_.parity)[0])) +
           std::to_string(settings_.stop_bits);
  }
  PortCapabilities capabilities() const override {
    PortCapabilities c;
    c.serial_settings = c.modem_lines = c.send_break = true;
    return c;
  }
  int native_handle() const override { return is_open() ? readable_.fd() : -1; }
  bool is_open() const override { return !closed_; }

  std::size_t available() override {
    std::lock_guard<std::mutex> lock(mutex_);
    return received_.size();
  }

  void close() override {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (closed_) return;
      closed_ = true;
    }
    changed_.notify_all();
    readable_.wake();
    connection_->close();  // wakes the reader's blocked read
    if (reader_.joinable()) reader_.join();
  }

  void flush_input() override {
    request(ClientSession::purge(true, false), Answer::purge);
    std::lock_guard<std::mutex> lock(mutex_);
    received_.clear();
    if (!gone_) readable_.drain();
  }
  void flush_output() override { request(ClientSession::purge(false, true), Answer::purge); }
  // What the server has not yet written to the device is out of reach: RFC
  // 2217 has no request to wait for it.
  void drain() override {}

  void set_baud(unsigned baud) override {
    SerialSettings settings = serial_settings();
    settings.baud = baud;
    configure(settings);
  }
  void configure(const SerialSettings& settings) override {
    request(ClientSession::set_baud(settings.baud), Answer::baud);
    request(ClientSession::set_data_bits(settings.data_bits), Answer::data_size);
    request(ClientSession::set_parity(settings.parity), Answer::parity);
    request(ClientSession::set_stop_bits(settings.stop_bits == 2 ? rfc2217::StopBits::two
                                                                 : rfc2217::StopBits::one),
            Answer::stop_size);
    request(ClientSession::set_flow_control(settings.flow), Answer::control);
    std::lock_guard<std::mutex> lock(mutex_);
    const rfc2217::ServerState& now = session_.state();
    SerialSettings in_effect = settings;
    in_effect.baud = now.baud.value_or(settings.baud);
    in_effect.data_bits = now.data_bits.value_or(settings.data_bits);
    in_effect.parity = now.parity.value_or(settings.parity);
    in_effect.stop_bits = now.stop_bits == rfc2217::StopBits::two ? 2 : 1;
    if (!now.stop_bits) in_effect.stop_bits = settings.stop_bits;
    in_effect.flow = now.flow.value_or(settings.flow);
    settings_ = in_effect;
    if (in_effect != settings) {
      throw PortError(EINVAL, where_ + ": the server did not take the line settings: asked " +
                                  settings_text(settings) + ", it set " +
                                  settings_text(in_effect),
                      PortError::OwnExplanation{});
    }
  }
  SerialSettings serial_settings() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return settings_;
  }
  void set_dtr(bool level) override { request(ClientSession::set_dtr(level), Answer::control); }
  void set_rts(bool level) override { request(ClientSession::set_rts(level), Answer::control); }
  bool cts() override { return modem_lines().cts; }
  bool dsr() override { return modem_lines().dsr; }
  bool ri() override { return modem_lines().ri; }
  bool cd() override { return modem_lines().cd; }
  void send_break(std::chrono::milliseconds duration) override {
    request(ClientSession::set_break(true), Answer::control);
    // The server holds the break for as long as we wait: RFC 2217 has no
    // timed break.
    std::this_thread::sleep_for(duration);
    request(ClientSession::set_break(false), Answer::control);
  }

 protected:
  std::size_t read_some(void* buffer, std::size_t size, Deadline deadline) override {
    return take(buffer, size, deadline, /*consume=*/true);
  }
  std::optional<std::size_t> peek_some(void* buffer, std::size_t size,
                                       Deadline deadline) override {
    return take(buffer, size, deadline, /*consume=*/false);
  }
  bool wait_readable_until(Deadline deadline) override {
    std::unique_lock<std::mutex> lock(mutex_);
    return wait_for_data(lock, deadline);
  }
  std::size_t write_some(const void* data, std::size_t size, Deadline deadline) override {
    check_usable();
    // A bounded piece, so that its escaped form is sent whole: a Telnet
    // stream cut inside an IAC IAC would change the next byte's meaning.
    constexpr std::size_t piece = 4096;
    const std::size_t taken = std::min(size, piece);
    std::string escaped;
    rfc2217::TelnetSession::escape(data, taken, escaped);
    std::lock_guard<std::mutex> lock(send_mutex_);
    const std::size_t sent = guarded([&] {
      return connection_->write_all(escaped.data(), escaped.size(), remaining(deadline));
    });
    if (sent == 0) return 0;
    if (sent < escaped.size()) {
      guarded([&] { return connection_->write_all(escaped.data() + sent, escaped.size() - sent, forever); });
    }
    return taken;
  }

 private:
  static std::string settings_text(const SerialSettings& s) {
    return std::to_string(s.baud) + " " + std::to_string(s.data_bits) + " " +
           to_string(s.parity) + " " + std::to_string(s.stop_bits) + " flow " +
           to_string(s.flow);
  }

  // Calls `f` on the connection, naming this port in what it raises.
  template <typename F>
  auto guarded(F f) -> decltype(f()) {
    try {
      return f();
    } catch (const PortClosed& e) {
      if (closed_) throw PortClosed(where_ + ": port closed");
      throw PortClosed(where_ + ": the server closed the connection (" + e.what() + ")");
    } catch (const PortError& e) {
      throw PortError(e.code().value(), where_ + ": " + e.what(), PortError::OwnExplanation{});
    }
  }

  void check_usable() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (closed_) throw PortClosed(where_ + ": port closed");
    if (gone_) throw PortClosed(where_ + ": " + gone_reason_);
  }

  void send(const std::string& bytes) {
    if (bytes.empty()) return;
    std::lock_guard<std::mutex> lock(send_mutex_);
    guarded([&] { return connection_->write_all(bytes.data(), bytes.size(), forever); });
  }

  // Sends a COM-PORT-OPTION request and waits for the server's answer.
  void request(const std::string& bytes, Answer answer) {
    check_usable();
    std::uint64_t before;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      before = session_.answers(answer);
    }
    send(bytes);
    std::unique_lock<std::mutex> lock(mutex_);
    const bool answered = changed_.wait_for(lock, answer_timeout_, [&] {
      return closed_ || gone_ || session_.answers(answer) > before;
    });
    if (closed_) throw PortClosed(where_ + ": port closed");
    if (gone_) throw PortClosed(where_ + ": " + gone_reason_);
    if (!answered) {
      throw PortError(ETIMEDOUT, where_ + ": the server did not answer " +
                                     ClientSession::name_of(answer) + " within " +
                                     seconds_text(answer_timeout_),
                      PortError::OwnExplanation{});
    }
  }

  rfc2217::ModemLines modem_lines() {
    check_usable();
    std::lock_guard<std::mutex> lock(mutex_);
    return session_.state().modem_lines.value_or(rfc2217::ModemLines{});
  }

  bool wait_for_data(std::unique_lock<std::mutex>& lock, Deadline deadline) {
    const auto ready = [&] { return closed_ || gone_ || !received_.empty(); };
    if (!deadline) {
      changed_.wait(lock, ready);
      return true;
    }
    return changed_.wait_until(lock, *deadline, ready);
  }

  std::size_t take(void* buffer, std::size_t size, Deadline deadline, bool consume) {
    std::unique_lock<std::mutex> lock(mutex_);
    if (!wait_for_data(lock, deadline)) return 0;
    if (closed_) throw PortClosed(where_ + ": port closed");
    if (received_.empty()) throw PortClosed(where_ + ": " + gone_reason_);
    const std::size_t n = std::min(size, received_.size());
    received_.copy(static_cast<char*>(buffer), n);
    if (consume) {
      received_.erase(0, n);
      if (received_.empty() && !gone_) readable_.drain();
    }
    return n;
  }

  // The reader thread: until the connection ends.
  void read_connection() {
    char buffer[16384];
    std::string answers;
    for (;;) {
      std::size_t n = 0;
      std::string reason;
      try {
        n = connection_->read(buffer, sizeof buffer, forever);
      } catch (const PortClosed& e) {
        reason = std::string("the server closed the connection (") + e.what() + ")";
      } catch (const std::exception& e) {
        reason = std::string("reading from the server failed: ") + e.what();
      }
      if (!reason.empty()) {
        {
          std::lock_guard<std::mutex> lock(mutex_);
          gone_ = true;
          gone_reason_ = reason;
        }
        readable_.wake();
        changed_.notify_all();
        return;
      }
      answers.clear();
      bool has_data = false;
      {
        std::lock_guard<std::mutex> lock(mutex_);
        const std::size_t had = received_.size();
        session_.receive(buffer, n, received_, answers);
        has_data = received_.size() > had;
      }
      if (has_data) readable_.wake();
      changed_.notify_all();
      if (!answers.empty()) {
        try {
          send(answers);
        } catch (const std::exception&) {
          // The read that follows sees the connection gone.
        }
      }
    }
  }

  std::unique_ptr<Port> connection_;
  const std::string where_;
  const std::chrono::nanoseconds answer_timeout_;
  WakePipe readable_;  // readable while received_ holds data, or the server is gone
  mutable std::mutex mutex_;  // the session and everything below
  std::condition_variable changed_;
  ClientSession session_;
  std::string received_;
  SerialSettings settings_;
  bool closed_ = false;
  bool gone_ = false;
  std::string gone_reason_;
  std::mutex send_mutex_;  // one sender on the connection at a time
  std::thread reader_;
};

}  // namespace

std::unique_ptr<Port> open_rfc2217(Options& options) {
  const std::string host = options.take_string("host");
  const int port = static_cast<int>(options.take_int("port"));
  SerialSettings settings;
  settings.baud = static_cast<unsigned>(options.take_int("baud"));
  settings.data_bits = static_cast<int>(options.take_int("databits"));
  settings.stop_bits = static_cast<int>(options.take_int("stopbits"));
  settings.parity = parse_parity(options.take_choice("parity")).value_or(Parity::none);
  settings.flow = parse_flow_control(options.take_choice("flow")).value_or(FlowControl::none);
  const Timeout answer_timeout = options.take_timeout("answer_timeout");
  options.finish("rfc2217");  // reject bad keys before connecting

  const std::string where = "rfc2217 " + host + ":" + std::to_string(port);
  // answer_timeout=-1 waits as long as a wait can be told to.
  const std::chrono::nanoseconds bound =
      answer_timeout.value_or(std::chrono::hours(24 * 365));
  auto connection = connect_tcp(host, port, answer_timeout, where);
  auto opened = std::make_unique<Rfc2217Port>(std::move(connection), where, bound);
  opened->negotiate(settings);
  return opened;
}

}  // namespace wiretape::detail
