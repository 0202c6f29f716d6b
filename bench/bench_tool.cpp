// The measuring tool behind `make bench` (bench/run.py). Each subcommand
// measures one figure in this process and prints one JSON object on stdout:
//
//   make-session FILE BYTES           a session of 4 KiB rx records
//   replay FILE BYTES                 timing=none replay in 64 KiB reads
//   timing RECORDS PERIOD_US          timing=session lateness + naive player
//   record-throughput BYTES ROUNDS    64 KiB TCP writes, recorded vs not
//   record-latency ROUNDTRIPS ROUNDS  64-byte ping-pong, recorded vs not
//   record-rss BYTES FILE             peak RSS while recording BYTES
//   make-exchanges FILE COUNT         COUNT request/response pairs (below)
//   soak SECONDS DIR                  record+replay loop; one JSON line a second
//   make-channels FILE BYTES          4 channels c0..c3 of BYTES each, interleaved
//   replay-c1 FILE BYTES              replay (as above) of channel c1 of that file
//   causal-latency ROUNDS CHANNELS    timing=causal: write on one port -> rx
//                                     released on (CHANNELS=1) the same, (2) another
//
// Errors go to stderr with exit status 1 (run.py reports the figure as
// missing with that message).
#include <dirent.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <iostream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "bench_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

namespace wb = wiretape::bench;
using wb::Clock;

namespace {

std::string temp_path(const std::string& stem) {
  const char* dir = std::getenv("WIRETAPE_BENCH_DIR");
  return std::string(dir ? dir : "/tmp") + "/" + stem + "-" + std::to_string(::getpid()) + ".wtape";
}

// Reads `expected` bytes from a timing=none replay of `path` in 64 KiB calls.
int replay(const std::string& path, std::uint64_t expected, const std::string& extra_keys = "") {
  const auto start = Clock::now();
  auto port = wiretape::open_port("type=replay,file=" + path +
                                  ",timing=none,unused=ignore,timeout=10" + extra_keys);
  std::vector<char> buffer(64 * 1024);
  std::uint64_t total = 0;
  while (total < expected) {
    const std::size_t got = port->read(buffer.data(), buffer.size());
    if (got == 0) {
      throw std::runtime_error("replay: timed out after " + std::to_string(total) +
                               " of " + std::to_string(expected) + " bytes");
    }
    total += got;
  }
  const double seconds = wb::seconds_since(start);
  port->close();
  std::printf("{\"bytes\": %llu, \"seconds\": %.6f, \"MBps\": %.3f, \"peak_rss_MB\": %.2f}\n",
              static_cast<unsigned long long>(total), seconds,
              static_cast<double>(total) / seconds / 1e6, wb::peak_rss_mib());
  return 0;
}

// timing=session: how late each record becomes readable compared with its
// due time (open + recorded time), and the same for a player that sleeps the
// recorded gap after each record (the reference that drifts).
int timing(std::uint64_t records, std::uint64_t period_us) {
  const std::string path = temp_path("wiretape-bench-timing");
  const std::uint64_t period_ns = period_us * 1000;
  constexpr std::size_t record_bytes = 8;
  {
    wiretape::SessionHeader header;
    header.port_type = "serial";
    header.port_options = "type=serial,device=/dev/bench";
    wiretape::SessionWriter writer(path, header);
    writer.write(wiretape::RecordKind::open, 0, "{}");
    for (std::uint64_t i = 0; i < records; ++i) {
      char payload[record_bytes] = {};
      std::memcpy(payload, &i, sizeof i);
      writer.write(wiretape::RecordKind::rx, (i + 1) * period_ns,
                   std::string_view(payload, record_bytes));
    }
    writer.close();
  }
  auto due_offset = [&](std::uint64_t i) { return std::chrono::nanoseconds((i + 1) * period_ns); };

  std::vector<Clock::time_point> available(records);
  const auto open_start = Clock::now();
  auto port = wiretape::open_port("type=replay,file=" + path +
                                  ",timing=session,unused=ignore,timeout=10");
  const auto open_end = Clock::now();
  std::vector<char> buffer(4096);
  std::uint64_t bytes = 0;
  const std::uint64_t expected = records * record_bytes;
  while (bytes < expected) {
    const std::size_t got = port->read(buffer.data(), buffer.size());
    const auto now = Clock::now();
    if (got == 0) throw std::runtime_error("timing: replay read timed out at byte " + std::to_string(bytes));
    // Every record completed by this read became readable no later than now.
    for (std::uint64_t end = bytes + got, b = bytes; b < end; ++b) {
      if ((b + 1) % record_bytes == 0) available[b / record_bytes] = now;
    }
    bytes += got;
  }
  port->close();
  std::remove(path.c_str());

  // The replay takes its t=0 somewhere inside the open_port() call, which
  // this side cannot see. Due times are anchored at the latest instant inside
  // the call at which no record became readable early: the best record counts
  // as on time, so the figures are lateness above the best case. Anchored at
  // the start of the call instead (an upper bound), the median is reported as
  // p50_from_open_start_us.
  auto since_open_start = [&](std::uint64_t i) {
    return std::chrono::duration<double, std::micro>(available[i] - (open_start + due_offset(i))).count();
  };
  const double open_us = std::chrono::duration<double, std::micro>(open_end - open_start).count();
  double anchor_us = open_us;
  for (std::uint64_t i = 0; i < records; ++i) anchor_us = std::min(anchor_us, since_open_start(i));
  anchor_us = std::max(anchor_us, 0.0);
  std::vector<double> lateness_us, lateness_from_open_start_us;
  lateness_us.reserve(records);
  lateness_from_open_start_us.reserve(records);
  for (std::uint64_t i = 0; i < records; ++i) {
    lateness_from_open_start_us.push_back(since_open_start(i));
    lateness_us.push_back(since_open_start(i) - anchor_us);
  }
  const double span_ns = static_cast<double>((records - 1) * period_ns);
  auto drift_pct = [&](const std::vector<Clock::time_point>& times) {
    const double actual = std::chrono::duration<double, std::nano>(times.back() - times.front()).count();
    return (actual - span_ns) / span_ns * 100.0;
  };

  // The naive player: sleep the recorded gap, then deliver; errors add up.
  std::vector<Clock::time_point> naive(records);
  const auto naive_start = Clock::now();
  for (std::uint64_t i = 0; i < records; ++i) {
    std::this_thread::sleep_for(std::chrono::nanoseconds(period_ns));
    naive[i] = Clock::now();
  }
  const double naive_end_late_ms =
      std::chrono::duration<double, std::milli>(naive.back() - (naive_start + due_offset(records - 1))).count();

  // The machine's floor: this thread sleeping until each due time, anchored
  // (no drift), with the default timer slack. A replay cannot beat it by
  // much without asking the kernel for less slack.
  std::vector<double> sleeper_us;
  sleeper_us.reserve(records);
  const auto sleeper_start = Clock::now();
  for (std::uint64_t i = 0; i < records; ++i) {
    const auto due = sleeper_start + due_offset(i);
    std::this_thread::sleep_until(due);
    sleeper_us.push_back(std::chrono::duration<double, std::micro>(Clock::now() - due).count());
  }

  std::printf(
      "{\"sleep_until_p50_us\": %.3f, \"sleep_until_p99_us\": %.3f, "
      "\"records\": %llu, \"period_us\": %llu, \"p50_us\": %.3f, \"p99_us\": %.3f, "
      "\"max_us\": %.3f, \"min_us\": %.3f, \"drift_pct\": %.5f, \"open_us\": %.1f, "
      "\"p50_from_open_start_us\": %.3f, \"anchor_after_open_start_us\": %.1f, "
      "\"naive_drift_pct\": %.4f, \"naive_last_late_ms\": %.3f}\n",
      wb::percentile(sleeper_us, 0.5), wb::percentile(sleeper_us, 0.99),
      static_cast<unsigned long long>(records), static_cast<unsigned long long>(period_us),
      wb::percentile(lateness_us, 0.5), wb::percentile(lateness_us, 0.99),
      wb::percentile(lateness_us, 1.0), wb::percentile(lateness_us, 0.0), drift_pct(available),
      open_us, wb::percentile(lateness_from_open_start_us, 0.5), anchor_us,
      drift_pct(naive), naive_end_late_ms);
  return 0;
}

// CPU time used so far by every thread of this process, seconds.
double process_cpu_seconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  const auto seconds = [](const timeval& t) { return static_cast<double>(t.tv_sec) + static_cast<double>(t.tv_usec) / 1e6; };
  return seconds(usage.ru_utime) + seconds(usage.ru_stime);
}

// Seconds to push `bytes` in 64 KiB writes to a sink over loopback TCP;
// `cpu_seconds` gets the CPU time all threads (sender, sink, recorder) used.
double tcp_push_seconds(std::uint64_t bytes, const std::string& log_path, double* cpu_seconds = nullptr) {
  wb::TcpSink sink;
  std::string options = sink.client_options();
  if (!log_path.empty()) options += ",log=" + log_path;
  std::vector<char> chunk(64 * 1024, 'x');
  const auto start = Clock::now();
  const double cpu_start = process_cpu_seconds();
  {
    auto port = wiretape::open_port(options);
    std::uint64_t sent = 0;
    while (sent < bytes) {
      const std::size_t n = port->write_all(chunk.data(), chunk.size());
      if (n != chunk.size()) throw std::runtime_error("record-throughput: write timed out");
      sent += n;
    }
    port->close();  // the recorder's file is complete once close returns
  }
  const auto deadline = Clock::now() + std::chrono::seconds(60);
  while (sink.received() < bytes) {
    if (Clock::now() > deadline) throw std::runtime_error("record-throughput: sink never got every byte");
    std::this_thread::yield();
  }
  if (cpu_seconds) *cpu_seconds = process_cpu_seconds() - cpu_start;
  return wb::seconds_since(start);
}

int record_throughput(std::uint64_t bytes, std::uint64_t rounds) {
  const std::string log_path = temp_path("wiretape-bench-record");
  std::vector<double> plain, recorded, ratios, plain_cores, recorded_cores;
  for (std::uint64_t r = 0; r < rounds; ++r) {
    // Interleaved, in alternating order: each pair runs under the same
    // conditions, and the ratio is taken per pair, so that the machine's
    // drift from round to round (loopback throughput on a shared VM varies
    // by a factor of two) cancels out.
    double plain_s = 0, recorded_s = 0, plain_cpu = 0, recorded_cpu = 0;
    if (r % 2 == 0) {
      plain_s = tcp_push_seconds(bytes, "", &plain_cpu);
      recorded_s = tcp_push_seconds(bytes, log_path, &recorded_cpu);
    } else {
      recorded_s = tcp_push_seconds(bytes, log_path, &recorded_cpu);
      plain_s = tcp_push_seconds(bytes, "", &plain_cpu);
    }
    plain_cores.push_back(plain_cpu / plain_s);
    recorded_cores.push_back(recorded_cpu / recorded_s);
    std::remove(log_path.c_str());
    plain.push_back(plain_s);
    recorded.push_back(recorded_s);
    ratios.push_back(plain_s / recorded_s);
  }
  const double plain_MBps = static_cast<double>(bytes) / wb::percentile(plain, 0.5) / 1e6;
  const double recorded_MBps = static_cast<double>(bytes) / wb::percentile(recorded, 0.5) / 1e6;
  std::printf("{\"bytes\": %llu, \"rounds\": %llu, \"plain_MBps\": %.2f, \"recorded_MBps\": %.2f, "
              "\"ratio\": %.4f, \"ratio_min\": %.4f, \"ratio_max\": %.4f, "
              "\"plain_cores\": %.2f, \"recorded_cores\": %.2f, \"cores\": %u}\n",
              static_cast<unsigned long long>(bytes), static_cast<unsigned long long>(rounds),
              plain_MBps, recorded_MBps, wb::percentile(ratios, 0.5), wb::percentile(ratios, 0.0),
              wb::percentile(ratios, 1.0), wb::percentile(plain_cores, 0.5),
              wb::percentile(recorded_cores, 0.5), std::thread::hardware_concurrency());
  return 0;
}

void ping_pong(std::uint64_t roundtrips, const std::string& log_path, std::vector<double>& rtts_us) {
  wb::TcpEcho echo;
  std::string options = echo.client_options();
  if (!log_path.empty()) options += ",log=" + log_path;
  auto port = wiretape::open_port(options);
  const std::string message(64, 'p');
  for (std::uint64_t i = 0; i < roundtrips; ++i) {
    const auto start = Clock::now();
    port->write_all(message);
    const std::string answer = port->read_exactly(message.size());
    const auto end = Clock::now();
    if (answer.size() != message.size()) throw std::runtime_error("record-latency: echo timed out");
    rtts_us.push_back(std::chrono::duration<double, std::micro>(end - start).count());
  }
  port->close();
}

int record_latency(std::uint64_t roundtrips, std::uint64_t rounds) {
  const std::string log_path = temp_path("wiretape-bench-latency");
  std::vector<double> plain, recorded;
  for (std::uint64_t r = 0; r < rounds; ++r) {
    ping_pong(roundtrips, "", plain);
    ping_pong(roundtrips, log_path, recorded);
    std::remove(log_path.c_str());
  }
  const double plain_us = wb::percentile(plain, 0.5);
  const double recorded_us = wb::percentile(recorded, 0.5);
  std::printf("{\"roundtrips\": %llu, \"plain_median_us\": %.3f, \"recorded_median_us\": %.3f, "
              "\"plain_p99_us\": %.3f, \"recorded_p99_us\": %.3f, \"ratio\": %.4f}\n",
              static_cast<unsigned long long>(roundtrips * rounds), plain_us, recorded_us,
              wb::percentile(plain, 0.99), wb::percentile(recorded, 0.99), recorded_us / plain_us);
  return 0;
}

int record_rss(std::uint64_t bytes, const std::string& path) {
  const double seconds = tcp_push_seconds(bytes, path);
  struct stat info {};
  const bool exists = ::stat(path.c_str(), &info) == 0;
  std::printf("{\"bytes\": %llu, \"seconds\": %.3f, \"file_bytes\": %lld, \"peak_rss_MB\": %.2f}\n",
              static_cast<unsigned long long>(bytes), seconds,
              exists ? static_cast<long long>(info.st_size) : -1LL, wb::peak_rss_mib());
  return 0;
}

// Request i is "REQ%05d\n", its response "RSP%05d,OK\n" (bench_devices.py
// writes the same exchanges in pytest-reserial's format).
int make_exchanges(const std::string& path, std::uint64_t count) {
  wiretape::SessionHeader header;
  header.port_type = "serial";
  header.port_options = "type=serial,device=/dev/bench";
  wiretape::SessionWriter writer(path, header);
  writer.write(wiretape::RecordKind::open, 0, "{}");
  std::uint64_t t_ns = 1000;
  for (std::uint64_t i = 0; i < count; ++i) {
    char request[32], response[32];
    const int request_size = std::snprintf(request, sizeof request, "REQ%05llu\n", static_cast<unsigned long long>(i));
    const int response_size = std::snprintf(response, sizeof response, "RSP%05llu,OK\n", static_cast<unsigned long long>(i));
    writer.write(wiretape::RecordKind::tx, t_ns, std::string_view(request, static_cast<std::size_t>(request_size)));
    writer.write(wiretape::RecordKind::rx, t_ns + 500, std::string_view(response, static_cast<std::size_t>(response_size)));
    t_ns += 1000;
  }
  writer.close();
  std::printf("{\"path\": \"%s\", \"exchanges\": %llu}\n", path.c_str(), static_cast<unsigned long long>(count));
  return 0;
}

// Current (not peak) resident set size, MiB, and open file descriptors.
double current_rss_mib() {
  long pages_total = 0, pages_resident = 0;
  if (FILE* statm = std::fopen("/proc/self/statm", "r")) {
    if (std::fscanf(statm, "%ld %ld", &pages_total, &pages_resident) != 2) pages_resident = 0;
    std::fclose(statm);
  }
  return static_cast<double>(pages_resident) * static_cast<double>(::sysconf(_SC_PAGESIZE)) / (1 << 20);
}

int open_fds() {
  int count = 0;
  if (DIR* dir = ::opendir("/proc/self/fd")) {
    while (const dirent* entry = ::readdir(dir)) {
      if (entry->d_name[0] != '.') ++count;
    }
    ::closedir(dir);
    --count;  // the directory stream itself
  }
  return count;
}

// Records a loopback session, then replays it with check=data, again and
// again; prints RSS and open fds once a second so a leak shows as growth.
int soak(std::uint64_t seconds, const std::string& dir) {
  const std::string path = dir + "/soak-" + std::to_string(::getpid()) + ".wtape";
  std::vector<std::string> messages;
  for (int i = 0; i < 100; ++i) messages.push_back("message " + std::to_string(i) + std::string(1000, 'a' + i % 26));
  const auto start = Clock::now();
  auto next_sample = start;
  std::uint64_t iterations = 0;
  while (Clock::now() - start < std::chrono::seconds(seconds)) {
    {
      auto port = wiretape::open_port("type=loopback,timeout=5,log=" + path);
      for (const auto& message : messages) {
        port->write_all(message);
        if (port->read_exactly(message.size()) != message) throw std::runtime_error("soak: loopback lost data");
      }
      port->close();
    }
    {
      auto port = wiretape::open_port("type=replay,timing=none,check=data,unused=error,timeout=5,file=" + path);
      for (const auto& message : messages) {
        port->write_all(message);
        if (port->read_exactly(message.size()) != message) {
          throw std::runtime_error("soak: replay differs at iteration " + std::to_string(iterations));
        }
      }
      port->close();
    }
    ++iterations;
    if (Clock::now() >= next_sample) {
      std::printf("{\"t\": %.1f, \"iterations\": %llu, \"rss_MB\": %.2f, \"fds\": %d}\n",
                  wb::seconds_since(start), static_cast<unsigned long long>(iterations),
                  current_rss_mib(), open_fds());
      std::fflush(stdout);
      next_sample += std::chrono::seconds(1);
    }
  }
  std::remove(path.c_str());
  return 0;
}

// Four channels c0..c3 with BYTES each in 4 KiB rx records, interleaved in
// time as a recording of four devices streaming at once would be.
int make_channels(const std::string& path, std::uint64_t bytes_per_channel) {
  constexpr std::uint16_t channels = 4;
  constexpr std::size_t record_bytes = 4096;
  wiretape::SessionHeader header;
  for (std::uint16_t id = 0; id < channels; ++id) {
    wiretape::Channel channel;
    channel.id = id;
    channel.name = "c" + std::to_string(id);
    channel.port_type = "serial";
    channel.port_options = "type=serial,device=/dev/bench" + std::to_string(id);
    header.channels.push_back(channel);
  }
  header.port_type = "serial";
  header.port_options = header.channels.front().port_options;
  wiretape::SessionWriter writer(path, header);
  std::string payload(record_bytes, '\0');
  for (std::size_t i = 0; i < payload.size(); ++i) payload[i] = static_cast<char>('A' + i % 26);
  std::uint64_t t_ns = 1000;
  for (std::uint64_t written = 0; written < bytes_per_channel; written += record_bytes) {
    const auto size = static_cast<std::size_t>(
        std::min<std::uint64_t>(record_bytes, bytes_per_channel - written));
    for (std::uint16_t id = 0; id < channels; ++id) {
      writer.write(wiretape::RecordKind::rx, t_ns, std::string_view(payload.data(), size), id);
      t_ns += 250;
    }
  }
  writer.close();
  std::printf("{\"path\": \"%s\"}\n", path.c_str());
  return 0;
}

// timing=causal: how long after the client's write the rx it releases is
// read by a reader blocked on (channels=1) the same port, (channels=2) the
// port of another channel of the file. One write and one rx per round, the
// rx recorded right after the write.
int causal_latency(std::uint64_t rounds, std::uint64_t channels) {
  if (channels != 1 && channels != 2) throw std::runtime_error("CHANNELS is 1 or 2");
  const std::string path = temp_path("wiretape-bench-causal");
  {
    wiretape::SessionHeader header;
    header.port_type = "serial";
    if (channels == 2) {
      for (std::uint16_t id = 0; id < 2; ++id) {
        wiretape::Channel channel;
        channel.id = id;
        channel.name = id == 0 ? "cmd" : "data";
        channel.port_type = "serial";
        header.channels.push_back(channel);
      }
    }
    wiretape::SessionWriter writer(path, header);
    const std::uint16_t rx_channel = channels == 2 ? 1 : 0;
    for (std::uint64_t i = 0; i < rounds; ++i) {
      const std::uint64_t t_ns = 1'000'000 + i * 1'000'000;
      writer.write(wiretape::RecordKind::tx, t_ns, "G", 0);
      writer.write(wiretape::RecordKind::rx, t_ns + 1, "X", rx_channel);
    }
  }
  const std::string keys = "type=replay,timing=causal,unused=ignore,timeout=10,file=" + path;
  auto writer = wiretape::open_port(channels == 2 ? keys + ",channel=cmd" : keys);
  std::unique_ptr<wiretape::Port> other;
  if (channels == 2) other = wiretape::open_port(keys + ",channel=data");
  wiretape::Port& reader_port = channels == 2 ? *other : *writer;
  std::vector<double> latency_us;
  latency_us.reserve(rounds);
  std::atomic<std::int64_t> written_at{0};
  std::atomic<std::uint64_t> reads{0};
  std::thread reader([&] {
    char byte = 0;
    for (std::uint64_t i = 0; i < rounds; ++i) {
      if (reader_port.read(&byte, 1) != 1) throw std::runtime_error("causal: read timed out");
      const auto now = Clock::now().time_since_epoch().count();
      latency_us.push_back(static_cast<double>(now - written_at.load()) / 1e3);
      reads = i + 1;
    }
  });
  for (std::uint64_t i = 0; i < rounds; ++i) {
    // The reader blocks first: the write is what wakes it.
    while (reads.load() < i) std::this_thread::yield();
    std::this_thread::sleep_for(std::chrono::microseconds(200));
    written_at = Clock::now().time_since_epoch().count();
    writer->write("G", 1);
  }
  reader.join();
  std::remove(path.c_str());
  std::printf("{\"rounds\": %llu, \"p50_us\": %.3f, \"p99_us\": %.3f}\n",
              static_cast<unsigned long long>(rounds), wb::percentile(latency_us, 0.5),
              wb::percentile(latency_us, 0.99));
  return 0;
}

int usage() {
  std::cerr << "usage: wiretape_bench_tool make-session FILE BYTES | replay FILE BYTES |\n"
               "       timing RECORDS PERIOD_US | record-throughput BYTES ROUNDS |\n"
               "       record-latency ROUNDTRIPS ROUNDS | record-rss BYTES FILE |\n"
               "       make-exchanges FILE COUNT | soak SECONDS DIR |\n"
               "       make-channels FILE BYTES | replay-c1 FILE BYTES |\n"
               "       causal-latency ROUNDS CHANNELS\n";
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) return usage();
  const std::string command = argv[1];
  try {
    if (command == "make-session") {
      wb::write_rx_session(argv[2], wb::parse_count(argv[3], "BYTES"));
      std::printf("{\"path\": \"%s\"}\n", argv[2]);
      return 0;
    }
    if (command == "replay") return replay(argv[2], wb::parse_count(argv[3], "BYTES"));
    if (command == "replay-c1") {
      return replay(argv[2], wb::parse_count(argv[3], "BYTES"), ",channel=c1");
    }
    if (command == "make-channels") {
      return make_channels(argv[2], wb::parse_count(argv[3], "BYTES"));
    }
    if (command == "causal-latency") {
      return causal_latency(wb::parse_count(argv[2], "ROUNDS"), wb::parse_count(argv[3], "CHANNELS"));
    }
    if (command == "timing") return timing(wb::parse_count(argv[2], "RECORDS"), wb::parse_count(argv[3], "PERIOD_US"));
    if (command == "record-throughput") {
      return record_throughput(wb::parse_count(argv[2], "BYTES"), wb::parse_count(argv[3], "ROUNDS"));
    }
    if (command == "record-latency") {
      return record_latency(wb::parse_count(argv[2], "ROUNDTRIPS"), wb::parse_count(argv[3], "ROUNDS"));
    }
    if (command == "soak") return soak(wb::parse_count(argv[2], "SECONDS"), argv[3]);
    if (command == "make-exchanges") return make_exchanges(argv[2], wb::parse_count(argv[3], "COUNT"));
    if (command == "record-rss") return record_rss(wb::parse_count(argv[2], "BYTES"), argv[3]);
  } catch (const std::exception& error) {
    std::cerr << "wiretape_bench_tool " << command << ": " << error.what() << "\n";
    return 1;
  }
  return usage();
}
