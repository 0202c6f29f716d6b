#include "session/buffered_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "posix/syscalls.hpp"
#include "wiretape/errors.hpp"

namespace wiretape {
namespace detail {

namespace {
constexpr std::size_t buffer_size = 128 * 1024;
}  // namespace

BufferedFile::BufferedFile(const std::string& path, Streams streams)
    : file_(path, streams), buffer_(new char[buffer_size]) {
  refresh_size();
}

void BufferedFile::refresh_size() {
  if (is_stream()) return;
  struct stat info {};
  if (sys::fstat(file_.fd(), &info) == 0) size_ = static_cast<std::uint64_t>(info.st_size);
}

std::uint64_t BufferedFile::remaining() {
  if (is_stream()) {
    if (end_ == begin_) fill();
    return end_ - begin_;
  }
  // At the known end, look again: the file may still be being written.
  if (position_ >= size_) refresh_size();
  return size_ > position_ ? size_ - position_ : 0;
}

std::size_t BufferedFile::fill() {
  if (buffer_.use_count() > 1 && (begin_ > 0 || end_ == 0)) {
    // Views still point into this buffer: go on in a fresh one rather than
    // move or overwrite their bytes.
    std::shared_ptr<char[]> fresh;
    for (auto& retired : retired_) {
      if (retired.use_count() == 1) {  // its views are all gone: reuse it
        fresh = std::move(retired);
        retired = std::move(retired_.back());
        retired_.pop_back();
        break;
      }
    }
    // A fresh allocation costs page faults every time; reuse is what pays.
    if (!fresh) fresh.reset(new char[buffer_size]);
    std::memcpy(fresh.get(), buffer_.get() + begin_, end_ - begin_);
    end_ -= begin_;
    begin_ = 0;
    if (retired_.size() < max_retired_buffers) retired_.push_back(std::move(buffer_));
    buffer_ = std::move(fresh);
  } else if (begin_ > 0) {
    std::memmove(buffer_.get(), buffer_.get() + begin_, end_ - begin_);
    end_ -= begin_;
    begin_ = 0;
  }
  std::size_t room = buffer_size - end_;
  const std::uint64_t buffered_end = position_ + (end_ - begin_);
  if (read_ahead_end_ > buffered_end) {
    room = static_cast<std::size_t>(std::min<std::uint64_t>(room, read_ahead_end_ - buffered_end));
  }
  if (room > 0) end_ += read_some(buffer_.get() + end_, room, buffered_end);
  return end_ - begin_;
}

bool BufferedFile::read(void* out, std::size_t size) {
  auto* dst = static_cast<char*>(out);
  if (end_ - begin_ >= size) {
    std::memcpy(dst, buffer_.get() + begin_, size);
    begin_ += size;
    position_ += size;
    return true;
  }
  if (is_stream()) return read_stream(dst, size);
  if (remaining() < size) refresh_size();
  if (remaining() < size) return false;
  // Large reads go straight to the destination.
  std::size_t done = end_ - begin_;
  std::memcpy(dst, buffer_.get() + begin_, done);
  begin_ = end_ = 0;
  if (size - done >= buffer_size) {
    while (done < size) {
      const std::size_t n = read_some(dst + done, size - done, position_ + done);
      if (n == 0) {
        seek(position_);
        return false;
      }
      done += n;
    }
    position_ += size;
    return true;
  }
  // position_ follows what was taken: fill() reads at the buffer's end.
  const std::uint64_t start = position_;
  position_ += done;
  while (done < size) {
    if (fill() == 0) {
      seek(start);
      return false;
    }
    const std::size_t take = std::min(size - done, end_ - begin_);
    std::memcpy(dst + done, buffer_.get() + begin_, take);
    begin_ += take;
    position_ += take;
    done += take;
  }
  return true;
}

bool BufferedFile::read_stream(char* out, std::size_t size) {
  if (size > buffer_size) {  // through a string that grows only as bytes arrive
    std::string bytes;
    if (!read_into(bytes, size)) return false;
    std::memcpy(out, bytes.data(), size);
    return true;
  }
  // Nothing consumed until all of it is there.
  while (end_ - begin_ < size) {
    const std::size_t before = end_ - begin_;
    if (fill() == before) return false;
  }
  std::memcpy(out, buffer_.get() + begin_, size);
  begin_ += size;
  position_ += size;
  return true;
}

bool BufferedFile::read_into(std::string& out, std::size_t size) {
  if (end_ - begin_ >= size) {
    // One copy, without the zero-fill a resize() would do first.
    out.assign(buffer_.get() + begin_, size);
    begin_ += size;
    position_ += size;
    return true;
  }
  if (is_stream()) {
    // The length came from the stream itself: never allocate more than
    // twice what has arrived, whatever it claims.
    out.clear();
    while (out.size() < size) {
      if (begin_ == end_ && fill() == 0) return false;
      const std::size_t take = std::min(size - out.size(), end_ - begin_);
      if (out.capacity() < out.size() + take) {
        out.reserve(std::min(size, std::max(2 * out.capacity(), out.size() + take)));
      }
      out.append(buffer_.get() + begin_, take);
      begin_ += take;
      position_ += take;
    }
    return true;
  }
  out.resize(size);
  return size == 0 || read(&out[0], size);
}

std::size_t BufferedFile::max_view_size() { return buffer_size / 2; }

bool BufferedFile::read_view(std::size_t size, PayloadView& out) {
  if (size > max_view_size() || is_stream()) return false;
  if (end_ - begin_ < size) {
    if (remaining() < size) refresh_size();
    if (remaining() < size) return false;
    while (end_ - begin_ < size) {
      const std::size_t before = end_ - begin_;
      if (fill() == before) {
        seek(position_);
        return false;
      }
    }
  }
  out.owner = buffer_;
  out.bytes = std::string_view(buffer_.get() + begin_, size);
  begin_ += size;
  position_ += size;
  return true;
}

bool BufferedFile::skip(std::uint64_t size) {
  if (end_ - begin_ >= size) {
    begin_ += static_cast<std::size_t>(size);
    position_ += size;
    return true;
  }
  if (is_stream()) {
    while (size > 0) {
      if (begin_ == end_ && fill() == 0) return false;
      const std::size_t take =
          static_cast<std::size_t>(std::min<std::uint64_t>(size, end_ - begin_));
      begin_ += take;
      position_ += take;
      size -= take;
    }
    return true;
  }
  if (remaining() < size) refresh_size();
  if (remaining() < size) return false;
  seek(position_ + size);
  return true;
}

std::size_t BufferedFile::read_some(char* out, std::size_t size, std::uint64_t offset) {
  if (is_stream()) return file_.read_some(out, size);
  // A regular file is read at its offsets, so that a seek costs no call.
  for (;;) {
    const ssize_t n = sys::pread(file_.fd(), out, size, static_cast<off_t>(offset));
    if (n >= 0) return static_cast<std::size_t>(n);
    if (errno != EINTR) return 0;
  }
}

void BufferedFile::seek(std::uint64_t position) {
  if (is_stream()) throw PortError(ESPIPE, path() + ": a pipe or FIFO cannot be read again");
  position_ = position;
  begin_ = end_ = 0;
}

}  // namespace detail
}  // namespace wiretape
