// Helpers shared by the tests of src/replay/: records made in a line, a
// replay opened on records in memory with the keys a test gives, and a
// session written to a file. Header-only, so that each test program takes
// what it uses.
#pragma once

#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "replay/replay_config.hpp"
#include "replay/replay_port.hpp"
#include "session/record_source.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/options.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

namespace wiretape::test::replay_support {

constexpr std::uint64_t ms(std::uint64_t n) { return n * 1'000'000; }

inline Record rx(std::uint64_t t, std::string data) {
  return {t, RecordKind::rx, std::move(data)};
}
inline Record tx(std::uint64_t t, std::string data) {
  return {t, RecordKind::tx, std::move(data)};
}
inline Record event(std::uint64_t t, RecordKind kind) { return {t, kind, ""}; }

// The replay keys `keys` parsed as open_port parses them.
inline detail::ReplayConfig config_from(const std::string& keys) {
  Options options = Options::parse("file=synthetic.wtape," + keys);
  detail::ReplayConfig config = detail::take_replay_config(options);
  options.finish("replay");
  return config;
}

// A replay of `records` (held in memory) with `keys`.
inline std::unique_ptr<Port> replay(std::vector<Record> records,
                                    const std::string& keys = "timing=none",
                                    bool datagrams = false) {
  detail::ReplayConfig config = config_from(keys);
  config.datagrams = datagrams;
  auto port = detail::open_replay_session(
      config, detail::vector_source_factory(std::move(records)));
  port->set_timeout(kEventDeadline);
  return port;
}

inline std::string read_some(Port& port, std::size_t size = 4096,
                             Timeout timeout = std::chrono::seconds(5)) {
  std::string buffer(size, '\0');
  buffer.resize(port.read(buffer.data(), size, timeout));
  return buffer;
}

inline std::string write_session(const TempDir& dir, const std::vector<Record>& records,
                                 const std::string& port_type = "serial") {
  const std::string path = dir.file("session.wtape");
  SessionHeader header;
  header.port_type = port_type;
  SessionWriter writer(path, header);
  for (const Record& record : records) writer.write(record);
  writer.close();
  return path;
}

// A typical command/response session with a greeting.
inline std::vector<Record> hello_session() {
  return {rx(ms(1), "HELLO\n"), tx(ms(10), "PING\n"), rx(ms(20), "PONG\n"),
          tx(ms(30), "TIME\n"), rx(ms(40), "12:00\n"), rx(ms(45), "OK\n")};
}

// Upper time bounds mean nothing under ThreadSanitizer's slowdown.
inline bool under_thread_sanitizer() {
#if defined(__SANITIZE_THREAD__)
  return true;
#else
  return std::getenv("WIRETAPE_TSAN") != nullptr;
#endif
}

}  // namespace wiretape::test::replay_support
