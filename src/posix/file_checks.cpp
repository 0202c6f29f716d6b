#include "posix/file_checks.hpp"

#include <fcntl.h>

#include <poll.h>

#include <algorithm>
#include <atomic>
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

std::atomic<InterruptionCheck>& interruption_check() {
  static std::atomic<InterruptionCheck> check{nullptr};
  return check;
}

// What no output may be, even written through: nothing can be written into
// a directory or a socket as a file.
bool never_an_output(mode_t mode) { return S_ISDIR(mode) || S_ISSOCK(mode); }

void refuse_never_an_output(const std::string& path, mode_t mode) {
  if (never_an_output(mode)) refuse(not_regular_file_problem(path, mode));
}

// The output written through: links followed, a regular file emptied, a FIFO
// or device opened as it is. A FIFO nobody reads yet (ENXIO) is waited on,
// interruptibly, as opening it blocking would wait deaf to signals.
sys::UniqueFd open_output_written_through(const std::string& path) {
  struct stat info {};
  if (sys::stat(path.c_str(), &info) == 0) refuse_never_an_output(path, info.st_mode);
  sys::UniqueFd fd;
  for (;;) {
    fd.reset(open_retrying(path, O_WRONLY | O_CREAT | O_NONBLOCK | O_CLOEXEC, 0644));
    const int error = errno;
    if (fd || error != ENXIO || !is_stream(path)) {
      errno = error;
      break;
    }
    check_interruption();
    sys::poll(nullptr, 0, interruption_check_interval_ms);
  }
  if (!fd) throw PortError(errno, path + ": cannot create");
  if (sys::fstat(fd.get(), &info) != 0) throw PortError(errno, path + ": cannot create");
  refuse_never_an_output(path, info.st_mode);
  refuse_if_being_read(path, info);
  if (S_ISREG(info.st_mode) && sys::ftruncate(fd.get(), 0) != 0) {
    throw PortError(errno, path + ": cannot empty");
  }
  clear_nonblocking(fd.get());
  return fd;
}

}  // namespace

void set_interruption_check(InterruptionCheck check) { interruption_check().store(check); }

void check_interruption() {
  if (const InterruptionCheck check = interruption_check().load()) check();
}

bool is_stream(const std::string& path) {
  struct stat info {};
  return sys::stat(path.c_str(), &info) == 0 && S_ISFIFO(info.st_mode);
}

std::string not_regular_file_problem(const std::string& path, mode_t mode) {
  if (S_ISREG(mode)) return "";
  const char* kind = kind_of(mode);
  if (kind == nullptr) return path + " is not a regular file";
  return path + " is " + kind + ", not a regular file";
}

InputFile::InputFile(const std::string& path, Streams streams) : path_(path) {
  // O_NONBLOCK: opening a FIFO for reading would otherwise wait, deaf to
  // signals, for a writer to appear.
  fd_.reset(open_retrying(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC));
  if (!fd_) throw PortError(errno, path + ": cannot open");
  struct stat info {};
  if (sys::fstat(fd_.get(), &info) != 0) throw PortError(errno, path + ": cannot open");
  stream_ = streams == Streams::read && S_ISFIFO(info.st_mode);
  if (!stream_) {
    const std::string problem = not_regular_file_problem(path, info.st_mode);
    if (!problem.empty()) refuse(problem);
    clear_nonblocking(fd_.get());
  }
  // A stream stays non-blocking: a read with no writer yet would report the
  // end at once, so reads wait in poll(), which can be interrupted.
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

void InputFile::wait_readable() {
  // Until a writer first connects, poll() reports nothing; once it has gone,
  // POLLHUP, and the read that follows reports the end.
  pollfd entry{fd_.get(), POLLIN, 0};
  for (;;) {
    const int ready = sys::poll(&entry, 1, interruption_check_interval_ms);
    if (ready > 0) return;
    if (ready < 0 && errno != EINTR) return;  // the read reports it
    check_interruption();
  }
}

std::size_t InputFile::read_some(void* out, std::size_t size) {
  for (;;) {
    if (stream_) wait_readable();
    const ssize_t n = sys::read(fd_.get(), out, size);
    if (n >= 0) return static_cast<std::size_t>(n);
    if (errno == EINTR) {
      if (stream_) check_interruption();  // only a stream's wait is the user's to end
      continue;
    }
    if (stream_ && errno == EAGAIN) continue;
    return 0;
  }
}

void check_output_file(const std::string& path, SpecialOutputs special) {
  struct stat info {};
  if (special == SpecialOutputs::written_through) {
    if (sys::stat(path.c_str(), &info) != 0) return;  // to be created
    refuse_never_an_output(path, info.st_mode);
    refuse_if_being_read(path, info);
    return;
  }
  if (sys::lstat(path.c_str(), &info) != 0) return;  // to be created
  const std::string problem = not_regular_file_problem(path, info.st_mode);
  if (!problem.empty()) refuse(problem);
  refuse_if_being_read(path, info);
}

sys::UniqueFd open_output_file(const std::string& path, SpecialOutputs special) {
  if (special == SpecialOutputs::written_through) return open_output_written_through(path);
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
