// Port's compound calls (port.cpp) over a scripted transport: what they ask
// of the primitives and what they return on timeouts.
#include <gtest/gtest.h>

#include <chrono>
#include <deque>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"

using namespace std::chrono_literals;
using wiretape::Deadline;
using wiretape::Port;

namespace {

// Serves scripted chunks; an empty chunk is a timeout. Writes accept at most
// `write_limit` bytes per call and time out once `write_budget` is spent.
class ScriptedPort final : public Port {
 public:
  std::deque<std::string> chunks;
  std::vector<Deadline> read_deadlines;
  std::string written;
  std::size_t write_limit = 1 << 20;
  std::size_t write_budget = 1 << 20;
  int read_calls = 0;
  // Lets a compound read look ahead, a chunk at a time (as a replay does).
  bool peeks = false;

  std::size_t available() override {
    return chunks.empty() ? 0 : chunks.front().size();
  }
  void flush_input() override { chunks.clear(); }
  void flush_output() override {}
  void drain() override {}
  void close() override { open_ = false; }
  bool is_open() const override { return open_; }
  std::string description() const override { return "scripted"; }
  std::string type() const override { return "scripted"; }
  int native_handle() const override { return -1; }

 protected:
  std::size_t read_some(void* buffer, std::size_t size, Deadline deadline) override {
    ++read_calls;
    read_deadlines.push_back(deadline);
    if (chunks.empty()) return 0;
    std::string& chunk = chunks.front();
    if (chunk.empty()) {
      chunks.pop_front();
      return 0;
    }
    const std::size_t n = std::min(size, chunk.size());
    chunk.copy(static_cast<char*>(buffer), n);
    chunk.erase(0, n);
    if (chunk.empty()) chunks.pop_front();
    return n;
  }
  std::optional<std::size_t> peek_some(void* buffer, std::size_t size, Deadline) override {
    if (!peeks) return std::nullopt;
    if (chunks.empty()) return 0;
    const std::size_t n = std::min(size, chunks.front().size());
    chunks.front().copy(static_cast<char*>(buffer), n);
    return n;
  }
  std::size_t write_some(const void* data, std::size_t size, Deadline) override {
    const std::size_t n = std::min({size, write_limit, write_budget});
    written.append(static_cast<const char*>(data), n);
    write_budget -= n;
    return n;
  }
  bool wait_readable_until(Deadline) override { return !chunks.empty(); }

 private:
  bool open_ = true;
};

}  // namespace

TEST(PortApi, ReadReturnsWhatIsThereAndZeroOnTimeout) {
  ScriptedPort port;
  port.chunks = {"abc", ""};
  char buffer[10];
  EXPECT_EQ(port.read(buffer, sizeof buffer), 3u);
  EXPECT_EQ(port.read(buffer, sizeof buffer), 0u) << "timeout is not an error";
  EXPECT_EQ(port.read(buffer, 0), 0u);
}

TEST(PortApi, PortTimeoutAppliesUnlessACallGivesItsOwn) {
  ScriptedPort port;
  char byte;
  port.read(&byte, 1);
  EXPECT_FALSE(port.read_deadlines.back().has_value()) << "default blocks";
  port.set_timeout(0s);
  const auto before = std::chrono::steady_clock::now();
  port.read(&byte, 1);
  ASSERT_TRUE(port.read_deadlines.back().has_value());
  EXPECT_LE(*port.read_deadlines.back(), std::chrono::steady_clock::now());
  EXPECT_GE(*port.read_deadlines.back(), before);
  port.read(&byte, 1, 10s);
  EXPECT_GT(*port.read_deadlines.back(), std::chrono::steady_clock::now() + 5s);
  port.read(&byte, 1, wiretape::forever);
  EXPECT_FALSE(port.read_deadlines.back().has_value());
}

TEST(PortApi, ReadExactlyCollectsChunksAndReturnsPartialOnTimeout) {
  ScriptedPort port;
  port.chunks = {"ab", "cd", "ef"};
  EXPECT_EQ(port.read_exactly(5), "abcde");
  port.chunks.push_back("xy");
  port.chunks.push_back("");
  EXPECT_EQ(port.read_exactly(5), "fxy") << "partial data, no throw";
}

TEST(PortApi, CompoundReadsShareOneDeadline) {
  ScriptedPort port;
  port.chunks = {"a", "b", "c"};
  port.read_exactly(3, 1s);
  ASSERT_EQ(port.read_deadlines.size(), 3u);
  EXPECT_EQ(port.read_deadlines[0], port.read_deadlines[2]);
}

TEST(PortApi, ReadUntilStopsAtTheDelimiterMaxOrTimeout) {
  ScriptedPort port;
  port.chunks = {"one\r\ntwo\r\nthree"};
  EXPECT_EQ(port.read_until("\r\n"), "one\r\n");
  EXPECT_EQ(port.read_until("\r\n", 2), "tw");
  EXPECT_EQ(port.read_until("\r\n"), "o\r\n");
  port.chunks.push_back("");
  EXPECT_EQ(port.read_until("\r\n"), "three") << "partial on timeout";
  port.chunks = {"line\nrest"};
  EXPECT_EQ(port.read_line(), "line\n");
  EXPECT_EQ(port.available(), 4u) << "nothing past the delimiter consumed";
}

TEST(PortApi, ReadUntilFindsADelimiterAcrossPeekedChunks) {
  ScriptedPort port;
  port.peeks = true;
  port.chunks = {"ab\r", "\ncd\r", "\n\r\nx", "yyE", "N", "Dzz\r\n"};
  EXPECT_EQ(port.read_until("\r\n"), "ab\r\n");
  EXPECT_EQ(port.read_until("\r\n"), "cd\r\n");
  EXPECT_EQ(port.read_until("\r\n"), "\r\n");
  EXPECT_EQ(port.read_until("END"), "xyyEND");
  EXPECT_EQ(port.read_until("\r\n"), "zz\r\n");
  EXPECT_TRUE(port.chunks.empty()) << "every byte up to a delimiter, none past it";
}

TEST(PortApi, SkipAndSkipUntil) {
  ScriptedPort port;
  port.chunks = {"0123456789"};
  EXPECT_EQ(port.skip(4), 4u);
  EXPECT_EQ(port.read_exactly(2), "45");
  port.chunks = {"junk;", "data"};
  EXPECT_TRUE(port.skip_until(";"));
  EXPECT_EQ(port.read_exactly(4), "data");
  port.chunks = {"no end", ""};
  EXPECT_FALSE(port.skip_until(";"));
  port.chunks = {"abc", ""};
  EXPECT_EQ(port.skip(10), 3u);
}

TEST(PortApi, WriteReturnsWhatWasAcceptedAndWriteAllLoops) {
  ScriptedPort port;
  port.write_limit = 3;
  EXPECT_EQ(port.write("abcdefg"), 3u);
  EXPECT_EQ(port.write_all("abcdefg"), 7u);
  EXPECT_EQ(port.written, "abcabcdefg");
  port.write_budget = 2;
  EXPECT_EQ(port.write_all("xyz"), 2u) << "less than asked only on timeout";
  EXPECT_EQ(port.write("", 0), 0u);
}

TEST(PortApi, AccessModeGuardsReadsAndWrites) {
  ScriptedPort port;
  port.set_access(wiretape::Access::read_only);
  EXPECT_THROW(port.write("x"), wiretape::PortError);
  EXPECT_THROW(port.write_all("x"), wiretape::PortError);
  port.set_access(wiretape::Access::write_only);
  char byte;
  EXPECT_THROW(port.read(&byte, 1), wiretape::PortError);
  EXPECT_THROW(port.read_exactly(1), wiretape::PortError);
  EXPECT_THROW(port.read_until("\n"), wiretape::PortError);
  EXPECT_THROW(port.skip(1), wiretape::PortError);
  try {
    port.read(&byte, 1);
  } catch (const wiretape::PortError& error) {
    EXPECT_EQ(error.code().value(), EBADF);
    EXPECT_NE(std::string(error.what()).find("write-only"), std::string::npos);
  }
}

TEST(PortApi, SerialControlIsUnsupportedWhereThePortHasNone) {
  ScriptedPort port;
  try {
    port.set_baud(9600);
    FAIL();
  } catch (const wiretape::PortError& error) {
    EXPECT_EQ(error.code().value(), ENOTSUP);
    EXPECT_NE(std::string(error.what()).find("set_baud"), std::string::npos);
  }
  EXPECT_THROW(port.serial_settings(), wiretape::PortError);
  EXPECT_THROW(port.cts(), wiretape::PortError);
  EXPECT_THROW(port.send_break(1ms), wiretape::PortError);
}

TEST(PortApi, OneReaderAndOneWriterAtOnce) {
  // A serial port on a pty whose device side echoes: one thread writes
  // while another reads the echo.
  wiretape::test::TempDir dir;
  auto device = wiretape::open_port("type=pty,timeout=10,link=" + dir.path + "/tty");
  auto port = wiretape::open_port("type=serial,timeout=10,device=" + dir.path + "/tty");
  const std::size_t total = 200000;
  std::string message(total, '\0');
  for (std::size_t i = 0; i < total; ++i) message[i] = static_cast<char>('a' + i % 26);
  std::thread echo([&] {
    char buffer[4096];
    std::size_t echoed = 0;
    while (echoed < total) {
      const std::size_t n = device->read(buffer, sizeof buffer);
      if (n == 0) return;
      device->write_all(buffer, n);
      echoed += n;
    }
  });
  std::thread writer([&] {
    for (std::size_t i = 0; i < total; i += 1000) port->write_all(message.data() + i, 1000);
  });
  EXPECT_EQ(port->read_exactly(total), message);
  writer.join();
  echo.join();
}
