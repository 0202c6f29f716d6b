// What a running bridge shows other threads (Bridge's getters): its outcome,
// counters, diagnostics and addresses, behind one mutex.
#pragma once

#include <condition_variable>
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
};

}  // namespace wiretape::detail::bridge
