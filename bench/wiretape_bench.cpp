// Google Benchmark micro-benchmarks of the hot paths: timing=none replay in
// 64 KiB reads, 64 KiB TCP writes with and without recording, and a 64-byte
// ping-pong with and without recording. bench/run.py turns the ratios that
// matter into results.json with bench_tool; these give the per-call view.
#include <benchmark/benchmark.h>
#include <unistd.h>

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
  wiretape::SessionWriter writer(path, wiretape::SessionWriterOptions{});
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

}  // namespace

BENCHMARK_MAIN();
