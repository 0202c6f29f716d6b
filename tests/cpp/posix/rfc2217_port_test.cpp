// type=rfc2217 against a server in this process: the negotiation, the line
// API mapped onto COM-PORT-OPTION requests, IAC both ways, and servers that
// misbehave (silent, not Telnet, refusing, gone mid-session, mute or
// answering garbage later),
// each a clear error naming the server; a recording through log= is kept
// and valid when the server goes away.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "core/rfc2217.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

namespace {

using namespace wiretape;
using namespace wiretape::detail::rfc2217;
using wiretape::test::kEventDeadline;

// The device behind the server: every setting taken and logged.
class LoggingComPort final : public ComPort {
 public:
  std::uint32_t set_baud(std::optional<std::uint32_t> baud) override {
    if (baud) baud_ = *baud;
    log("baud " + std::to_string(baud_));
    return baud_;
  }
  int set_data_bits(std::optional<int> bits) override {
    log("databits " + std::to_string(bits.value_or(8)));
    return bits.value_or(8);
  }
  Parity set_parity(std::optional<Parity> parity) override {
    log(std::string("parity ") + to_string(parity.value_or(Parity::none)));
    return parity.value_or(Parity::none);
  }
  StopBits set_stop_bits(std::optional<StopBits> stop_bits) override {
    log(stop_bits == StopBits::two ? "stopbits 2" : "stopbits 1");
    return stop_bits.value_or(StopBits::one);
  }
  FlowControl set_flow_control(std::optional<FlowControl> flow) override {
    log(std::string("flow ") + to_string(flow.value_or(FlowControl::none)));
    return flow.value_or(FlowControl::none);
  }
  bool set_break(std::optional<bool> on) override { return level("break", on); }
  bool set_dtr(std::optional<bool> on) override { return level("dtr", on); }
  bool set_rts(std::optional<bool> on) override { return level("rts", on); }
  void purge(bool from_device, bool for_device) override {
    log(std::string("purge") + (from_device ? " from_device" : "") +
        (for_device ? " for_device" : ""));
  }
  ModemLines modem_lines() override {
    ModemLines lines;
    lines.cts = true;
    lines.cd = true;
    return lines;
  }
  LineState line_state() override { return {}; }

  std::vector<std::string> calls() {
    std::lock_guard<std::mutex> lock(mutex_);
    return calls_;
  }

 private:
  bool level(const char* line, std::optional<bool> on) {
    log(std::string(line) + (on.value_or(true) ? " on" : " off"));
    return on.value_or(true);
  }
  void log(std::string call) {
    std::lock_guard<std::mutex> lock(mutex_);
    calls_.push_back(std::move(call));
  }
  std::mutex mutex_;
  std::vector<std::string> calls_;
  std::uint32_t baud_ = 9600;
};

enum class Behaviour {
  rfc2217,       // a working server
  silent,        // accepts and never says anything
  not_telnet,    // a plain TCP port with a talkative device behind it
  refuses,       // a Telnet server without COM-PORT-OPTION
  mute_later,    // negotiates, then stops answering requests
};

// One client connection on 127.0.0.1, served by a thread of its own.
class FakeServer {
 public:
  explicit FakeServer(Behaviour behaviour) : behaviour_(behaviour) {
    listener_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(::bind(listener_, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
    EXPECT_EQ(::listen(listener_, 1), 0);
    socklen_t length = sizeof address;
    ::getsockname(listener_, reinterpret_cast<sockaddr*>(&address), &length);
    port_ = ntohs(address.sin_port);
    thread_ = std::thread([this] { serve(); });
  }
  ~FakeServer() {
    stop_ = true;
    thread_.join();
    if (connection_ >= 0) ::close(connection_);
    ::close(listener_);
  }

  std::string options(const std::string& extra = "") const {
    return "type=rfc2217,host=127.0.0.1,port=" + std::to_string(port_) + extra;
  }
  std::string where() const { return "rfc2217 127.0.0.1:" + std::to_string(port_); }
  LoggingComPort& device() { return device_; }

  // Device data for the client, escaped.
  void send_device(const std::string& data) {
    std::string escaped;
    TelnetSession::escape(data.data(), data.size(), escaped);
    send_raw(escaped);
  }
  // Waits until the device received `size` bytes from the client.
  std::string device_received(std::size_t size) {
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait_for(lock, kEventDeadline, [&] { return to_device_.size() >= size; });
    return to_device_;
  }
  // Ends the connection, as a server that goes away.
  void drop() {
    std::lock_guard<std::mutex> lock(mutex_);
    ::shutdown(connection_, SHUT_RDWR);
    dropped_ = true;
  }
  void stop_answering() { mute_ = true; }
  // Later requests are answered with a malformed answer (a SET-BAUDRATE
  // answer of one byte) and stray data.
  void answer_garbage() { garbage_ = true; }

 private:
  void send_raw(const std::string& bytes) {
    std::lock_guard<std::mutex> lock(send_mutex_);
    ASSERT_EQ(::send(connection_, bytes.data(), bytes.size(), MSG_NOSIGNAL),
              static_cast<ssize_t>(bytes.size()));
  }

  void serve() {
    pollfd waiting{listener_, POLLIN, 0};
    while (!stop_ && ::poll(&waiting, 1, 20) == 0) {
    }
    if (stop_) return;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      connection_ = ::accept(listener_, nullptr, nullptr);
    }
    ServerSession session(device_);
    if (behaviour_ == Behaviour::rfc2217 || behaviour_ == Behaviour::mute_later) {
      send_raw(session.greeting());
    }
    if (behaviour_ == Behaviour::not_telnet) send_raw("login: hello, this is a shell\r\n");
    if (behaviour_ == Behaviour::refuses) {
      send_raw(std::string("\xff\xfe\x2c\xff\xfc\x2c", 6));  // DONT, WONT COM-PORT-OPTION
    }
    char buffer[4096];
    while (!stop_) {
      pollfd ready{connection_, POLLIN, 0};
      if (::poll(&ready, 1, 20) <= 0) continue;
      const ssize_t n = ::recv(connection_, buffer, sizeof buffer, 0);
      if (n <= 0) return;
      if (behaviour_ != Behaviour::rfc2217 && behaviour_ != Behaviour::mute_later) continue;
      if (garbage_) {
        send_raw(std::string("\xff\xfa\x2c\x65\x01\xff\xf0?!", 9));
        continue;
      }
      if (mute_) continue;
      std::string to_device;
      std::string to_client;
      session.receive(buffer, static_cast<std::size_t>(n), to_device, to_client);
      if (!to_client.empty()) send_raw(to_client);
      std::lock_guard<std::mutex> lock(mutex_);
      to_device_ += to_device;
      changed_.notify_all();
    }
  }

  Behaviour behaviour_;
  LoggingComPort device_;
  int listener_ = -1;
  int connection_ = -1;
  int port_ = 0;
  std::atomic<bool> stop_{false};
  std::atomic<bool> mute_{false};
  std::atomic<bool> garbage_{false};
  bool dropped_ = false;
  std::mutex mutex_;
  std::mutex send_mutex_;
  std::condition_variable changed_;
  std::string to_device_;
  std::thread thread_;
};

std::string error_of(const std::string& options) {
  try {
    open_port(options);
  } catch (const PortError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST(Rfc2217Port, NegotiatesAndSetsTheLineOnOpen) {
  FakeServer server(Behaviour::rfc2217);
  auto port = open_port(server.options(",baud=115200,parity=even,stopbits=2"));
  EXPECT_EQ(port->type(), "rfc2217");
  EXPECT_EQ(server.device().calls(),
            (std::vector<std::string>{"baud 115200", "databits 8", "parity even",
                                      "stopbits 2", "flow none"}));
  const SerialSettings settings = port->serial_settings();
  EXPECT_EQ(settings.baud, 115200u);
  EXPECT_EQ(settings.parity, Parity::even);
  EXPECT_EQ(settings.stop_bits, 2);
  EXPECT_TRUE(port->capabilities().modem_lines);
  EXPECT_NE(port->description().find(server.where()), std::string::npos);
}

TEST(Rfc2217Port, DataPassesBothWaysWithIacEscaped) {
  FakeServer server(Behaviour::rfc2217);
  auto port = open_port(server.options(",timeout=10"));
  const std::string to_device("a\xff" "b\r\n\xff\xff", 7);
  ASSERT_EQ(port->write_all(to_device), to_device.size());
  EXPECT_EQ(server.device_received(to_device.size()), to_device);

  const std::string from_device("\xff\x00z\r\xff", 5);
  server.send_device(from_device);
  EXPECT_EQ(port->read_exactly(from_device.size()), from_device);
  EXPECT_EQ(port->available(), 0u);
  // Nothing more to read: a read times out instead of returning Telnet.
  char byte;
  EXPECT_EQ(port->read(&byte, 1, std::chrono::milliseconds(0)), 0u);
}

TEST(Rfc2217Port, NativeHandleIsReadableExactlyWhileDataWaits) {
  FakeServer server(Behaviour::rfc2217);
  auto port = open_port(server.options(",timeout=10"));
  EXPECT_FALSE(wiretape::test::fd_readable(port->native_handle(), std::chrono::milliseconds(0)));
  server.send_device("xy");
  EXPECT_TRUE(wiretape::test::fd_readable(port->native_handle(), kEventDeadline));
  EXPECT_EQ(port->read_exactly(2), "xy");
  EXPECT_FALSE(wiretape::test::fd_readable(port->native_handle(), std::chrono::milliseconds(0)));
}

TEST(Rfc2217Port, LinesBreakAndFlushesAreRequestsTheServerAnswers) {
  FakeServer server(Behaviour::rfc2217);
  auto port = open_port(server.options());
  const std::size_t at_open = server.device().calls().size();
  port->set_dtr(false);
  port->set_rts(true);
  port->send_break(std::chrono::milliseconds(0));
  port->flush_input();
  port->flush_output();
  port->set_baud(57600);
  const std::vector<std::string> calls = server.device().calls();
  EXPECT_EQ(std::vector<std::string>(calls.begin() + static_cast<long>(at_open), calls.begin() + static_cast<long>(at_open) + 6),
            (std::vector<std::string>{"dtr off", "rts on", "break on", "break off",
                                      "purge from_device", "purge for_device"}));
  EXPECT_EQ(port->serial_settings().baud, 57600u);
  // The modem state the server announced when COM-PORT-OPTION was agreed.
  EXPECT_TRUE(port->cts());
  EXPECT_TRUE(port->cd());
  EXPECT_FALSE(port->dsr());
  EXPECT_FALSE(port->ri());
}

TEST(Rfc2217Port, ASilentServerIsAnErrorNamingItWithinTheAnswerTimeout) {
  FakeServer server(Behaviour::silent);
  const auto start = std::chrono::steady_clock::now();
  const std::string error = error_of(server.options(",answer_timeout=0.3"));
  EXPECT_NE(error.find(server.where()), std::string::npos) << error;
  EXPECT_NE(error.find("no RFC 2217 answer within 0.3 s"), std::string::npos) << error;
  EXPECT_NE(error.find("no Telnet negotiation at all"), std::string::npos) << error;
  EXPECT_LT(std::chrono::steady_clock::now() - start, kEventDeadline);
}

TEST(Rfc2217Port, APlainTcpPortIsNamedAsOne) {
  FakeServer server(Behaviour::not_telnet);
  const std::string error = error_of(server.options(",answer_timeout=0.3"));
  EXPECT_NE(error.find(server.where()), std::string::npos) << error;
  EXPECT_NE(error.find("bytes of data: is it a plain TCP port?"), std::string::npos) << error;
}

TEST(Rfc2217Port, AServerRefusingComPortOptionIsNamed) {
  FakeServer server(Behaviour::refuses);
  const std::string error = error_of(server.options());
  EXPECT_NE(error.find(server.where() + ": the server refused COM-PORT-OPTION"),
            std::string::npos)
      << error;
}

TEST(Rfc2217Port, AServerThatStopsAnsweringIsNamedWithTheRequest) {
  FakeServer server(Behaviour::mute_later);
  auto port = open_port(server.options(",answer_timeout=0.3"));
  server.stop_answering();
  try {
    port->set_baud(19200);
    FAIL() << "no error";
  } catch (const PortError& e) {
    const std::string error = e.what();
    EXPECT_NE(error.find(server.where() + ": the server did not answer SET-BAUDRATE within 0.3 s"),
              std::string::npos)
        << error;
  }
}

TEST(Rfc2217Port, AServerAnsweringGarbageIsNamedWithTheRequest) {
  FakeServer server(Behaviour::rfc2217);
  auto port = open_port(server.options(",answer_timeout=0.3,timeout=10"));
  server.answer_garbage();
  try {
    port->set_baud(19200);
    FAIL() << "no error";
  } catch (const PortError& e) {
    const std::string error = e.what();
    EXPECT_NE(error.find(server.where() + ": the server did not answer SET-BAUDRATE within 0.3 s"),
              std::string::npos)
        << error;
  }
  // The stray bytes are data, as a serial line's noise would be.
  EXPECT_EQ(port->read_exactly(2), "?!");
}

TEST(Rfc2217Port, AServerGoneMidSessionIsPortClosedNamingIt) {
  FakeServer server(Behaviour::rfc2217);
  auto port = open_port(server.options(",timeout=10"));
  server.send_device("last");
  EXPECT_EQ(port->read_exactly(4), "last");
  server.drop();
  char byte;
  try {
    port->read(&byte, 1);
    FAIL() << "no error";
  } catch (const PortClosed& e) {
    EXPECT_NE(std::string(e.what()).find(server.where() + ": the server closed the connection"),
              std::string::npos)
        << e.what();
  }
  EXPECT_THROW(port->set_dtr(true), PortClosed);
}

TEST(Rfc2217Port, ARecordingKeepsWhatCameBeforeTheServerWentAway) {
  wiretape::test::TempDir dir;
  const std::string path = dir.file("lab.wtape");
  {
    FakeServer server(Behaviour::rfc2217);
    auto port = open_port(server.options(",timeout=10,baud=115200,log=" + path));
    port->set_dtr(false);
    port->write_all(std::string("ping"));
    server.device_received(4);
    server.send_device("pong");
    EXPECT_EQ(port->read_exactly(4), "pong");
    server.drop();
    char byte;
    EXPECT_THROW(port->read(&byte, 1), PortClosed);
  }
  SessionReader reader(path);
  EXPECT_EQ(reader.header().port_type, "rfc2217");
  std::vector<std::string> kinds;
  std::string rx;
  Record record;
  while (reader.next(record)) {
    kinds.emplace_back(to_string(record.kind));
    if (record.kind == RecordKind::rx) rx += record.data;
  }
  EXPECT_FALSE(reader.damage());
  EXPECT_EQ(rx, "pong");
  // Recorded as a serial port's: its modem inputs, the DTR change, the bytes.
  for (const char* kind : {"open", "modem_lines", "tx", "rx", "close"}) {
    EXPECT_NE(std::find(kinds.begin(), kinds.end(), kind), kinds.end()) << kind;
  }
}
