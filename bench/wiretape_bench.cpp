// Google Benchmark micro-benchmarks of the hot paths: timing=none replay in
// 64 KiB reads, 64 KiB TCP writes with and without recording, and a 64-byte
// ping-pong with and without recording. bench/run.py turns the ratios that
// matter into results.json with bench_tool; these give the per-call view.
#include <benchmark/benchmark.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <stdexcept>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "bench_support.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

namespace wb = wiretape::bench;

namespace {

std::string scratch(const std::string& stem) {
  const char* dir = std::getenv("WIRETAPE_BENCH_DIR");
  return std::string(dir ? dir : "/tmp") + "/" + stem + "-" + std::to_string(::getpid()) + ".wtape";
}

void BM_ReplayTimingNone(benchmark::State& state) {
  const auto bytes = static_cast<std::uint64_t>(state.range(0)) << 20;
  const std::string path = scratch("wiretape-gbench-replay");
  wb::write_rx_session(path, bytes);
  std::vector<char> buffer(64 * 1024);
  for (auto _ : state) {
    auto port = wiretape::open_port("type=replay,file=" + path + ",timing=none,unused=ignore,timeout=10");
    std::uint64_t total = 0;
    while (total < bytes) {
      const std::size_t got = port->read(buffer.data(), buffer.size());
      if (got == 0) {
        state.SkipWithError("replay read timed out");
        break;
      }
      total += got;
    }
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * bytes));
  std::remove(path.c_str());
}
BENCHMARK(BM_ReplayTimingNone)->Arg(64)->Unit(benchmark::kMillisecond)->UseRealTime();

// Where replay time goes: the checksum of every record, and reading the
// records without any replay logic.
void BM_Crc32c(benchmark::State& state) {
  const std::string data(static_cast<std::size_t>(state.range(0)), 'c');
  std::uint32_t crc = 0;
  for (auto _ : state) {
    crc = wiretape::crc32c(data.data(), data.size(), crc);
    benchmark::DoNotOptimize(crc);
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * data.size()));
}
BENCHMARK(BM_Crc32c)->Arg(4096)->Arg(65536);

void BM_SessionReaderScan(benchmark::State& state) {
  const auto bytes = static_cast<std::uint64_t>(state.range(0)) << 20;
  const std::string path = scratch("wiretape-gbench-scan");
  wb::write_rx_session(path, bytes);
  for (auto _ : state) {
    wiretape::SessionReader reader(path);
    wiretape::Record record;
    std::uint64_t total = 0;
    while (reader.next(record)) total += record.data.size();
    benchmark::DoNotOptimize(total);
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * bytes));
  std::remove(path.c_str());
}
BENCHMARK(BM_SessionReaderScan)->Arg(64)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_SessionWriter4KiB(benchmark::State& state) {
  const std::string path = scratch("wiretape-gbench-writer");
  wiretape::SessionWriter writer(path, wiretape::SessionHeader{});
  const std::string payload(4096, 'w');
  std::uint64_t t_ns = 0;
  for (auto _ : state) {
    writer.write(wiretape::RecordKind::rx, t_ns += 1000, payload);
  }
  writer.close();
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * payload.size()));
  std::remove(path.c_str());
}
BENCHMARK(BM_SessionWriter4KiB)->UseRealTime();

void BM_TcpWrite64KiB(benchmark::State& state) {
  const bool recorded = state.range(0) != 0;
  const std::string log_path = scratch("wiretape-gbench-record");
  wb::TcpSink sink;
  auto port = wiretape::open_port(sink.client_options() + (recorded ? ",log=" + log_path : ""));
  std::vector<char> chunk(64 * 1024, 'x');
  for (auto _ : state) {
    port->write_all(chunk.data(), chunk.size());
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * chunk.size()));
  port->close();
  std::remove(log_path.c_str());
}
BENCHMARK(BM_TcpWrite64KiB)->ArgName("recorded")->Arg(0)->Arg(1)->UseRealTime();

void BM_PingPong64(benchmark::State& state) {
  const bool recorded = state.range(0) != 0;
  const std::string log_path = scratch("wiretape-gbench-pingpong");
  wb::TcpEcho echo;
  auto port = wiretape::open_port(echo.client_options() + (recorded ? ",log=" + log_path : ""));
  const std::string message(64, 'p');
  for (auto _ : state) {
    port->write_all(message);
    const std::string answer = port->read_exactly(message.size());
    if (answer.size() != message.size()) {
      state.SkipWithError("echo timed out");
      break;
    }
  }
  port->close();
  std::remove(log_path.c_str());
}
BENCHMARK(BM_PingPong64)->ArgName("recorded")->Arg(0)->Arg(1)->UseRealTime()->Unit(benchmark::kMicrosecond);

// --- match=request against match=sequence (DESIGN.md section 13) -------------
//
// One session of `exchanges` request/response pairs replayed with
// timing=none by a client that sends each request and reads its response,
// once in each mode; the counters give both times and their ratio (the
// design asks request <= 1.5 x sequence). BM_RequestModePeakRss replays a
// 1 GiB session (100,000 exchanges, 10 KiB responses) in request mode in a
// child process and reports its peak RSS (VmHWM, reset at the child's start;
// the design asks <= 64 MiB).

std::string exchange_request(std::size_t i) {
  char text[32];
  std::snprintf(text, sizeof text, "GET %08zu\n", i);
  return text;
}

void write_exchange_session(const std::string& path, std::size_t exchanges,
                            std::size_t response_bytes) {
  wiretape::SessionHeader header;
  header.port_type = "serial";
  header.port_options = "type=serial,device=/dev/bench";
  wiretape::SessionWriter writer(path, header);
  std::string response(response_bytes, 'r');
  response.back() = '\n';
  std::uint64_t t_ns = 1000;
  for (std::size_t i = 0; i < exchanges; ++i) {
    writer.write(wiretape::RecordKind::tx, t_ns += 1000, exchange_request(i));
    std::snprintf(response.data(), response.size(), "%08zu", i);
    writer.write(wiretape::RecordKind::rx, t_ns += 1000, response);
  }
  writer.close();
}

// Seconds to replay the session once as its recording client did.
double replay_exchanges(const std::string& path, const std::string& match,
                        std::size_t exchanges, std::size_t response_bytes) {
  const auto start = std::chrono::steady_clock::now();
  auto port = wiretape::open_port("type=replay,file=" + path + ",match=" + match +
                                  ",timing=none,unused=ignore,timeout=10");
  for (std::size_t i = 0; i < exchanges; ++i) {
    port->write_all(exchange_request(i));
    if (port->read_exactly(response_bytes).size() != response_bytes) {
      throw std::runtime_error("replay read timed out at exchange " + std::to_string(i));
    }
  }
  port->close();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void BM_RequestVsSequence(benchmark::State& state) {
  const auto exchanges = static_cast<std::size_t>(state.range(0));
  constexpr std::size_t response_bytes = 32;
  const std::string path = scratch("wiretape-gbench-exchanges");
  write_exchange_session(path, exchanges, response_bytes);
  double sequence_s = 0;
  double request_s = 0;
  for (auto _ : state) {
    sequence_s += replay_exchanges(path, "sequence", exchanges, response_bytes);
    request_s += replay_exchanges(path, "request", exchanges, response_bytes);
  }
  const auto runs = static_cast<double>(state.iterations());
  state.counters["sequence_s"] = sequence_s / runs;
  state.counters["request_s"] = request_s / runs;
  state.counters["request_over_sequence"] = request_s / sequence_s;
  std::remove(path.c_str());
}
BENCHMARK(BM_RequestVsSequence)->Arg(100000)->Iterations(3)->Unit(benchmark::kSecond)->UseRealTime();

// VmHWM of this process, in KiB.
long peak_rss_kib() {
  std::FILE* status = std::fopen("/proc/self/status", "r");
  if (status == nullptr) return -1;
  char line[256];
  long kib = -1;
  while (std::fgets(line, sizeof line, status) != nullptr) {
    if (std::sscanf(line, "VmHWM: %ld kB", &kib) == 1) break;
  }
  std::fclose(status);
  return kib;
}

void BM_RequestModePeakRss(benchmark::State& state) {
  const auto exchanges = static_cast<std::size_t>(state.range(0));
  constexpr std::size_t response_bytes = 10 * 1024;
  const std::string path = scratch("wiretape-gbench-1gib");
  write_exchange_session(path, exchanges, response_bytes);
  long child_peak_kib = -1;
  double seconds = 0;
  for (auto _ : state) {
    int report[2];
    if (::pipe(report) != 0) {
      state.SkipWithError("pipe failed");
      break;
    }
    const pid_t child = ::fork();
    if (child == 0) {
      ::close(report[0]);
      // The peak from here on: what the replay itself takes.
      if (std::FILE* clear = std::fopen("/proc/self/clear_refs", "w")) {
        std::fputs("5", clear);
        std::fclose(clear);
      }
      long result[2] = {-1, 0};
      try {
        const double taken = replay_exchanges(path, "request", exchanges, response_bytes);
        result[0] = peak_rss_kib();
        result[1] = static_cast<long>(taken * 1000);
      } catch (...) {
      }
      (void)!::write(report[1], result, sizeof result);
      ::_exit(0);
    }
    ::close(report[1]);
    long result[2] = {-1, 0};
    (void)!::read(report[0], result, sizeof result);
    ::close(report[0]);
    int status = 0;
    ::waitpid(child, &status, 0);
    if (result[0] < 0) {
      state.SkipWithError("the replay in the child failed");
      break;
    }
    child_peak_kib = std::max(child_peak_kib, result[0]);
    seconds += static_cast<double>(result[1]) / 1000;
  }
  state.counters["session_mib"] =
      static_cast<double>(exchanges * (response_bytes + 13)) / (1 << 20);
  state.counters["peak_rss_mib"] = static_cast<double>(child_peak_kib) / 1024;
  state.counters["replay_s"] = seconds / static_cast<double>(state.iterations());
  std::remove(path.c_str());
}
BENCHMARK(BM_RequestModePeakRss)->Arg(100000)->Iterations(1)->Unit(benchmark::kSecond)->UseRealTime();

// profile=modbus-tcp with a client that polls in another order (each pair
// of polls swapped) and with its own transaction ids, against match=sequence
// replaying the recorded order without a profile (the design asks <= 2x).
std::string modbus_poll(std::size_t i, std::uint16_t tid) {
  const auto address = static_cast<std::uint16_t>(i % 65536);
  const auto count = static_cast<std::uint16_t>(1 + i / 65536);
  const char frame[12] = {static_cast<char>(tid >> 8), static_cast<char>(tid & 0xFF), 0, 0, 0, 6, 1, 3,
                          static_cast<char>(address >> 8), static_cast<char>(address & 0xFF),
                          static_cast<char>(count >> 8), static_cast<char>(count & 0xFF)};
  return std::string(frame, sizeof frame);
}

std::string modbus_reply(std::size_t i, std::uint16_t tid) {
  const char frame[11] = {static_cast<char>(tid >> 8), static_cast<char>(tid & 0xFF), 0, 0, 0, 5, 1, 3, 2,
                          static_cast<char>((i >> 8) & 0xFF), static_cast<char>(i & 0xFF)};
  return std::string(frame, sizeof frame);
}

double replay_modbus(const std::string& path, const std::string& keys, std::size_t polls,
                     bool reorder) {
  const auto start = std::chrono::steady_clock::now();
  auto port = wiretape::open_port("type=replay,file=" + path + "," + keys +
                                  ",timing=none,unused=ignore,timeout=10");
  for (std::size_t k = 0; k < polls; ++k) {
    const std::size_t i = reorder ? (k ^ 1) % polls : k;
    const auto tid = static_cast<std::uint16_t>(reorder ? k + 7 : i);
    port->write_all(modbus_poll(i, tid));
    if (port->read_exactly(11) != modbus_reply(i, tid)) {
      throw std::runtime_error("wrong Modbus reply at poll " + std::to_string(k));
    }
  }
  port->close();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void BM_ModbusTcpReordering(benchmark::State& state) {
  const auto polls = static_cast<std::size_t>(state.range(0));
  const std::string path = scratch("wiretape-gbench-modbus");
  {
    wiretape::SessionHeader header;
    header.port_type = "tcp";
    header.port_options = "type=tcp,host=127.0.0.1,port=502";
    wiretape::SessionWriter writer(path, header);
    std::uint64_t t_ns = 1000;
    for (std::size_t i = 0; i < polls; ++i) {
      const auto tid = static_cast<std::uint16_t>(i);
      writer.write(wiretape::RecordKind::tx, t_ns += 1000, modbus_poll(i, tid));
      writer.write(wiretape::RecordKind::rx, t_ns += 1000, modbus_reply(i, tid));
    }
    writer.close();
  }
  double sequence_s = 0;
  double profile_s = 0;
  for (auto _ : state) {
    sequence_s += replay_modbus(path, "match=sequence", polls, false);
    profile_s += replay_modbus(path, "match=request,profile=modbus-tcp", polls, true);
  }
  const auto runs = static_cast<double>(state.iterations());
  state.counters["sequence_s"] = sequence_s / runs;
  state.counters["modbus_reordered_s"] = profile_s / runs;
  state.counters["modbus_over_sequence"] = profile_s / sequence_s;
  std::remove(path.c_str());
}
BENCHMARK(BM_ModbusTcpReordering)->Arg(100000)->Iterations(3)->Unit(benchmark::kSecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
