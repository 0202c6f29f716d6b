#include "attach/syscall_recorder.hpp"

#include <fcntl.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <sys/uio.h>
#include <termios.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "posix/termios_settings.hpp"

namespace wiretape::detail {

namespace {

// The kernel's termios and termios2 (not glibc's struct termios, which is
// laid out otherwise).
struct KernelTermios {
  std::uint32_t iflag, oflag, cflag, lflag;
  std::uint8_t line;
  std::uint8_t cc[19];
};
struct KernelTermios2 {
  KernelTermios base;
  std::uint32_t ispeed, ospeed;
};
static_assert(sizeof(KernelTermios) == 36 && sizeof(KernelTermios2) == 44);

constexpr unsigned long tcgets2 = _IOR('T', 0x2A, KernelTermios2);
constexpr unsigned long tcsets2 = _IOW('T', 0x2B, KernelTermios2);
constexpr unsigned long tcsetsw2 = _IOW('T', 0x2C, KernelTermios2);
constexpr unsigned long tcsetsf2 = _IOW('T', 0x2D, KernelTermios2);
constexpr std::uint32_t kernel_cbaud = 0010017;
constexpr std::uint32_t kernel_bother = 0010000;
constexpr std::int64_t default_break_ms = 250;  // tcsendbreak(fd, 0)

SerialSettings settings_of(const KernelTermios& kernel, std::optional<std::uint32_t> ospeed) {
  termios settings{};
  settings.c_iflag = kernel.iflag;
  settings.c_oflag = kernel.oflag;
  settings.c_cflag = kernel.cflag;
  settings.c_lflag = kernel.lflag;
  const std::uint32_t code = kernel.cflag & kernel_cbaud;
  unsigned baud = baud_of_speed(static_cast<speed_t>(code));
  if (code == kernel_bother && ospeed) baud = *ospeed;
  return line_settings_of(settings, baud);
}

template <typename T>
std::optional<T> read_struct(pid_t pid, std::uint64_t address) {
  const std::string bytes = read_tracee_memory(pid, address, sizeof(T));
  if (bytes.size() != sizeof(T)) return std::nullopt;
  T value;
  std::memcpy(&value, bytes.data(), sizeof(T));
  return value;
}

ModemInputs inputs_of(int bits) {
  ModemInputs inputs;
  inputs.cts = (bits & TIOCM_CTS) != 0;
  inputs.dsr = (bits & TIOCM_DSR) != 0;
  inputs.ri = (bits & TIOCM_RNG) != 0;
  inputs.cd = (bits & TIOCM_CAR) != 0;
  return inputs;
}

bool is_read(std::uint64_t n) {
  return n == SYS_read || n == SYS_readv || n == SYS_pread64 || n == SYS_preadv ||
         n == SYS_preadv2 || n == SYS_recvfrom || n == SYS_recvmsg;
}
bool is_write(std::uint64_t n) {
  return n == SYS_write || n == SYS_writev || n == SYS_pwrite64 || n == SYS_pwritev ||
         n == SYS_pwritev2 || n == SYS_sendto || n == SYS_sendmsg;
}

}  // namespace

SyscallRecorder::SyscallRecorder(pid_t pid, AttachTarget target, AttachSink& sink)
    : pid_(pid), target_(std::move(target)), sink_(sink) {
  fds_.insert(target_.fds.begin(), target_.fds.end());
  for (const int fd : io_uring_descriptors(pid_)) {
    warn("the program has an io_uring (descriptor " + std::to_string(fd) +
         "): what it reads or writes through it is not recorded");
  }
}

void SyscallRecorder::warn(const std::string& text) {
  if (!warned_.insert(text).second) return;
  warnings_.push_back(text);
  new_warnings_ = true;
}

bool SyscallRecorder::take_new_warnings() {
  const bool any = new_warnings_;
  new_warnings_ = false;
  return any;
}

void SyscallRecorder::emit(RecordKind kind, std::uint64_t t_ns, std::string data) {
  held_.push_back({t_ns, order_++, kind, std::move(data)});
  release();
}

void SyscallRecorder::release() {
  const std::uint64_t bound =
      running_writes_.empty() ? UINT64_MAX : *running_writes_.begin();
  std::stable_sort(held_.begin(), held_.end(), [](const Held& a, const Held& b) {
    return a.t_ns != b.t_ns ? a.t_ns < b.t_ns : a.order < b.order;
  });
  std::size_t done = 0;
  while (done < held_.size() && held_[done].t_ns < bound) {
    sink_.write(held_[done].kind, held_[done].t_ns, held_[done].data);
    ++done;
  }
  held_.erase(held_.begin(), held_.begin() + static_cast<std::ptrdiff_t>(done));
}

void SyscallRecorder::flush() {
  running_writes_.clear();
  entered_at_.clear();
  release();
}

void SyscallRecorder::first_stop(Injector& injector) {
  if (target_.device.kind != DeviceKind::tty || fds_.empty()) return;
  const std::uint64_t fd = static_cast<std::uint64_t>(*fds_.begin());
  std::string scratch;
  if (injector.run(SYS_ioctl, {fd, tcgets2, 0, 0, 0, 0}, 2, sizeof(KernelTermios2), scratch) ==
          0 &&
      scratch.size() == sizeof(KernelTermios2)) {
    KernelTermios2 kernel;
    std::memcpy(&kernel, scratch.data(), sizeof kernel);
    at_attach_.settings = settings_of(kernel.base, kernel.ospeed);
  }
  if (injector.run(SYS_ioctl, {fd, TIOCMGET, 0, 0, 0, 0}, 2, sizeof(int), scratch) == 0 &&
      scratch.size() == sizeof(int)) {
    int bits = 0;
    std::memcpy(&bits, scratch.data(), sizeof bits);
    at_attach_.dtr = (bits & TIOCM_DTR) != 0;
    at_attach_.rts = (bits & TIOCM_RTS) != 0;
    at_attach_.inputs = inputs_of(bits);
  }
  const std::uint64_t now = sink_.now_ns();
  if (at_attach_.settings) record_settings(*at_attach_.settings, now);
  if (at_attach_.dtr) record_outputs(at_attach_.dtr, at_attach_.rts, now);
  if (at_attach_.inputs) record_inputs(*at_attach_.inputs, now);
}

void SyscallRecorder::entered(pid_t tid, const SyscallCall& call) {
  if (is_write(call.number) && tracked(call.args[0])) {
    const std::uint64_t now = sink_.now_ns();
    entered_at_[tid] = now;
    running_writes_.insert(now);
  } else if (call.number == SYS_ioctl && tracked(call.args[0])) {
    entered_at_[tid] = sink_.now_ns();
  }
}

void SyscallRecorder::returned(pid_t tid, const SyscallCall& call, std::int64_t result) {
  const std::uint64_t n = call.number;
  const std::uint64_t now = sink_.now_ns();
  if (is_read(n) && tracked(call.args[0])) {
    on_read(call, result, now);
  } else if (is_write(n) && tracked(call.args[0])) {
    on_write(tid, call, result);
  } else if (n == SYS_ioctl && tracked(call.args[0])) {
    on_ioctl(tid, call, result, now);
    entered_at_.erase(tid);
  } else if (n == SYS_recvmmsg || n == SYS_sendmmsg) {
    if (tracked(call.args[0])) {
      warn(std::string(n == SYS_recvmmsg ? "recvmmsg" : "sendmmsg") + " on descriptor " +
           std::to_string(call.args[0]) + ": its datagrams are not recorded");
    }
  } else if (n == SYS_splice || n == SYS_tee || n == SYS_sendfile || n == SYS_copy_file_range ||
             n == SYS_vmsplice) {
    const bool in = tracked(call.args[0]);
    const bool out = n == SYS_sendfile || n == SYS_tee ? tracked(call.args[1])
                     : n == SYS_vmsplice          ? false
                                                  : tracked(call.args[2]);
    if (in || out) {
      const char* name = n == SYS_splice ? "splice" : n == SYS_tee ? "tee"
                         : n == SYS_sendfile ? "sendfile" : n == SYS_vmsplice ? "vmsplice"
                                                                             : "copy_file_range";
      warn(std::string("the program moved bytes of the device with ") + name +
           ", which cannot be seen: they are missing from the recording");
    }
  } else if (n == SYS_io_uring_setup || n == SYS_io_uring_enter) {
    warn("the program uses io_uring: what it reads or writes through it is not recorded");
  } else {
    on_descriptors(call, result, now);
  }
}

std::string SyscallRecorder::gather(std::uint64_t iov, std::uint64_t count,
                                    std::int64_t total) const {
  std::string bytes;
  count = std::min<std::uint64_t>(count, 1024);  // IOV_MAX
  const std::string vectors = read_tracee_memory(pid_, iov, count * sizeof(iovec));
  for (std::size_t i = 0; i + sizeof(iovec) <= vectors.size() &&
                          bytes.size() < static_cast<std::uint64_t>(total);
       i += sizeof(iovec)) {
    iovec v;
    std::memcpy(&v, vectors.data() + i, sizeof v);
    const std::size_t want =
        std::min<std::size_t>(v.iov_len, static_cast<std::size_t>(total) - bytes.size());
    bytes += read_tracee_memory(pid_, reinterpret_cast<std::uint64_t>(v.iov_base), want);
  }
  return bytes;
}

void SyscallRecorder::on_read(const SyscallCall& call, std::int64_t result, std::uint64_t now) {
  const std::uint64_t n = call.number;
  if (n == SYS_recvfrom && (call.args[3] & MSG_PEEK) != 0) return;  // read again later
  if (n == SYS_recvmsg && (call.args[2] & MSG_PEEK) != 0) return;
  if (result < 0) {
    if (result == -EIO || result == -ENXIO || result == -ECONNRESET) {
      if (!at_end_) {
        at_end_ = true;
        emit(RecordKind::device_lost, now,
             event_payload(RecordKind::device_lost,
                           {{event_field::error,
                             system_error_message("read", static_cast<int>(-result))},
                            {event_field::error_number, std::int64_t{-result}}}));
      }
    }
    return;  // EAGAIN, EINTR...: no data
  }
  if (result == 0) {
    // A stream's end. A terminal's read returns 0 when VMIN=0 found nothing
    // (gpsd polls so): no data, and no end (a hung-up pty reads EIO).
    const bool stream_end = target_.device.kind != DeviceKind::udp &&
                            target_.device.kind != DeviceKind::tty;
    if (stream_end && !at_end_) {
      at_end_ = true;
      emit(RecordKind::device_lost, now,
           event_payload(RecordKind::device_lost,
                         {{event_field::error, std::string("end of file (a read returned 0)")}}));
    }
    return;
  }
  std::string bytes;
  if (n == SYS_read || n == SYS_pread64 || n == SYS_recvfrom) {
    bytes = read_tracee_memory(pid_, call.args[1], static_cast<std::size_t>(result));
  } else if (n == SYS_recvmsg) {
    if (const auto message = read_struct<msghdr>(pid_, call.args[1])) {
      bytes = gather(reinterpret_cast<std::uint64_t>(message->msg_iov), message->msg_iovlen,
                     result);
    }
  } else {
    bytes = gather(call.args[1], call.args[2], result);
  }
  at_end_ = false;
  rx_bytes_ += bytes.size();
  emit(RecordKind::rx, now, std::move(bytes));
}

void SyscallRecorder::on_write(pid_t tid, const SyscallCall& call, std::int64_t result) {
  const auto entry = entered_at_.find(tid);
  const std::uint64_t at = entry == entered_at_.end() ? sink_.now_ns() : entry->second;
  if (entry != entered_at_.end()) {
    running_writes_.erase(running_writes_.find(entry->second));
    entered_at_.erase(entry);
  }
  if (result <= 0) {
    release();
    return;
  }
  const std::uint64_t n = call.number;
  std::string bytes;
  if (n == SYS_write || n == SYS_pwrite64 || n == SYS_sendto) {
    bytes = read_tracee_memory(pid_, call.args[1], static_cast<std::size_t>(result));
  } else if (n == SYS_sendmsg) {
    if (const auto message = read_struct<msghdr>(pid_, call.args[1])) {
      bytes = gather(reinterpret_cast<std::uint64_t>(message->msg_iov), message->msg_iovlen,
                     result);
    }
  } else {
    bytes = gather(call.args[1], call.args[2], result);
  }
  tx_bytes_ += bytes.size();
  emit(RecordKind::tx, at, std::move(bytes));
}

void SyscallRecorder::record_settings(const SerialSettings& settings, std::uint64_t now) {
  if (settings_ && *settings_ == settings) return;  // only changes, as a bridge records
  settings_ = settings;
  emit(RecordKind::settings, now,
       event_payload(RecordKind::settings,
                     {{event_field::baud, std::int64_t{settings.baud}},
                      {event_field::databits, std::int64_t{settings.data_bits}},
                      {event_field::stopbits, std::int64_t{settings.stop_bits}},
                      {event_field::parity, std::string(to_string(settings.parity))},
                      {event_field::flow, std::string(to_string(settings.flow))}}));
}

void SyscallRecorder::record_outputs(std::optional<bool> dtr, std::optional<bool> rts,
                                     std::uint64_t now, std::optional<bool> applied) {
  // Each change the program asked for, even a level the line already has
  // (a pulse is two changes, whatever was before).
  EventMembers members;
  if (dtr) members.emplace_back(event_field::dtr, *dtr);
  if (rts) members.emplace_back(event_field::rts, *rts);
  if (applied) members.emplace_back(event_field::applied, *applied);
  if (dtr) dtr_ = dtr;
  if (rts) rts_ = rts;
  if (dtr || rts) emit(RecordKind::modem_lines, now, event_payload(RecordKind::modem_lines, members));
}

void SyscallRecorder::record_inputs(const ModemInputs& inputs, std::uint64_t now) {
  if (inputs_ && *inputs_ == inputs) return;
  inputs_ = inputs;
  emit(RecordKind::modem_lines, now, modem_inputs_payload(inputs));
}

void SyscallRecorder::on_ioctl(pid_t tid, const SyscallCall& call, std::int64_t result,
                               std::uint64_t now) {
  const unsigned long request = static_cast<unsigned long>(call.args[1] & 0xffffffffu);
  const std::uint64_t argument = call.args[2];
  // A device without modem lines (a pty) refuses them: the program's
  // intent is recorded as not applied, as a bridge records it.
  const bool line_request = request == TIOCMBIS || request == TIOCMBIC || request == TIOCMSET;
  const bool unsupported = result == -ENOTTY || result == -EINVAL;
  if (result != 0 && !(line_request && unsupported)) return;
  const std::optional<bool> applied = result == 0 ? std::nullopt : std::optional<bool>(false);
  const auto line_bits = [&]() { return read_struct<int>(pid_, argument); };
  switch (request) {
    case TCSETS:
    case TCSETSW:
    case TCSETSF:
      if (const auto kernel = read_struct<KernelTermios>(pid_, argument)) {
        if (request == TCSETSF) emit(RecordKind::flush_input, now, "{}");
        record_settings(settings_of(*kernel, std::nullopt), now);
      }
      return;
    case tcsets2:
    case tcsetsw2:
    case tcsetsf2:
      if (const auto kernel = read_struct<KernelTermios2>(pid_, argument)) {
        if (request == tcsetsf2) emit(RecordKind::flush_input, now, "{}");
        record_settings(settings_of(kernel->base, kernel->ospeed), now);
      }
      return;
    case TIOCMBIS:
    case TIOCMBIC:
      if (const auto bits = line_bits()) {
        const bool level = request == TIOCMBIS;
        record_outputs((*bits & TIOCM_DTR) ? std::optional<bool>(level) : std::nullopt,
                       (*bits & TIOCM_RTS) ? std::optional<bool>(level) : std::nullopt, now,
                       applied);
      }
      return;
    case TIOCMSET:
      if (const auto bits = line_bits()) {
        record_outputs((*bits & TIOCM_DTR) != 0, (*bits & TIOCM_RTS) != 0, now, applied);
      }
      return;
    case TIOCMGET:
      if (const auto bits = line_bits()) record_inputs(inputs_of(*bits), now);
      return;
    case TCSBRK:
      if (argument == 0) {
        emit(RecordKind::line_break, now,
             event_payload(RecordKind::line_break, {{event_field::duration_ms, default_break_ms}}));
      } else {
        emit(RecordKind::drain, now, "{}");
      }
      return;
    case TCSBRKP: {
      const std::int64_t ms =
          argument == 0 ? default_break_ms : static_cast<std::int64_t>(argument) * 100;
      emit(RecordKind::line_break, now,
           event_payload(RecordKind::line_break, {{event_field::duration_ms, ms}}));
      return;
    }
    case TIOCSBRK: {
      const auto entry = entered_at_.find(tid);
      break_since_ = entry == entered_at_.end() ? now : entry->second;
      return;
    }
    case TIOCCBRK:
      if (break_since_) {
        const std::int64_t ms =
            std::max<std::int64_t>(1, static_cast<std::int64_t>((now - *break_since_) / 1000000));
        emit(RecordKind::line_break, *break_since_,
             event_payload(RecordKind::line_break, {{event_field::duration_ms, ms}}));
        break_since_.reset();
      }
      return;
    case TCFLSH:
      if (argument == TCIFLUSH || argument == TCIOFLUSH) emit(RecordKind::flush_input, now, "{}");
      if (argument == TCOFLUSH || argument == TCIOFLUSH) emit(RecordKind::flush_output, now, "{}");
      return;
    default:
      return;
  }
}

void SyscallRecorder::untrack(int fd, std::uint64_t now) {
  if (fds_.erase(fd) == 0 || !fds_.empty() || closed_) return;
  closed_ = true;
  emit(RecordKind::close, now, "{}");
}

void SyscallRecorder::on_descriptors(const SyscallCall& call, std::int64_t result,
                                     std::uint64_t now) {
  const std::uint64_t n = call.number;
  const int first = static_cast<int>(call.args[0]);
  if (n == SYS_close) {
    // The descriptor is released even when close reports an error.
    if (result != -EBADF) untrack(first, now);
    return;
  }
  if (n == SYS_close_range) {
    constexpr std::uint64_t cloexec_only = 1u << 2;  // CLOSE_RANGE_CLOEXEC
    if (result != 0 || (call.args[2] & cloexec_only) != 0) return;
    const std::vector<int> held(fds_.begin(), fds_.end());
    for (const int fd : held) {
      if (static_cast<std::uint64_t>(fd) >= call.args[0] &&
          static_cast<std::uint64_t>(fd) <= call.args[1]) {
        untrack(fd, now);
      }
    }
    return;
  }
  if (result < 0) return;
  const int made = static_cast<int>(result);
  if (n == SYS_dup || (n == SYS_fcntl && (call.args[1] == F_DUPFD || call.args[1] == F_DUPFD_CLOEXEC))) {
    if (tracked(call.args[0])) fds_.insert(made);
  } else if (n == SYS_dup2 || n == SYS_dup3) {
    const int target = static_cast<int>(call.args[1]);
    if (target == first) return;
    if (tracked(call.args[0])) {
      fds_.insert(target);
    } else {
      untrack(target, now);
    }
  } else if (n == SYS_openat || n == SYS_open || n == SYS_openat2) {
    if (target_.device.kind != DeviceKind::tty && target_.device.kind != DeviceKind::other) return;
    if (!descriptor_is(pid_, made, target_.device)) return;
    fds_.insert(made);
    if (closed_) {
      closed_ = false;
      at_end_ = false;
      emit(RecordKind::open, now,
           event_payload(RecordKind::open, {{event_field::description,
                                             "reopened " + target_.device.target},
                                            {event_field::reopened, true}}));
    }
  }
}

}  // namespace wiretape::detail
