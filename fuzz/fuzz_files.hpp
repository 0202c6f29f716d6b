// Scratch files for fuzz targets whose input is read from disk: one private
// directory per process, removed at exit.
#pragma once

#include <stdlib.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <set>

namespace wiretape::fuzz {

class ScratchDir {
 public:
  // In memory (/dev/shm) where there is one: fuzzing rewrites these files
  // thousands of times a second.
  ScratchDir() {
    const bool shm = ::access("/dev/shm", W_OK) == 0;
    std::string pattern = std::string(shm ? "/dev/shm" : "/tmp") + "/wiretape-fuzz-XXXXXX";
    if (::mkdtemp(&pattern[0]) == nullptr) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~ScratchDir() {
    for (const std::string& name : created_) ::unlink(name.c_str());
    ::rmdir(path_.c_str());
  }
  // Writes `data` to the file `name` in the directory; returns its path.
  std::string write(const std::string& name, const std::uint8_t* data, std::size_t size) {
    const std::string path = file(name);
    // A new file rather than a truncated one: ext4 flushes truncated-and-
    // rewritten files to disk on close, which is slow.
    ::unlink(path.c_str());
    std::FILE* out = std::fopen(path.c_str(), "wb");
    if (out == nullptr) throw std::runtime_error("cannot write " + path);
    if (size > 0) std::fwrite(data, 1, size, out);
    std::fclose(out);
    return path;
  }
  // A path in the directory, removed at exit.
  std::string file(const std::string& name) {
    const std::string path = path_ + "/" + name;
    created_.insert(path);
    return path;
  }

 private:
  std::string path_;
  std::set<std::string> created_;
};

inline ScratchDir& scratch() {
  static ScratchDir dir;
  return dir;
}

}  // namespace wiretape::fuzz
