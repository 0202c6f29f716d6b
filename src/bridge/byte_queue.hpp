// Bytes waiting to be written, consumed from the front without moving the
// rest on every write.
#pragma once

#include <cstddef>
#include <string>

namespace wiretape::detail::bridge {

// The size of one read or write: data moves in chunks this large.
constexpr std::size_t kChunk = 64 * 1024;

class ByteQueue {
 public:
  std::size_t size() const { return data_.size() - start_; }
  bool empty() const { return size() == 0; }
  const char* data() const { return data_.data() + start_; }
  void append(const char* bytes, std::size_t n) { data_.append(bytes, n); }
  void append(const std::string& bytes) { data_.append(bytes); }
  void consume(std::size_t n) {
    start_ += n;
    if (start_ == data_.size()) {
      data_.clear();
      start_ = 0;
    } else if (start_ > kChunk && start_ * 2 > data_.size()) {
      data_.erase(0, start_);
      start_ = 0;
    }
  }
  void clear() {
    data_.clear();
    start_ = 0;
  }

 private:
  std::string data_;
  std::size_t start_ = 0;
};

}  // namespace wiretape::detail::bridge
