#include "posix/file_checks.hpp"

#include <fcntl.h>

#include <algorithm>
#include <cerrno>
#include <mutex>
#include <vector>

#include "wiretape/errors.hpp"

namespace wiretape::detail {

namespace {

const char* kind_of(mode_t mode) {
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  if (S_ISLNK(mode)) return "a symbolic link";
  return nullptr;
}

// errno 0: the message is the whole story (the Python binding then adds no
// strerror text to it).
[[noreturn]] void refuse(const std::string& message) { throw PortError(0, message); }

int open_retrying(const std::string& path, int flags, mode_t mode = 0) {
  int fd = -1;
  do {
    fd = sys::open(path.c_str(), flags, mode);
  } while (fd < 0 && errno == EINTR);
  return fd;
}

// The descriptor was opened with O_NONBLOCK only so that open() itself could
// not block; reads and writes of a regular file never do, but say what is
// meant.
void clear_nonblocking(int fd) {
  const int flags = sys::fcntl(fd, F_GETFL);
  if (flags >= 0) sys::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
}

// The files InputFile has open in this process, by identity.
struct OpenInput {
  dev_t device;
  ino_t inode;
  std::string path;
};

std::mutex& inputs_mutex() {
  static std::mutex mutex;
  return mutex;
}

std::vector<OpenInput>& open_inputs() {
  static std::vector<OpenInput> inputs;
  return inputs;
}

void refuse_if_being_read(const std::string& path, const struct stat& info) {
  std::lock_guard<std::mutex> lock(inputs_mutex());
  for (const OpenInput& input : open_inputs()) {
    if (input.device == info.st_dev && input.inode == info.st_ino) {
      refuse(path + " is the same file as " + input.path +
             ", which is being read: refusing to overwrite the input");
    }
  }
}

}  // namespace

std::string not_regular_file_problem(const std::string& path, mode_t mode) {
  if (S_ISREG(mode)) return "";
  const char* kind = kind_of(mode);
  if (kind == nullptr) return path + " is not a regular file";
  return path + " is " + kind + ", not a regular file";
}

InputFile::InputFile(const std::string& path) : path_(path) {
  // O_NONBLOCK: opening a FIFO for reading would otherwise wait, deaf to
  // signals, for a writer to appear.
  fd_.reset(open_retrying(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC));
  if (!fd_) throw PortError(errno, path + ": cannot open");
  struct stat info {};
  if (sys::fstat(fd_.get(), &info) != 0) throw PortError(errno, path + ": cannot open");
  const std::string problem = not_regular_file_problem(path, info.st_mode);
  if (!problem.empty()) refuse(problem);
  clear_nonblocking(fd_.get());
  device_ = info.st_dev;
  inode_ = info.st_ino;
  std::lock_guard<std::mutex> lock(inputs_mutex());
  open_inputs().push_back({device_, inode_, path_});
}

InputFile::~InputFile() {
  std::lock_guard<std::mutex> lock(inputs_mutex());
  auto& inputs = open_inputs();
  const auto found = std::find_if(inputs.begin(), inputs.end(), [this](const OpenInput& input) {
    return input.device == device_ && input.inode == inode_ && input.path == path_;
  });
  if (found != inputs.end()) inputs.erase(found);
}

void check_output_file(const std::string& path) {
  struct stat info {};
  if (sys::lstat(path.c_str(), &info) != 0) return;  // to be created
  const std::string problem = not_regular_file_problem(path, info.st_mode);
  if (!problem.empty()) refuse(problem);
  refuse_if_being_read(path, info);
}

sys::UniqueFd open_output_file(const std::string& path) {
  // Look before opening: opening a device can have effects of its own.
  check_output_file(path);
  struct stat info {};
  // No O_TRUNC yet: nothing is emptied before the checks below. O_NOFOLLOW
  // and the fstat close the race with a file replaced since the lstat.
  sys::UniqueFd fd(open_retrying(
      path, O_WRONLY | O_CREAT | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC, 0644));
  if (!fd) {
    const int error = errno;
    // ELOOP: a symbolic link; ENXIO: a FIFO nobody reads.
    if ((error == ELOOP || error == ENXIO) && sys::lstat(path.c_str(), &info) == 0) {
      const std::string problem = not_regular_file_problem(path, info.st_mode);
      if (!problem.empty()) refuse(problem);
    }
    throw PortError(error, path + ": cannot create");
  }
  if (sys::fstat(fd.get(), &info) != 0) throw PortError(errno, path + ": cannot create");
  const std::string problem = not_regular_file_problem(path, info.st_mode);
  if (!problem.empty()) refuse(problem);
  refuse_if_being_read(path, info);
  if (sys::ftruncate(fd.get(), 0) != 0) throw PortError(errno, path + ": cannot empty");
  clear_nonblocking(fd.get());
  return fd;
}

}  // namespace wiretape::detail
