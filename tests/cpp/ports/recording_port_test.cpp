// The recording port (log=FILE): what it records, that it forwards
// everything unchanged, and what happens when recording fails.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <stdlib.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include "support/port_test_support.hpp"

#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <deque>
#include <future>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "util/json.hpp"
#include "ports/ports.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

using namespace wiretape;
using namespace std::chrono_literals;

namespace {

using wiretape::test::TempDir;

// A scripted device: reads return queued chunks (0 when none: a timeout),
// writes accept at most `write_limit` bytes a call, and every serial-control
// call is noted.
class FakePort final : public Port {
 public:
  std::deque<std::string> incoming;
  std::string written;
  std::size_t write_limit = 1 << 20;
  std::chrono::milliseconds write_delay{0};
  bool lost = false;
  std::vector<std::string> calls;
  bool open = true;
  bool has_modem_lines = false;  // what capabilities() says
  bool cts_level = true;

  PortCapabilities capabilities() const override {
    PortCapabilities c;
    c.modem_lines = has_modem_lines;
    return c;
  }

  std::size_t available() override {
    calls.push_back("available");
    return incoming.empty() ? 0 : incoming.front().size();
  }
  void flush_input() override { calls.push_back("flush_input"); }
  void flush_output() override { calls.push_back("flush_output"); }
  void drain() override { calls.push_back("drain"); }
  void close() override { open = false; }
  bool is_open() const override { return open; }
  std::string description() const override { return "fake device"; }
  std::string type() const override { return "fake"; }
  int native_handle() const override { return 42; }
  void set_baud(unsigned baud) override { calls.push_back("baud " + std::to_string(baud)); }
  void configure(const SerialSettings& s) override {
    calls.push_back("configure " + std::to_string(s.baud));
  }
  SerialSettings serial_settings() const override {
    SerialSettings s;
    s.baud = 4242;
    return s;
  }
  void set_dtr(bool level) override { calls.push_back(std::string("dtr ") + (level ? "1" : "0")); }
  void set_rts(bool level) override { calls.push_back(std::string("rts ") + (level ? "1" : "0")); }
  bool cts() override { return cts_level; }
  bool dsr() override { return false; }
  bool ri() override { return true; }
  bool cd() override { return false; }
  void send_break(std::chrono::milliseconds d) override {
    calls.push_back("break " + std::to_string(d.count()));
  }

 protected:
  std::size_t read_some(void* buffer, std::size_t size, Deadline) override {
    if (lost) throw PortClosed("fake device: unplugged", ENXIO);
    if (incoming.empty()) return 0;  // the deadline passed with nothing
    std::string& front = incoming.front();
    const std::size_t n = std::min(size, front.size());
    std::copy_n(front.data(), n, static_cast<char*>(buffer));
    front.erase(0, n);
    if (front.empty()) incoming.pop_front();
    return n;
  }
  std::size_t write_some(const void* data, std::size_t size, Deadline) override {
    if (lost) throw PortClosed("fake device: unplugged", ENXIO);
    if (write_delay.count() > 0) {
      // A slow device: the call takes at least write_delay.
      std::mutex mutex;
      std::condition_variable never;
      std::unique_lock<std::mutex> lock(mutex);
      never.wait_for(lock, write_delay);
    }
    const std::size_t n = std::min(size, write_limit);
    written.append(static_cast<const char*>(data), n);
    return n;
  }
  bool wait_readable_until(Deadline) override { return !incoming.empty(); }
};

detail::RecordingConfig config_for(const std::string& path) {
  detail::RecordingConfig config;
  config.path = path;
  config.options_text = "type=fake,log=" + path;
  config.port_type = "fake";
  config.flush_ms = 10;
  config.metadata = {{"who", "test"}};
  return config;
}

std::vector<Record> read_all(const std::string& path) {
  SessionReader reader(path);
  std::vector<Record> records;
  Record record;
  while (reader.next(record)) records.push_back(record);
  EXPECT_FALSE(reader.damage());
  return records;
}

std::vector<std::string> kinds_of(const std::vector<Record>& records) {
  std::vector<std::string> kinds;
  for (const auto& record : records) kinds.emplace_back(to_string(record.kind));
  return kinds;
}

}  // namespace

TEST(RecordingPort, RecordsReadsWritesAndEventsInOrder) {
  TempDir dir;
  const std::string path = dir.file("s.wtape");
  auto fake_owner = std::make_unique<FakePort>();
  FakePort& fake = *fake_owner;
  fake.incoming = {"abc", "de"};
  fake.write_limit = 3;
  auto port = detail::record_port(std::move(fake_owner), config_for(path));

  EXPECT_EQ(port->write("hello", 5), 3u);  // the device took 3 bytes
  char buffer[16];
  EXPECT_EQ(port->read(buffer, sizeof buffer), 3u);
  EXPECT_EQ(port->read_exactly(2), "de");
  port->flush_input();
  port->flush_output();
  port->drain();
  port->set_baud(115200);
  SerialSettings settings;
  settings.baud = 57600;
  settings.parity = Parity::even;
  port->configure(settings);
  port->set_dtr(true);
  port->set_rts(false);
  port->send_break(250ms);
  port->close();

  const auto records = read_all(path);
  EXPECT_EQ(kinds_of(records),
            (std::vector<std::string>{"open", "tx", "rx", "rx", "flush_input",
                                      "flush_output", "drain", "settings", "settings",
                                      "modem_lines", "modem_lines", "break", "close"}));
  ASSERT_EQ(records.size(), 13u);
  EXPECT_EQ(records[0].t_ns, 0u);
  EXPECT_EQ(detail::json::parse(records[0].data).string_member("description"),
            "fake device");
  EXPECT_EQ(records[1].data, "hel");
  EXPECT_EQ(records[2].data, "abc");
  EXPECT_EQ(records[3].data, "de");
  EXPECT_EQ(records[7].data, "{\"baud\":115200}");
  EXPECT_EQ(records[8].data,
            "{\"baud\":57600,\"databits\":8,\"stopbits\":1,\"parity\":\"even\",\"flow\":\"none\"}");
  EXPECT_EQ(records[9].data, "{\"dtr\":true}");
  EXPECT_EQ(records[10].data, "{\"rts\":false}");
  EXPECT_EQ(records[11].data, "{\"duration_ms\":250}");
  for (std::size_t i = 1; i < records.size(); ++i) {
    EXPECT_GE(records[i].t_ns, records[i - 1].t_ns) << i;
  }
  SessionReader reader(path);
  EXPECT_EQ(reader.header().port_type, "fake");
  EXPECT_EQ(reader.header().port_options, "type=fake,log=" + path);
  EXPECT_EQ(reader.header().capture, Capture::client);
  EXPECT_EQ(reader.header().user_metadata.at("who"), "test");
}

TEST(RecordingPort, RecordsTheDeviceLinesAtOpenAndWhenAReadFindsThemChanged) {
  TempDir dir;
  const std::string path = dir.file("lines.wtape");
  auto fake_owner = std::make_unique<FakePort>();
  FakePort* fake = fake_owner.get();
  fake->has_modem_lines = true;
  fake->cts_level = false;
  auto port = detail::record_port(std::move(fake_owner), config_for(path));
  port->set_dtr(false);
  EXPECT_FALSE(port->cts());  // unchanged: not recorded again
  fake->cts_level = true;
  EXPECT_TRUE(port->dsr() == false && port->cts());  // a read of any line sees the change
  port->close();
  const auto records = read_all(path);
  std::vector<std::string> lines;
  for (const Record& record : records) {
    if (record.kind == RecordKind::modem_lines) lines.push_back(record.data);
  }
  EXPECT_EQ(lines, (std::vector<std::string>{
                       R"({"cts":false,"dsr":false,"ri":true,"cd":false})",
                       R"({"dtr":false})",
                       R"({"cts":true,"dsr":false,"ri":true,"cd":false})"}));
}

TEST(RecordingPort, ADeviceWithoutLinesGetsNoLineEvents) {
  TempDir dir;
  const std::string path = dir.file("nolines.wtape");
  auto port = detail::record_port(std::make_unique<FakePort>(), config_for(path));
  EXPECT_TRUE(port->cts());  // answered by the port, not recorded
  port->close();
  for (const Record& record : read_all(path)) EXPECT_NE(record.kind, RecordKind::modem_lines);
}

TEST(RecordingPort, TimedOutReadsAreNotRecorded) {
  TempDir dir;
  const std::string path = dir.file("s.wtape");
  auto port = detail::record_port(std::make_unique<FakePort>(), config_for(path));
  char byte;
  EXPECT_EQ(port->read(&byte, 1, 0ms), 0u);
  EXPECT_EQ(port->read_exactly(4, 0ms), "");
  port->close();
  EXPECT_EQ(kinds_of(read_all(path)), (std::vector<std::string>{"open", "close"}));
}

TEST(RecordingPort, WritesAreStampedWhenTheCallEntered) {
  TempDir dir;
  const std::string path = dir.file("s.wtape");
  auto fake_owner = std::make_unique<FakePort>();
  fake_owner->write_delay = 60ms;
  fake_owner->incoming = {"reply"};
  auto port = detail::record_port(std::move(fake_owner), config_for(path));
  port->write_all("request");
  EXPECT_EQ(port->read_exactly(5), "reply");
  port->close();
  const auto records = read_all(path);
  ASSERT_EQ(kinds_of(records), (std::vector<std::string>{"open", "tx", "rx", "close"}));
  // The read returned after the slow write finished; the write is stamped at
  // its start, so at least the write's duration lies between the two.
  EXPECT_GE(records[2].t_ns - records[1].t_ns, 60'000'000u);
}

TEST(RecordingPort, ForwardsEverythingUnchanged) {
  TempDir dir;
  auto fake_owner = std::make_unique<FakePort>();
  FakePort& fake = *fake_owner;
  fake.incoming = {"xyz"};
  fake_owner->set_timeout(1500ms);
  fake_owner->set_access(Access::read_only);
  auto port = detail::record_port(std::move(fake_owner), config_for(dir.file("s.wtape")));
  EXPECT_EQ(port->available(), 3u);
  EXPECT_TRUE(port->wait_readable(0ms));
  EXPECT_EQ(port->native_handle(), 42);
  EXPECT_EQ(port->description(), "fake device");
  EXPECT_EQ(port->type(), "fake");
  EXPECT_EQ(port->timeout(), Timeout(1500ms));
  EXPECT_EQ(port->access(), Access::read_only);
  EXPECT_THROW(port->write("no", 2), PortError);  // read-only, as the port under it
  EXPECT_TRUE(port->cts());
  EXPECT_FALSE(port->dsr());
  EXPECT_TRUE(port->ri());
  EXPECT_FALSE(port->cd());
  EXPECT_EQ(port->serial_settings().baud, 4242u);
  EXPECT_TRUE(port->is_open());
  port->close();
  EXPECT_FALSE(port->is_open());
  EXPECT_FALSE(fake.open);
}

TEST(RecordingPort, DeviceLossIsRecordedAndRaised) {
  TempDir dir;
  const std::string path = dir.file("s.wtape");
  auto fake_owner = std::make_unique<FakePort>();
  FakePort& fake = *fake_owner;
  auto port = detail::record_port(std::move(fake_owner), config_for(path));
  fake.lost = true;
  char byte;
  EXPECT_THROW(port->read(&byte, 1), PortClosed);
  EXPECT_THROW(port->read(&byte, 1), PortClosed);
  port->close();
  const auto records = read_all(path);
  ASSERT_EQ(kinds_of(records), (std::vector<std::string>{"open", "device_lost", "close"}));
  const auto event = detail::json::parse(records[1].data);
  EXPECT_EQ(event.string_member("error").value_or("").rfind("fake device: unplugged", 0), 0u);
}

TEST(RecordingPort, DestroyedWithoutCloseStillEndsTheFile) {
  TempDir dir;
  const std::string path = dir.file("s.wtape");
  {
    auto fake_owner = std::make_unique<FakePort>();
    fake_owner->incoming = {"q"};
    auto port = detail::record_port(std::move(fake_owner), config_for(path));
    EXPECT_EQ(port->read_exactly(1), "q");
  }
  EXPECT_EQ(kinds_of(read_all(path)), (std::vector<std::string>{"open", "rx", "close"}));
}

TEST(RecordingPort, LoopbackWithLogOption) {
  TempDir dir;
  const std::string path = dir.file("loop.wtape");
  {
    auto port = open_port("type=loopback,timeout=2,log=" + path + ",meta_robot=r2,flush_ms=20");
    ASSERT_EQ(port->write_all("ping"), 4u);
    EXPECT_EQ(port->read_exactly(4), "ping");
    char byte;
    EXPECT_EQ(port->read(&byte, 1, 0ms), 0u);
    port->close();
  }
  SessionReader reader(path);
  EXPECT_EQ(reader.header().port_type, "loopback");
  EXPECT_NE(reader.header().port_options.find("type=loopback"), std::string::npos);
  EXPECT_EQ(reader.header().user_metadata.at("robot"), "r2");
  std::string rx;
  std::string tx;
  Record record;
  std::vector<std::string> kinds;
  while (reader.next(record)) {
    if (record.kind == RecordKind::rx) rx += record.data;
    else if (record.kind == RecordKind::tx) tx += record.data;
    kinds.emplace_back(to_string(record.kind));
  }
  EXPECT_EQ(tx, "ping");
  EXPECT_EQ(rx, "ping");
  EXPECT_EQ(kinds.front(), "open");
  EXPECT_EQ(kinds.back(), "close");
}

namespace {

struct ChildResult {
  std::string report;  // what the child wrote to the pipe
  std::string errors;  // its stderr
};

// Runs `body` in a child with a 4 KiB file-size limit (SIGXFSZ ignored, so
// writes fail with EFBIG), returning what it reports.
template <typename Body>
ChildResult run_limited(Body body) {
  int report_pipe[2];
  int error_pipe[2];
  if (::pipe(report_pipe) != 0 || ::pipe(error_pipe) != 0) throw std::runtime_error("pipe");
  const pid_t child = ::fork();
  if (child == 0) {
    ::close(report_pipe[0]);
    ::close(error_pipe[0]);
    ::dup2(error_pipe[1], 2);
    ::signal(SIGXFSZ, SIG_IGN);
    rlimit limit{};
    limit.rlim_cur = limit.rlim_max = 4096;
    ::setrlimit(RLIMIT_FSIZE, &limit);
    std::string report;
    try {
      report = body();
    } catch (const std::exception& e) {
      report = std::string("unexpected: ") + e.what();
    }
    (void)!::write(report_pipe[1], report.data(), report.size());
    ::_exit(0);
  }
  ::close(report_pipe[1]);
  ::close(error_pipe[1]);
  auto drain = [](int fd) {
    std::string text;
    char chunk[512];
    ssize_t n;
    while ((n = ::read(fd, chunk, sizeof chunk)) > 0) text.append(chunk, n);
    ::close(fd);
    return text;
  };
  ChildResult result;
  result.report = drain(report_pipe[0]);
  result.errors = drain(error_pipe[0]);
  int status = 0;
  ::waitpid(child, &status, 0);
  return result;
}

}  // namespace

TEST(RecordingPort, RecordingFailureIsRaisedOnceThenThePortGoesOn) {
  TempDir dir;
  const std::string path = dir.file("full.wtape");
  const ChildResult result = run_limited([&] {
    auto port = open_port("type=loopback,timeout=1,flush_ms=1,log=" + path);
    const std::string chunk(200, 'x');
    int raised = 0;
    std::string first_error;
    // Until the background flush has hit the limit and the failure was
    // raised, then some more rounds that must not raise again.
    const auto deadline = std::chrono::steady_clock::now() + 10s;
    int rounds_after = 0;
    while (rounds_after < 50 && std::chrono::steady_clock::now() < deadline) {
      if (raised > 0) ++rounds_after;
      try {
        port->write_all(chunk);
        if (port->read_exactly(chunk.size()) != chunk) return std::string("data lost");
        port->flush_input();  // records an event: surfaces background failures
      } catch (const PortError& e) {
        if (++raised == 1) first_error = e.what();
      }
    }
    // The port still works after the failure (dropping what a raised call
    // left unread).
    port->flush_input();
    port->write_all("after");
    const std::string back = port->read_exactly(5);
    return std::to_string(raised) + "|" + back + "|" + first_error;
  });
  ASSERT_EQ(result.report.rfind("1|after|", 0), 0u) << result.report << result.errors;
  EXPECT_NE(result.report.find(path), std::string::npos) << result.report;
  EXPECT_NE(result.report.find("File too large"), std::string::npos) << result.report;
  SessionReader reader(path);
  Record record;
  int records = 0;
  while (reader.next(record)) ++records;
  EXPECT_FALSE(reader.damage());
  EXPECT_GT(records, 5);
}

TEST(RecordingPort, RecordingFailureWithWarnPrintsOnceAndNeverRaises) {
  TempDir dir;
  const std::string path = dir.file("full.wtape");
  const ChildResult result = run_limited([&] {
    auto port = open_port("type=loopback,timeout=1,flush_ms=1,log_errors=warn,log=" + path);
    const std::string chunk(200, 'y');
    // Long enough for the background flush to hit the limit mid-session.
    const auto until = std::chrono::steady_clock::now() + 200ms;
    while (std::chrono::steady_clock::now() < until) {
      port->write_all(chunk);
      if (port->read_exactly(chunk.size()) != chunk) return std::string("data lost");
      port->flush_input();
    }
    const bool raised_at_close = [&] {
      try {
        port->close();
        return false;
      } catch (const PortError&) {
        return true;
      }
    }();
    return std::string(raised_at_close ? "raised" : "ok");
  });
  EXPECT_EQ(result.report, "ok") << result.errors;
  const auto first = result.errors.find("recording stopped");
  ASSERT_NE(first, std::string::npos) << result.errors;
  EXPECT_EQ(result.errors.find("recording stopped", first + 1), std::string::npos)
      << result.errors;
  EXPECT_NE(result.errors.find(path), std::string::npos) << result.errors;
  SessionReader reader(path);
  Record record;
  while (reader.next(record)) {
  }
  EXPECT_FALSE(reader.damage());
}

// flexiport's logging port types: the named transport wrapped in a recorder,
// `file` as `log`. flexiport's LogWriter crashed when an option key sorted
// after `file`; here keys come in any order.
TEST(FlexiportLoggingTypes, TcplogWithKeysAfterFileRecordsTheSession) {
  TempDir dir;
  const std::string path = dir.file("tcp.wtape");
  const int listener = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  ASSERT_GE(listener, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::bind(listener, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
  ASSERT_EQ(::listen(listener, 1), 0);
  socklen_t length = sizeof address;
  ASSERT_EQ(::getsockname(listener, reinterpret_cast<sockaddr*>(&address), &length), 0);
  const int port_number = ntohs(address.sin_port);

  auto port = open_port("type=tcplog,file=" + path + ",host=127.0.0.1,port=" +
                        std::to_string(port_number) + ",timeout=5,nodelay=1");
  const int peer = ::accept(listener, nullptr, nullptr);
  ASSERT_GE(peer, 0);
  EXPECT_EQ(port->type(), "tcp");
  ASSERT_EQ(port->write_all("VV\n"), 3u);
  char request[3];
  ASSERT_EQ(::recv(peer, request, sizeof request, MSG_WAITALL), 3);
  ASSERT_EQ(::send(peer, "VV\n00P\n\n", 8, 0), 8);
  EXPECT_EQ(port->read_until("\n\n"), "VV\n00P\n\n");
  port->close();
  ::close(peer);
  ::close(listener);

  SessionReader reader(path);
  EXPECT_EQ(reader.header().port_type, "tcp");
  std::string tx;
  std::string rx;
  Record record;
  while (reader.next(record)) {
    if (record.kind == RecordKind::tx) tx += record.data;
    if (record.kind == RecordKind::rx) rx += record.data;
  }
  EXPECT_FALSE(reader.damage());
  EXPECT_EQ(tx, "VV\n");
  EXPECT_EQ(rx, "VV\n00P\n\n");
}

TEST(FlexiportLoggingTypes, SeriallogOnAPseudoTerminalRecordsSettings) {
  TempDir dir;
  const std::string path = dir.file("serial.wtape");
  const int master = ::posix_openpt(O_RDWR | O_NOCTTY | O_CLOEXEC);
  ASSERT_GE(master, 0);
  ASSERT_EQ(::grantpt(master), 0);
  ASSERT_EQ(::unlockpt(master), 0);
  const std::string device = ::ptsname(master);
  std::unique_ptr<Port> port;
  try {
    port = open_port("type=seriallog,device=" + device + ",file=" + path +
                     ",baud=115200,timeout=5");
  } catch (const PortError& e) {
    ::close(master);
    GTEST_SKIP() << "a pty cannot be opened as a serial port here: " << e.what();
  }
  port->set_baud(57600);
  ASSERT_EQ(port->write_all("ping"), 4u);
  char got[4];
  std::size_t have = 0;
  while (have < 4) {
    const ssize_t n = ::read(master, got + have, 4 - have);
    ASSERT_GT(n, 0);
    have += static_cast<std::size_t>(n);
  }
  port->close();
  ::close(master);
  SessionReader reader(path);
  EXPECT_EQ(reader.header().port_type, "serial");
  std::vector<std::string> kinds;
  Record record;
  std::string settings;
  while (reader.next(record)) {
    kinds.emplace_back(to_string(record.kind));
    if (record.kind == RecordKind::settings) settings = record.data;
  }
  EXPECT_EQ(kinds, (std::vector<std::string>{"open", "settings", "tx", "close"}));
  EXPECT_EQ(settings, "{\"baud\":57600}");
}

TEST(RecordingPort, CloseFromAnotherThreadEndsTheSessionCleanly) {
  TempDir dir;
  const std::string path = dir.file("closed.wtape");
  auto port = open_port("type=loopback,log=" + path);
  std::promise<std::string> outcome;
  std::thread reader([&] {
    try {
      char byte;
      port->read(&byte, 1);  // blocks: nothing was written
      outcome.set_value("returned");
    } catch (const PortClosed&) {
      outcome.set_value("closed");
    } catch (const std::exception& e) {
      outcome.set_value(std::string("other: ") + e.what());
    }
  });
  port->close();
  auto result = outcome.get_future();
  ASSERT_EQ(result.wait_for(10s), std::future_status::ready);
  EXPECT_EQ(result.get(), "closed");
  reader.join();
  EXPECT_EQ(kinds_of(read_all(path)), (std::vector<std::string>{"open", "close"}));
}

namespace {

std::vector<std::string> rx_payloads(const std::string& path) {
  std::vector<std::string> payloads;
  for (const Record& record : read_all(path)) {
    if (record.kind == RecordKind::rx) payloads.push_back(record.data);
  }
  return payloads;
}

}  // namespace

TEST(RecordingPort, ACompoundReadIsOneRxRecordOverLoopback) {
  TempDir dir;
  const std::string path = dir.file("lines.wtape");
  {
    auto port = open_port("type=loopback,timeout=2,log=" + path);
    ASSERT_EQ(port->write_all("alpha\nbeta\n"), 11u);
    EXPECT_EQ(port->read_line(), "alpha\n");
    EXPECT_EQ(port->read_until("\n"), "beta\n");
    port->write_all("gam");
    port->write_all("ma");
    EXPECT_EQ(port->read_exactly(5), "gamma");
    port->write_all("noise;rest");
    EXPECT_TRUE(port->skip_until(";"));
    EXPECT_EQ(port->skip(4), 4u);
    port->close();
  }
  EXPECT_EQ(rx_payloads(path),
            (std::vector<std::string>{"alpha\n", "beta\n", "gamma", "noise;", "rest"}));
}

TEST(RecordingPort, ACompoundReadIsOneRxRecordOverReplay) {
  TempDir dir;
  const std::string session = dir.file("device.wtape");
  {
    SessionHeader header;
    header.port_type = "serial";
    SessionWriter writer(session, header);
    writer.write(RecordKind::rx, 0, "al");
    writer.write(RecordKind::rx, 1, "pha\nbe");
    writer.write(RecordKind::rx, 2, "ta\n");
    writer.close();
  }
  const std::string path = dir.file("driver.wtape");
  {
    auto port = open_port("type=replay,timing=none,timeout=2,file=" + session +
                          ",log=" + path);
    EXPECT_EQ(port->read_line(), "alpha\n");
    EXPECT_EQ(port->read_line(), "beta\n");
    port->close();
  }
  EXPECT_EQ(rx_payloads(path), (std::vector<std::string>{"alpha\n", "beta\n"}));
}

TEST(RecordingPort, ACompoundReadAdvancedInStepsIsOneRxRecord) {
  TempDir dir;
  const std::string path = dir.file("s.wtape");
  auto fake_owner = std::make_unique<FakePort>();
  FakePort& fake = *fake_owner;
  auto port = detail::record_port(std::move(fake_owner), config_for(path));
  fake.incoming = {"ab"};
  CompoundRead read = CompoundRead::until(*port, "\r\n");
  EXPECT_FALSE(read.advance(Deadline()));  // the fake has no more: a timeout
  fake.incoming = {"c\r", "\nnext"};
  EXPECT_TRUE(read.advance(Deadline()));
  EXPECT_EQ(read.finish(), "abc\r\n");
  port->close();
  EXPECT_EQ(rx_payloads(path), (std::vector<std::string>{"abc\r\n"}));
}

TEST(RecordingPort, ACompoundReadGivenUpStillRecordsWhatItConsumed) {
  TempDir dir;
  const std::string path = dir.file("s.wtape");
  auto fake_owner = std::make_unique<FakePort>();
  FakePort& fake = *fake_owner;
  auto port = detail::record_port(std::move(fake_owner), config_for(path));
  fake.incoming = {"partial"};
  {
    CompoundRead read = CompoundRead::exactly(*port, 100);
    EXPECT_FALSE(read.advance(Deadline()));
  }  // destroyed unfinished (in Python: Ctrl-C)
  port->close();
  EXPECT_EQ(rx_payloads(path), (std::vector<std::string>{"partial"}));
}

TEST(RecordingPort, BytesOfACompoundReadComeBeforeTheDeviceLoss) {
  TempDir dir;
  const std::string path = dir.file("s.wtape");
  auto fake_owner = std::make_unique<FakePort>();
  FakePort& fake = *fake_owner;
  auto port = detail::record_port(std::move(fake_owner), config_for(path));
  fake.incoming = {"ab"};
  CompoundRead read = CompoundRead::exactly(*port, 4);
  EXPECT_FALSE(read.advance(Deadline()));
  fake.lost = true;
  EXPECT_THROW(read.advance(Deadline()), PortClosed);
  read.finish();
  port->close();
  const auto records = read_all(path);
  EXPECT_EQ(kinds_of(records),
            (std::vector<std::string>{"open", "rx", "device_lost", "close"}));
  EXPECT_EQ(records[1].data, "ab");
}
