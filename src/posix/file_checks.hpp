// Opening the files wiretape reads and writes as sessions (.wtape files,
// flexiport logs): regular files only, never blocking in open(), and never
// writing over a file this process is reading.
#pragma once

#include <sys/stat.h>

#include <string>

#include "posix/syscalls.hpp"

namespace wiretape::detail {

// "PATH is a FIFO, not a regular file" for what `mode` says is not a regular
// file; "" for a regular file. The Python tools (tools/_files.py) use the
// same words.
std::string not_regular_file_problem(const std::string& path, mode_t mode);

// A session file open for reading. Opening never blocks (a FIFO or a device
// is refused before anything reads it) and follows symbolic links. While it
// is open, open_output_file() refuses the same file (same device and inode,
// so hard links and links to it are caught too).
class InputFile {
 public:
  // Throws PortError naming `path` if it cannot be opened or is not a
  // regular file.
  explicit InputFile(const std::string& path);
  ~InputFile();
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;

  int fd() const { return fd_.get(); }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  sys::UniqueFd fd_;
  dev_t device_ = 0;
  ino_t inode_ = 0;
};

// Creates `path`, or empties it if it is a regular file, for writing output
// (a session, a flexiport log). Refuses without touching it: a symbolic link
// (wiretape does not write through links), anything that is not a regular
// file (FIFO, device, directory, socket), and a file this process has open
// as an InputFile. Never blocks. Throws PortError naming the path (both paths
// for a file being read).
sys::UniqueFd open_output_file(const std::string& path);

// What open_output_file() refuses, checked without opening anything, for a
// writer of several files that must refuse before it empties any of them.
void check_output_file(const std::string& path);

}  // namespace wiretape::detail
