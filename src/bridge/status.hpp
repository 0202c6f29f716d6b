// What a running bridge shows other threads (Bridge's getters): its outcome,
// counters, diagnostics and addresses, behind one mutex.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <deque>
#include <mutex>
#include <string>

#include "wiretape/bridge.hpp"

namespace wiretape::detail::bridge {

class Status {
 public:
  static constexpr std::size_t kMaxMessages = 1000;

  explicit Status(bool quiet) : quiet_(quiet) {}

  // A diagnostic: printed unless quiet, kept for messages().
  void message(const std::string& text) {
    if (!quiet_) std::fprintf(stderr, "wiretape: %s\n", text.c_str());
    std::lock_guard<std::mutex> lock(mutex);
    messages.push_back(text);
    if (messages.size() > kMaxMessages) messages.pop_front();
  }

  template <typename Update>
  void update_stats(Update update) {
    std::lock_guard<std::mutex> lock(mutex);
    update(result.stats);
  }

  // The byte counters move at every read and write of the bridge's thread,
  // which is their one writer: atomics, not the mutex (a lock and an unlock
  // for each read of the device were 0.015 M instructions a MB of record
  // --pty, docs/benchmarks.md). Bridge's getters merge them into the stats.
  void add_bytes_from_device(std::uint64_t n) {
    bytes_from_device_.fetch_add(n, std::memory_order_release);
  }
  void add_bytes_to_device(std::uint64_t n) {
    bytes_to_device_.fetch_add(n, std::memory_order_release);
  }
  // result.stats with the byte counters; call with mutex held.
  BridgeStats stats() const {
    BridgeStats stats = result.stats;
    stats.bytes_from_device = bytes_from_device_.load(std::memory_order_acquire);
    stats.bytes_to_device = bytes_to_device_.load(std::memory_order_acquire);
    return stats;
  }

  template <typename Field>
  void set(Field Status::*field, Field value) {
    std::lock_guard<std::mutex> lock(mutex);
    this->*field = std::move(value);
  }

  mutable std::mutex mutex;
  std::condition_variable finished_cv;
  bool started = false;
  bool finished = false;
  BridgeResult result;
  std::deque<std::string> messages;
  std::string pty_path;
  std::string listen_address;
  std::string device_description;

 private:
  const bool quiet_;
  std::atomic<std::uint64_t> bytes_from_device_{0};
  std::atomic<std::uint64_t> bytes_to_device_{0};
};

}  // namespace wiretape::detail::bridge
