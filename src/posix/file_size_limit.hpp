// Writing files under a file-size limit (RLIMIT_FSIZE, `ulimit -f`). By
// default the kernel kills a process that writes past the limit with
// SIGXFSZ, in the middle of whatever it was writing; a recorder must instead
// see the write fail with EFBIG, cut its file back to the last whole record
// and say what happened.
#pragma once

#include <cstdint>
#include <optional>

namespace wiretape::detail {

// While alive, a write on this thread past the file-size limit fails with
// EFBIG instead of raising SIGXFSZ. Thread-scoped (the signal is blocked, not
// ignored): the process's disposition, which children inherit, is left
// alone. A SIGXFSZ that a failed write left pending is taken back before the
// signal is unblocked, so it never arrives late.
class FileSizeSignalBlocked {
 public:
  FileSizeSignalBlocked();
  ~FileSizeSignalBlocked();
  FileSizeSignalBlocked(const FileSizeSignalBlocked&) = delete;
  FileSizeSignalBlocked& operator=(const FileSizeSignalBlocked&) = delete;

 private:
  bool was_blocked_ = false;  // by the caller: left as it was
};

// The process's file-size limit in bytes, or nothing when it has none.
std::optional<std::uint64_t> file_size_limit();

}  // namespace wiretape::detail
