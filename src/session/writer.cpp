// Writing .wtape files: append-only, buffered, with a flusher thread that
// hands buffered records to the OS at most flush_ms after they were written,
// so that a killed recorder loses at most that much. The writing thread only
// copies; the flusher computes the records' checksums and makes the write()
// calls, from one buffer while the writer fills the other. Recording shares
// the machine with the traffic it records, so the work on the port's own
// thread is kept to the one copy that cannot be avoided.
#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

#include "posix/file_checks.hpp"
#include "posix/file_size_limit.hpp"
#include "posix/syscalls.hpp"
#include "session/chunks.hpp"
#include "session/format.hpp"
#include "session/header.hpp"
#include "session/reader.hpp"
#include "session/session_index.hpp"
#include "wiretape/session.hpp"

namespace wiretape {

namespace {

namespace sys = detail::sys;
using Clock = std::chrono::steady_clock;

// Above this much buffered data the flusher is woken at once, without
// waiting for flush_ms.
constexpr std::size_t flush_threshold = 256 * 1024;
// Above this much (the flusher cannot keep up with the disk), write() hands
// the buffer to the OS itself: memory stays bounded and the recording runs
// at the disk's pace.
constexpr std::size_t max_buffered = 1024 * 1024;
// A buffer is given room for that much and a record past it at once, so
// that recording at full rate never moves the records already buffered
// (the pages are only touched as records fill them).
constexpr std::size_t buffer_room = max_buffered + 64 * 1024;
// The file's blocks are reserved this far ahead of its end (without changing
// its size): writes into reserved blocks cost the file system much less than
// growing the file write by write.
constexpr std::uint64_t reserve_step = 32 * 1024 * 1024;

// The records buffered for the file. Unlike a std::string, its room past the
// end can be filled in place (a device read straight into a record:
// write_filled) and grown into without being initialised first; and its
// memory moves only when reserve() grows it.
class ByteBuffer {
 public:
  ByteBuffer() = default;
  ByteBuffer(const ByteBuffer&) = delete;
  ByteBuffer& operator=(const ByteBuffer&) = delete;

  std::size_t size() const { return size_; }
  std::size_t capacity() const { return capacity_; }
  bool empty() const { return size_ == 0; }
  char* data() { return bytes_.get(); }
  const char* data() const { return bytes_.get(); }
  char& operator[](std::size_t at) { return bytes_[at]; }
  void clear() { size_ = 0; }
  void reserve(std::size_t capacity) {
    if (capacity <= capacity_) return;
    std::unique_ptr<char[]> grown(new char[capacity]);
    if (size_ > 0) std::memcpy(grown.get(), bytes_.get(), size_);
    bytes_ = std::move(grown);
    capacity_ = capacity;
  }
  // Room for `n` more bytes at end(), which grow() then counts in.
  char* end() { return bytes_.get() + size_; }
  void grow(std::size_t n) { size_ += n; }
  void append(const char* bytes, std::size_t n) {
    if (capacity_ - size_ < n) reserve(std::max(size_ + n, capacity_ * 2));
    if (n > 0) std::memcpy(end(), bytes, n);
    size_ += n;
  }
  void append(const std::string& bytes) { append(bytes.data(), bytes.size()); }
  void swap(ByteBuffer& other) noexcept {
    std::swap(bytes_, other.bytes_);
    std::swap(size_, other.size_);
    std::swap(capacity_, other.capacity_);
  }

 private:
  std::unique_ptr<char[]> bytes_;
  std::size_t size_ = 0;
  std::size_t capacity_ = 0;
};

}  // namespace

struct SessionWriter::Impl {
  std::string path;
  SessionHeader header;  // as written
  FlushPolicy flush;
  int fd = -1;

  // Serialises writes to the file and keeps their order.
  std::mutex io_mutex;
  std::uint64_t committed = 0;  // bytes in the file, all whole records
  // Records (the file header counts as one) among those bytes: what a
  // reader finds, whatever was buffered when a write failed.
  std::uint64_t committed_records = 0;
  std::uint64_t reserved = 0;   // blocks reserved up to here (io_mutex)
  bool reserving = true;        // false once the file system declined

  // Guards everything below.
  mutable std::mutex mutex;
  std::condition_variable wake;
  // The records of a flush stay where they were buffered until the next
  // one is written: the flushed buffer becomes the spare, on a failure too
  // (write_filled's caller reads its record after the lock is let go).
  ByteBuffer buffer;
  ByteBuffer spare;  // a flushed buffer kept for its capacity
  // End offset of each buffered record (the file header counts as one); its
  // last 4 bytes are the CRC slot, filled in by seal() before the write.
  std::vector<std::size_t> record_ends;
  std::vector<std::size_t> spare_ends;  // kept for its capacity, as spare
  std::uint64_t buffered_total = 0;      // committed + buffer.size() + in flight
  std::optional<Clock::time_point> oldest_unflushed;
  bool flush_requested = false;  // the buffer passed flush_threshold
  std::optional<PortError> failure;
  bool closing = false;
  bool closed = false;
  std::thread flusher;
  // compress=zstd: records go into chunks as they are flushed (io_mutex).
  std::unique_ptr<detail::ChunkEncoder> chunks;
  // Where each channel's records are, for the index written at close.
  detail::SessionIndexBuilder index;
  std::uint64_t index_end = 0;  // where the index, once buffered, ends
  bool index_committed = false;  // the last record in the file is the index
  // records_written()'s answer, read without the lock: a recording bridge
  // asks for it after every record.
  std::atomic<std::uint64_t> records_in_file{0};

  // The header JSON's length in the file: the JSON, then spaces up to it.
  std::size_t header_json_room = 0;

  // Held for the whole of close(), so that a second close() waits for the
  // first to finish instead of racing it.
  std::mutex close_mutex;

  ~Impl() {
    if (fd >= 0) sys::close(fd);
  }

  // What a failed write means for the user: which limit was hit, and what
  // the file still holds.
  std::string write_failure_message(int error) const {
    std::string message = system_error_message(path + ": cannot write the session file", error);
    if (error == EFBIG) {
      const auto limit = detail::file_size_limit();
      message += limit ? " (the file-size limit of " + std::to_string(*limit) +
                             " bytes, RLIMIT_FSIZE or ulimit -f, is reached)"
                       : " (the largest file size allowed is reached)";
    }
    return message + "; its " + std::to_string(committed) +
           " bytes are whole records and stay readable, nothing more is recorded";
  }

  // Called with mutex held, once `committed` includes the records.
  void count_committed(std::uint64_t records) {
    committed_records += records;
    index_committed = index_end != 0 && committed >= index_end;
    // The file header, in the file since the constructor, is not a record,
    // nor is the index.
    const std::uint64_t structure = 1 + (index_committed ? 1 : 0);
    records_in_file.store(committed_records < structure ? 0 : committed_records - structure,
                          std::memory_order_release);
  }

  // Called with io_mutex held. The file is cut back to its last whole
  // record and let go at once: nothing more will be written to it, and a
  // writer that failed holds no descriptor, whoever forgets to close it.
  void fail_and_release(int error) {
    // Best effort: if even the cut fails, a reader still stops at the
    // partial record, at its offset, and returns every record before it.
    (void)sys::ftruncate(fd, static_cast<off_t>(committed));
    reserved = committed;
    sys::close(fd);
    fd = -1;
    std::lock_guard<std::mutex> lock(mutex);
    if (!failure) failure.emplace(error, write_failure_message(error));
    buffered_total = committed;
  }

  // Writes what is buffered. On a failure the file is cut back to the last
  // whole record, so a half-written record never hides good ones.
  // `final`: the last flush, which ends an open chunk.
  void flush_now(bool final = false) {
    std::lock_guard<std::mutex> io(io_mutex);
    ByteBuffer data;
    std::vector<std::size_t> ends;
    {
      std::lock_guard<std::mutex> lock(mutex);
      const bool chunk_to_end = final && chunks && chunks->chunk_open();
      if (failure || (buffer.empty() && !chunk_to_end)) {
        // Nothing more will reach the file after a failure.
        buffer.clear();
        record_ends.clear();
        oldest_unflushed.reset();
        flush_requested = false;
        return;
      }
      data.swap(buffer);
      buffer.swap(spare);
      ends.swap(record_ends);
      record_ends.swap(spare_ends);
      oldest_unflushed.reset();
      flush_requested = false;
    }
    seal(data, ends);
    const std::size_t records_in = ends.size();
    // What goes to the file: the records as buffered, or their chunks.
    std::string chunk_bytes;
    const char* out = data.data();
    std::size_t out_size = data.size();
    if (chunks) {
      chunks->set_file_offset(committed);
      chunk_bytes = chunked(data, ends, final);
      out = chunk_bytes.data();
      out_size = chunk_bytes.size();
      ends.assign(1, out_size);  // whole or not at all (see below)
    }
    // Past RLIMIT_FSIZE the write must fail (EFBIG) rather than the process
    // die between two pages of a record.
    const detail::FileSizeSignalBlocked no_file_size_signal;
    reserve_ahead(committed + out_size);
    std::size_t written = 0;
    int error = 0;
    while (written < out_size) {
      const ssize_t n = sys::write(fd, out + written, out_size - written);
      if (n < 0) {
        if (errno == EINTR) continue;
        error = errno;
        break;
      }
      if (n == 0) {
        error = ENOSPC;
        break;
      }
      written += static_cast<std::size_t>(n);
    }
    if (error == 0 && flush.fsync && sys::fsync(fd) != 0 && errno != EINVAL) {
      error = errno;
      written = 0;  // nothing is known to be on the disk
    }
    if (error == 0) {
      committed += out_size;
      std::lock_guard<std::mutex> count(mutex);
      count_committed(records_in);
      keep_as_spare(data);
      ends.clear();
      if (spare_ends.capacity() < ends.capacity()) spare_ends.swap(ends);
      return;
    }
    // Keep the records that made it whole. A flush of chunks is kept whole
    // or not at all: its records are in its parts, not at their ends.
    std::size_t whole = 0;
    std::uint64_t whole_records = 0;
    for (const std::size_t end : ends) {
      if (!chunks && end <= written) whole = end, ++whole_records;
    }
    committed += whole;
    {
      std::lock_guard<std::mutex> count(mutex);
      count_committed(whole_records);
      keep_as_spare(data);
    }
    fail_and_release(error);
  }

  // Called with mutex held: the flushed buffer's memory is kept (see
  // buffer), its records read as the writer wrote them until it is filled
  // again, which only a write after this flush does.
  void keep_as_spare(ByteBuffer& data) {
    data.clear();
    if (spare.capacity() < data.capacity()) spare.swap(data);
  }

  // The flushed bytes as chunk records: the file header as it is, each
  // record an entry of the open chunk (or, too large for one, as it is
  // between chunks), then the chunk's part up to here (ZSTD_e_flush), or
  // its last part when `final`.
  std::string chunked(const ByteBuffer& data, const std::vector<std::size_t>& ends,
                      bool final) {
    std::string out;
    std::size_t start = 0;
    for (std::size_t i = 0; i < ends.size(); ++i) {
      const std::size_t end = ends[i];
      if (committed == 0 && i == 0) {  // the file header
        out.append(data.data(), end);
        start = end;
        continue;
      }
      const char* record = data.data() + start;
      const std::uint32_t length = detail::get_u32le(record);
      // The index is the file's structure: read from its end, never chunked.
      const bool structure = static_cast<std::uint8_t>(record[4]) == detail::index_record_code;
      if (detail::ChunkEncoder::fits(length) && !structure) {
        chunks->add(static_cast<std::uint8_t>(record[4]), detail::get_u16le(record + 6),
                    detail::get_u64le(record + 8),
                    std::string_view(record + detail::record_header_size, length), out);
      } else {
        chunks->end_chunk(out);
        if (!structure) {
          index.add(committed + out.size(), committed + out.size() + (end - start),
                    detail::get_u16le(record + 6));
        }
        out.append(data.data() + start, end - start);
      }
      start = end;
    }
    if (final) {
      chunks->end_chunk(out);
    } else {
      chunks->flush_part(out);
    }
    // A compressed file's index lists whole chunks (they are read whole).
    for (const detail::ChunkPlace& place : chunks->take_ended()) {
      for (const auto& [channel, records] : place.records) {
        index.add(place.begin, place.end, channel, records);
      }
    }
    return out;
  }

  // Fills each record's CRC slot with the CRC32C of the bytes before it (the
  // file header has the same shape: fixed part, JSON, CRC).
  static void seal(ByteBuffer& data, const std::vector<std::size_t>& ends) {
    std::size_t start = 0;
    for (const std::size_t end : ends) {
      const std::size_t covered = end - detail::crc_size - start;
      detail::put_u32le(&data[end - detail::crc_size], crc32c(&data[start], covered));
      start = end;
    }
  }

  // Best effort: a file system without fallocate, a full disk or a file size
  // limit only means the writes that follow go unreserved, and report their
  // own errors.
  void reserve_ahead(std::uint64_t end) {
#ifdef FALLOC_FL_KEEP_SIZE
    if (!reserving || end <= reserved) return;
    // Small files reserve little: a killed recorder leaves at most the step
    // reserved past its end.
    const std::uint64_t target = end + std::min(reserve_step, end);
    if (sys::fallocate(fd, FALLOC_FL_KEEP_SIZE, static_cast<off_t>(reserved),
                    static_cast<off_t>(target - reserved)) == 0) {
      reserved = target;
    } else {
      reserving = false;
    }
#else
    (void)end;
#endif
  }

  // A file of several channels ends with their index (format 1.3), so that
  // a reader of one reads only its spans; a file of one is read whole
  // anyway. Called once the last records are in the file.
  void append_index() {
    std::lock_guard<std::mutex> io(io_mutex);  // header.channels
    if (header.channels.size() < 2) return;
    std::lock_guard<std::mutex> lock(mutex);
    if (failure || fd < 0) return;
    // A compressed file's offsets are its chunks', in the file (all of it
    // there by now), not the records' as they were buffered.
    const std::uint64_t at = chunks ? committed : buffered_total;
    const std::string bytes = index.record_bytes(at, header.channels.size());
    buffer.append(bytes);
    record_ends.push_back(buffer.size());
    buffered_total += bytes.size();
    index_end = at + bytes.size();
  }

  // Gives back the blocks reserved past the end of the file.
  void release_reserve() {
#ifdef FALLOC_FL_KEEP_SIZE
    if (reserved > committed && fd >= 0) {
      (void)sys::ftruncate(fd, static_cast<off_t>(committed));
      reserved = committed;
    }
#endif
  }

  // Called with mutex held: where a record of up to `size` bytes goes (its
  // bytes, after the room for its header), once the writer is known to
  // take it.
  char* room_for_record(std::size_t size) {
    if (failure) throw *failure;
    if (closed) {
      throw PortError(EBADF, path + ": the session writer is closed; the record was not written");
    }
    const std::size_t framed = detail::record_header_size + size + detail::crc_size;
    if (buffer.capacity() - buffer.size() < framed) {
      buffer.reserve(std::max(buffer.size() + framed, buffer_room));
    }
    return buffer.end() + detail::record_header_size;
  }

  // Called with mutex held, the record's `size` bytes at room_for_record():
  // frames the record and counts it in. True when the writing thread must
  // flush now.
  bool commit_record(RecordKind kind, std::uint64_t t_ns, std::size_t size,
                     std::uint16_t channel) {
    char* head = buffer.end();
    detail::put_u32le(head, static_cast<std::uint32_t>(size));
    head[4] = static_cast<char>(kind);
    head[5] = 0;
    detail::put_u16le(head + 6, channel);
    detail::put_u64le(head + 8, t_ns);
    // The CRC slot, filled in by the flusher (seal).
    std::memset(head + detail::record_header_size + size, 0, detail::crc_size);
    const std::size_t framed = detail::record_header_size + size + detail::crc_size;
    buffer.grow(framed);
    record_ends.push_back(buffer.size());
    const std::uint64_t offset = buffered_total;
    buffered_total += framed;
    // A compressed file's index is of chunks, built as they are flushed.
    if (!chunks) index.add(offset, buffered_total, channel);
    if (!oldest_unflushed) {
      oldest_unflushed = Clock::now();
      wake.notify_one();
    }
    if (buffer.size() >= flush_threshold && !flush_requested) {
      flush_requested = true;
      wake.notify_one();
    }
    return buffer.size() >= max_buffered || flush.interval.count() == 0;
  }

  // A write's own flush (commit_record said so), without mutex.
  void flush_here() {
    flush_now();
    std::lock_guard<std::mutex> lock(mutex);
    if (failure) throw *failure;
  }

  void run_flusher() {
    std::unique_lock<std::mutex> lock(mutex);
    for (;;) {
      if (closing) return;
      if (!oldest_unflushed) {
        wake.wait(lock);
        continue;
      }
      const auto due = *oldest_unflushed + flush.interval;
      if (!flush_requested && Clock::now() < due) {
        wake.wait_until(lock, due);
        continue;
      }
      lock.unlock();
      flush_now();
      lock.lock();
    }
  }
};

namespace {

// The fixed part of the file header and its JSON, padded with spaces to
// `room` bytes, followed by a zeroed CRC slot.
std::string file_header_bytes(const SessionHeader& header, const std::string& json,
                              std::size_t room) {
  std::string file_header(detail::file_header_fixed_size, '\0');
  std::memcpy(&file_header[0], detail::session_magic, sizeof detail::session_magic);
  detail::put_u16le(&file_header[8], header.version_major);
  detail::put_u16le(&file_header[10], header.version_minor);
  detail::put_u32le(&file_header[12], static_cast<std::uint32_t>(room));
  file_header += json;
  file_header.append(room - json.size(), ' ');
  file_header.append(detail::crc_size, '\0');
  return file_header;
}

}  // namespace

SessionWriter::SessionWriter(const std::string& path, const SessionHeader& header,
                             FlushPolicy flush, std::size_t header_room)
    : impl_(std::make_unique<Impl>()) {
  impl_->path = path;
  impl_->flush = flush;
  if (impl_->flush.interval.count() < 0) impl_->flush.interval = std::chrono::milliseconds(0);
  // A header the reader would refuse is refused before the file is created.
  const std::string json = detail::header_json(header);
  impl_->header = header;
  const bool compressed = impl_->flush.compression == Compression::zstd;
  impl_->header.version_major =
      compressed ? detail::compressed_version_major : detail::session_version_major;
  impl_->header.version_minor =
      compressed ? detail::compressed_version_minor : detail::session_version_minor;
  if (compressed) impl_->chunks = std::make_unique<detail::ChunkEncoder>();
  impl_->header.metadata_json = json;
  if (impl_->header.source_format.empty()) impl_->header.source_format = "wiretape";
  const std::size_t json_size = std::min<std::size_t>(json.size(), detail::max_header_json);
  if (header_room > detail::max_header_json - json_size) {
    throw OptionError("header_room", "a header room of " + std::to_string(header_room) +
                                         " bytes makes the header longer than the " +
                                         std::to_string(detail::max_header_json) +
                                         " bytes a reader accepts");
  }
  impl_->header_json_room = json.size() + header_room;
  impl_->fd = detail::open_output_file(path).release();
  // Held until close (or the process ends): a reader that reaches the end
  // of the file while it is held is at the writer's end, not at damage.
  // Best effort: a file system without flock only loses that distinction.
  (void)sys::flock(impl_->fd, LOCK_EX | LOCK_NB);
  // The CRC slot is sealed by the first flush.
  std::string file_header = file_header_bytes(impl_->header, json, impl_->header_json_room);
  // The header reaches the OS at once: a file that exists is readable.
  impl_->buffer.append(file_header);
  impl_->record_ends.push_back(file_header.size());
  impl_->buffered_total = file_header.size();
  impl_->flush_now();
  if (impl_->failure) throw *impl_->failure;
  impl_->flusher = std::thread([impl = impl_.get()] { impl->run_flusher(); });
}

SessionWriter::~SessionWriter() {
  try {
    close();
  } catch (...) {
    // Destructors never throw; close() reports failures to those who call it.
  }
}

void SessionWriter::write(RecordKind kind, std::uint64_t t_ns, std::string_view data,
                          std::uint16_t channel) {
  // Nothing is written that the reader would stop at.
  if (const auto problem = detail::record_content_problem(kind, t_ns, data)) {
    throw std::invalid_argument(impl_->path + ": refusing to write a record: " + *problem);
  }
  if (data.size() > 0xFFFFFFFFull) {
    throw PortError(EFBIG, impl_->path + ": a record of " + std::to_string(data.size()) +
                               " bytes is larger than the 4 GiB a record can hold");
  }
  bool flush_here = false;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    char* room = impl_->room_for_record(data.size());
    if (!data.empty()) std::memcpy(room, data.data(), data.size());
    flush_here = impl_->commit_record(kind, t_ns, data.size(), channel);
  }
  if (flush_here) impl_->flush_here();
}

void SessionWriter::write_filled(RecordKind kind, std::size_t max_size, Fill fill,
                                 void* context, std::string_view* bytes,
                                 std::uint16_t channel) {
  if (max_size > 0xFFFFFFFFull) {
    throw PortError(EFBIG, impl_->path + ": a record of " + std::to_string(max_size) +
                               " bytes is larger than the 4 GiB a record can hold");
  }
  *bytes = std::string_view();
  bool flush_here = false;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    char* room = impl_->room_for_record(max_size);
    const Filled filled = fill(context, room, max_size);
    if (filled.size == 0) return;
    const std::string_view data(room, std::min(filled.size, max_size));
    if (const auto problem = detail::record_content_problem(kind, filled.t_ns, data)) {
      throw std::invalid_argument(impl_->path + ": refusing to write a record: " + *problem);
    }
    flush_here = impl_->commit_record(kind, filled.t_ns, data.size(), channel);
    *bytes = data;
  }
  if (flush_here) impl_->flush_here();
}

// Writes `updated`'s JSON over the header's (its fixed part never changes),
// padded to the room reserved at construction. The caller holds io_mutex.
std::string SessionWriter::rewrite_in_place(const SessionHeader& updated, const std::string& what,
                                            const std::string& fit, const std::string& why) {
  const std::string json = detail::header_json(updated);  // OptionError names the member
  if (json.size() > impl_->header_json_room) {
    throw SessionError(impl_->path + ": the header has no room " + what +
                           ": its JSON would take " + std::to_string(json.size()) +
                           " bytes of the " + std::to_string(impl_->header_json_room) +
                           " reserved when the file was created, " + fit +
                           " (reserve more header room)",
                       detail::file_header_fixed_size);
  }
  std::string bytes = file_header_bytes(updated, json, impl_->header_json_room);
  const std::size_t covered = bytes.size() - detail::crc_size;
  detail::put_u32le(&bytes[covered], crc32c(bytes.data(), covered));
  // The fixed part never changes: only the JSON and its CRC are rewritten.
  const std::size_t at = detail::file_header_fixed_size;
  std::size_t written = 0;
  while (written < bytes.size() - at) {
    const ssize_t n = sys::pwrite(impl_->fd, bytes.data() + at + written,
                               bytes.size() - at - written, static_cast<off_t>(at + written));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int error = n < 0 ? errno : ENOSPC;
      throw PortError(error, impl_->path + ": cannot rewrite the session header " + why);
    }
    written += static_cast<std::size_t>(n);
  }
  if (impl_->flush.fsync) (void)sys::fsync(impl_->fd);
  return json;
}

void SessionWriter::rewrite_header(SessionHeader updated) {
  std::lock_guard<std::mutex> io(impl_->io_mutex);
  SessionHeader& header = impl_->header;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    if (impl_->failure) throw *impl_->failure;
    if (impl_->closed) {
      throw PortError(EBADF, impl_->path + ": the session writer is closed; its header was "
                                           "not rewritten");
    }
  }
  updated.channels = header.channels;
  updated.version_major = header.version_major;
  updated.version_minor = header.version_minor;
  updated.metadata_json = rewrite_in_place(updated, "for its update", "which held the header as first written",
                                           "in place");
  header = std::move(updated);
}

std::uint16_t SessionWriter::add_channel(Channel channel) {
  if (const auto problem = channel_name_problem(channel.name)) {
    throw OptionError("name", impl_->path + ": cannot add channel \"" + channel.name +
                                  "\": " + *problem);
  }
  std::lock_guard<std::mutex> io(impl_->io_mutex);
  SessionHeader& header = impl_->header;
  for (const Channel& existing : header.channels) {
    if (existing.name == channel.name) {
      throw OptionError("name", impl_->path + ": the session already has a channel named \"" +
                                    channel.name + "\"; channel names are unique");
    }
  }
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    if (impl_->failure) throw *impl_->failure;
    if (impl_->closed) {
      throw PortError(EBADF, impl_->path + ": the session writer is closed; channel \"" +
                                 channel.name + "\" was not added");
    }
  }
  SessionHeader updated = header;
  channel.id = static_cast<std::uint16_t>(header.channels.size());
  updated.channels.push_back(channel);
  const std::size_t count = header.channels.size();
  const std::string json = rewrite_in_place(
      updated, "for channel \"" + channel.name + "\"",
      "which fit " + std::to_string(count) + (count == 1 ? " channel" : " channels"),
      "to add channel \"" + channel.name + "\"");
  header.channels.push_back(std::move(channel));
  header.metadata_json = json;
  return header.channels.back().id;
}

void SessionWriter::flush() {
  impl_->flush_now();
  std::lock_guard<std::mutex> lock(impl_->mutex);
  if (impl_->failure) throw *impl_->failure;
}

void SessionWriter::close() {
  std::lock_guard<std::mutex> closing(impl_->close_mutex);
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    if (impl_->closed) return;
    // Refused from here on: a write that came after the final flush took
    // the buffer would never reach the file.
    impl_->closed = true;
    impl_->closing = true;
    impl_->wake.notify_all();
  }
  if (impl_->flusher.joinable()) impl_->flusher.join();
  impl_->flush_now(true);
  impl_->append_index();
  impl_->flush_now();
  std::optional<PortError> failure;
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    failure = impl_->failure;
  }
  {
    std::lock_guard<std::mutex> io(impl_->io_mutex);
    if (impl_->fd >= 0) {
      impl_->release_reserve();
      sys::close(impl_->fd);
      impl_->fd = -1;
    }
  }
  if (failure) throw *failure;
}

const std::string& SessionWriter::path() const { return impl_->path; }

const SessionHeader& SessionWriter::header() const { return impl_->header; }

std::optional<PortError> SessionWriter::failure() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->failure;
}

std::uint64_t SessionWriter::records_written() const {
  return impl_->records_in_file.load(std::memory_order_acquire);
}

std::uint64_t SessionWriter::size() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->buffered_total;
}

}  // namespace wiretape
