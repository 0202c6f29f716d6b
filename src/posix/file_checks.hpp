// Opening the files wiretape reads and writes as sessions (.wtape files,
// flexiport logs). DESIGN §6, "Special files": an input that is a pipe or FIFO
// may be read as a stream, waiting for a writer interruptibly; an output that
// is not a regular file may be written through, never renamed over; replay and
// the session writer need regular files. Nothing blocks in open(), and nothing
// is written over a file this process is reading.
#pragma once

#include <sys/stat.h>

#include <cstddef>
#include <string>

#include "posix/syscalls.hpp"

namespace wiretape::detail {

// "PATH is a FIFO, not a regular file" for what `mode` says is not a regular
// file; "" for a regular file. The Python tools (wiretape/session.py) use the
// same words.
std::string not_regular_file_problem(const std::string& path, mode_t mode);

// Called while a stream waits for a writer or for data (at least every
// interruption_check_interval_ms, and whenever a signal interrupts the wait);
// it throws to end the wait. The Python module installs one that raises a
// pending Python signal (KeyboardInterrupt), since the wait runs without the
// GIL and Python's own handlers only set a flag. None installed: the wait
// ends only with data or the end of the stream.
using InterruptionCheck = void (*)();
void set_interruption_check(InterruptionCheck check);
// Calls the installed check, if any (it may throw).
void check_interruption();
inline constexpr int interruption_check_interval_ms = 100;

// Whether pipes and FIFOs are read (as streams) or refused.
enum class Streams { refused, read };

// Whether `path` is a pipe or FIFO (following links), without opening it:
// opening and closing a FIFO a writer is using would cost it its reader.
bool is_stream(const std::string& path);

// A session file open for reading. Opening never blocks and follows
// symbolic links; a pipe or FIFO is refused or, with Streams::read, read as
// a stream; anything else that is not a regular file is refused. While it
// is open, open_output_file() refuses the same file (same device and inode,
// so hard links and links to it are caught too).
class InputFile {
 public:
  // Throws PortError naming `path` if it cannot be opened or is not a
  // regular file (nor, with Streams::read, a pipe or FIFO).
  explicit InputFile(const std::string& path, Streams streams = Streams::refused);
  ~InputFile();
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;

  int fd() const { return fd_.get(); }
  const std::string& path() const { return path_; }
  // A pipe or FIFO: no size, no seeking, reads wait for a writer.
  bool is_stream() const { return stream_; }
  // Up to `size` bytes, 0 at the end (or on a read error). A stream waits
  // for a writer and for data, calling the interruption check.
  std::size_t read_some(void* out, std::size_t size);

 private:
  void wait_readable();

  std::string path_;
  sys::UniqueFd fd_;
  bool stream_ = false;
  dev_t device_ = 0;
  ino_t inode_ = 0;
};

// What an output that is not a regular file gets: refused (the session
// writer: record -o, serve -o, log=) or written through (exports).
enum class SpecialOutputs { refused, written_through };

// Creates `path`, or empties it if it is a regular file, for writing output
// (a session, a flexiport log). Always refused, without touching it: a
// directory, a socket, and a file this process has open as an InputFile.
// SpecialOutputs::refused also refuses a symbolic link and anything else
// that is not a regular file. SpecialOutputs::written_through follows a
// symbolic link (a regular target is emptied and written in place) and opens
// a FIFO or a device to write to it as it is: a FIFO with no reader yet is
// waited on, interruptibly. Throws PortError naming the path (both paths for
// a file being read).
sys::UniqueFd open_output_file(const std::string& path,
                               SpecialOutputs special = SpecialOutputs::refused);

// What open_output_file() refuses, checked without opening anything, for a
// writer of several files that must refuse before it empties any of them.
void check_output_file(const std::string& path,
                       SpecialOutputs special = SpecialOutputs::refused);

}  // namespace wiretape::detail
