// Bytes waiting to be written, consumed from the front without moving the
// rest on every write.
//
// Every queue in the bridge has a limit, and the rule that keeps memory
// bounded is the same everywhere: whoever fills a queue asks room() (or
// full()) before producing more, and when there is none it stops reading the
// source of those bytes (backpressure) or drops them (a monitor). One step of
// production may overshoot by what it made of one chunk (kChunk) of input.
// The memory a queue holds follows its limit, not how full it ever was: its
// buffer grows to about the limit and no further (a std::string would double
// past it), and the consumed front is reused before the buffer grows.
#pragma once

#include <algorithm>
#include <cstddef>
#include <string>
#include <vector>

namespace wiretape::detail::bridge {

// The size of one read or write: data moves in chunks this large.
constexpr std::size_t kChunk = 64 * 1024;

class ByteQueue {
 public:
  explicit ByteQueue(std::size_t limit) : limit_(limit) {}

  std::size_t size() const { return data_.size() - start_; }
  bool empty() const { return size() == 0; }
  std::size_t limit() const { return limit_; }
  // How many more bytes fit under the limit.
  std::size_t room() const { return limit_ - std::min(limit_, size()); }
  bool full() const { return room() == 0; }
  // The memory the queue holds now (for tests of the bound).
  std::size_t capacity() const { return data_.capacity(); }

  const char* data() const { return data_.data() + start_; }
  void append(const char* bytes, std::size_t n) {
    if (data_.size() + n > data_.capacity()) make_room(n);
    data_.insert(data_.end(), bytes, bytes + n);
  }
  void append(const std::string& bytes) { append(bytes.data(), bytes.size()); }
  void consume(std::size_t n) {
    start_ += n;
    if (start_ == data_.size()) {
      data_.clear();
      start_ = 0;
    } else if (start_ > kChunk && start_ * 2 > data_.size()) {
      compact();
    }
  }
  void clear() {
    data_.clear();
    start_ = 0;
  }

 private:
  void compact() {
    data_.erase(data_.begin(), data_.begin() + static_cast<std::ptrdiff_t>(start_));
    start_ = 0;
  }
  void make_room(std::size_t n) {
    if (start_ > 0) compact();
    const std::size_t needed = data_.size() + n;
    if (needed <= data_.capacity()) return;
    // Geometric growth keeps appends cheap, but stops at the limit: a full
    // queue holds about `limit` bytes of memory, not up to twice that.
    const std::size_t grown = std::min(std::max(data_.capacity() * 2, kChunk), limit_);
    data_.reserve(std::max(needed, grown));
  }

  std::size_t limit_;
  std::vector<char> data_;
  std::size_t start_ = 0;
};

}  // namespace wiretape::detail::bridge
