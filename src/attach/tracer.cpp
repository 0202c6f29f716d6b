#include "attach/tracer.hpp"

#include <pthread.h>
#include <signal.h>
#include <sys/ptrace.h>
#include <sys/syscall.h>
#include <sys/uio.h>
#include <sys/user.h>
#include <sys/wait.h>

#include <cerrno>
#include <cstring>

#include "attach/process.hpp"
#include "posix/syscalls.hpp"
#include "wiretape/errors.hpp"

#if !defined(__x86_64__)
#error "attaching (src/attach) knows the registers of x86_64 Linux only"
#endif

namespace wiretape::detail {

namespace {

constexpr long trace_options = PTRACE_O_TRACESYSGOOD | PTRACE_O_TRACECLONE |
                               PTRACE_O_TRACEEXEC | PTRACE_O_TRACEEXIT;
constexpr int syscall_stop = SIGTRAP | 0x80;
// Waits see only the tracees of the calling thread: never a child another
// thread of this process started and will wait for itself.
constexpr int wait_flags = __WALL | __WNOTHREAD;

// Wakes run() out of waitpid: delivered to its thread only, handled by
// nothing (its arrival is the point: waitpid returns EINTR).
int wake_signal() { return SIGRTMAX - 1; }
void on_wake(int) {}

void install_wake_handler() {
  struct sigaction current {};
  sigaction(wake_signal(), nullptr, &current);
  if (current.sa_handler != SIG_DFL) return;
  struct sigaction action {};
  action.sa_handler = on_wake;
  sigemptyset(&action.sa_mask);
  action.sa_flags = 0;  // no SA_RESTART: waitpid must return
  sigaction(wake_signal(), &action, nullptr);
}

bool is_group_stop_signal(int signal) {
  return signal == SIGSTOP || signal == SIGTSTP || signal == SIGTTIN || signal == SIGTTOU;
}

long event_message(pid_t tid) {
  unsigned long message = 0;
  sys::ptrace(PTRACE_GETEVENTMSG, tid, nullptr, &message);
  return static_cast<long>(message);
}

}  // namespace

std::string read_tracee_memory(pid_t pid, std::uint64_t address, std::size_t size) {
  std::string bytes(size, '\0');
  std::size_t done = 0;
  while (done < size) {
    iovec local{bytes.data() + done, size - done};
    iovec remote{reinterpret_cast<void*>(address + done), size - done};
    const ssize_t got = sys::process_vm_readv(pid, &local, 1, &remote, 1);
    if (got <= 0) break;
    done += static_cast<std::size_t>(got);
  }
  bytes.resize(done);
  return bytes;
}

// The injector of the first system-call-entry stop: the thread's registers
// are saved, each run() sets up a system call of ours in their place, and
// finish() puts them back with the instruction pointer on the program's own
// `syscall` again, so that its call runs as if nothing had happened.
class Tracer::StopInjector : public Injector {
 public:
  explicit StopInjector(pid_t tid) : tid_(tid) {
    saved_ok_ = sys::ptrace(PTRACE_GETREGS, tid_, nullptr, &saved_) == 0;
  }

  long run(std::uint64_t number, std::array<std::uint64_t, 6> args, int scratch_arg,
           std::size_t scratch_size, std::string& scratch) override {
    if (!saved_ok_ || broken_) return -ENOSYS;
    // Below the red zone of the program's stack, which it may be using.
    const std::uint64_t address = (saved_.rsp - 512 - scratch_size) & ~std::uint64_t{15};
    const std::string original = read_tracee_memory(tid_, address, scratch_size);
    if (original.size() != scratch_size) return -EFAULT;
    if (!at_entry_ && !reenter()) return -ESRCH;
    if (scratch_arg >= 0) args[static_cast<std::size_t>(scratch_arg)] = address;
    user_regs_struct regs = saved_;
    regs.orig_rax = number;
    regs.rdi = args[0];
    regs.rsi = args[1];
    regs.rdx = args[2];
    regs.r10 = args[3];
    regs.r8 = args[4];
    regs.r9 = args[5];
    ran_ = true;
    if (sys::ptrace(PTRACE_SETREGS, tid_, nullptr, &regs) != 0 || !step_to_syscall_stop()) {
      broken_ = true;
      return -ESRCH;
    }
    at_entry_ = false;
    user_regs_struct after{};
    sys::ptrace(PTRACE_GETREGS, tid_, nullptr, &after);
    scratch = read_tracee_memory(tid_, address, scratch_size);
    write_memory(address, original);
    return static_cast<long>(after.rax);
  }

  // Whether the program's own call must be entered again (something of
  // ours ran in its place).
  bool ran() const { return ran_ && !broken_; }

  // Back to the program's registers, its `syscall` instruction next.
  void finish() {
    if (!ran()) return;
    user_regs_struct regs = saved_;
    regs.rip -= 2;  // the length of `syscall`
    regs.rax = saved_.orig_rax;
    sys::ptrace(PTRACE_SETREGS, tid_, nullptr, &regs);
  }

 private:
  bool reenter() {
    user_regs_struct regs = saved_;
    regs.rip -= 2;
    regs.rax = saved_.orig_rax;
    if (sys::ptrace(PTRACE_SETREGS, tid_, nullptr, &regs) != 0 || !step_to_syscall_stop()) {
      broken_ = true;
      return false;
    }
    at_entry_ = true;
    return true;
  }

  bool step_to_syscall_stop() {
    if (sys::ptrace(PTRACE_SYSCALL, tid_, nullptr, nullptr) != 0) return false;
    for (;;) {
      int status = 0;
      const pid_t got = sys::waitpid(tid_, &status, __WALL);
      if (got < 0 && errno == EINTR) continue;
      if (got != tid_ || !WIFSTOPPED(status)) return false;
      if (WSTOPSIG(status) == syscall_stop) return true;
      // Nothing else stops a thread between the two stops of a call that
      // does not block; anything that does ends the injection.
      return false;
    }
  }

  void write_memory(std::uint64_t address, const std::string& bytes) {
    iovec local{const_cast<char*>(bytes.data()), bytes.size()};
    iovec remote{reinterpret_cast<void*>(address), bytes.size()};
    sys::process_vm_writev(tid_, &local, 1, &remote, 1);
  }

  pid_t tid_;
  user_regs_struct saved_{};
  bool saved_ok_ = false;
  bool at_entry_ = true;
  bool ran_ = false;
  bool broken_ = false;
};

Tracer::~Tracer() = default;

void Tracer::seize() {
  // Threads started while seizing are followed by the ones seized before
  // (PTRACE_O_TRACECLONE) or found by the next listing.
  for (;;) {
    const std::vector<pid_t> tids = process_threads(pid_);
    if (tids.empty() && threads_.empty()) throw attach_refusal(pid_, ESRCH);
    bool added = false;
    for (const pid_t tid : tids) {
      if (threads_.count(tid) != 0) continue;
      if (sys::ptrace(PTRACE_SEIZE, tid, nullptr, reinterpret_cast<void*>(trace_options)) != 0) {
        const int error = errno;
        if (error == ESRCH && tid != pid_) continue;  // the thread ended meanwhile
        detach_all_quietly();
        throw attach_refusal(pid_, error);
      }
      threads_[tid].stopped_by_us = true;
      sys::ptrace(PTRACE_INTERRUPT, tid, nullptr, nullptr);
      added = true;
    }
    if (!added) break;
  }
}

void Tracer::detach_all_quietly() {
  struct Ignore : SyscallHandler {
    void entered(pid_t, const SyscallCall&) override {}
    void returned(pid_t, const SyscallCall&, std::int64_t) override {}
    void first_stop(Injector&) override {}
  } ignore;
  detach_all(ignore);
}

void Tracer::request_stop() {
  stop_ = true;
  if (running_) pthread_kill(static_cast<pthread_t>(runner_.load()), wake_signal());
}

void Tracer::say_when_tracing(const std::function<void()>& on_tracing) {
  if (tracing_said_) return;
  for (const auto& [tid, thread] : threads_) {
    if (thread.stopped_by_us) return;
  }
  tracing_said_ = true;
  if (on_tracing) on_tracing();
}

TraceEnd Tracer::run(SyscallHandler& handler, const std::function<void()>& on_tracing) {
  install_wake_handler();
  sigset_t only_wake;
  sigfillset(&only_wake);
  sigdelset(&only_wake, wake_signal());
  for (int synchronous : {SIGSEGV, SIGBUS, SIGFPE, SIGILL}) sigdelset(&only_wake, synchronous);
  sigset_t before;
  pthread_sigmask(SIG_SETMASK, &only_wake, &before);
  runner_ = static_cast<unsigned long>(pthread_self());
  running_ = true;
  say_when_tracing(on_tracing);
  while (!threads_.empty() && !ended_ && !stop_) {
    int status = 0;
    const pid_t tid = sys::waitpid(-1, &status, wait_flags);
    if (tid < 0) {
      if (errno == EINTR) continue;
      threads_.clear();  // ECHILD: nothing of the program is traced any more
      break;
    }
    handle_stop(tid, status, handler);
    say_when_tracing(on_tracing);
  }
  running_ = false;
  detach_all(handler);
  pthread_sigmask(SIG_SETMASK, &before, nullptr);
  return end_;
}

void Tracer::let_go(pid_t tid, int signal) {
  if (detaching_) {
    sys::ptrace(PTRACE_DETACH, tid, nullptr, reinterpret_cast<void*>(static_cast<long>(signal)));
    forget(tid);
    return;
  }
  if (sys::ptrace(PTRACE_SYSCALL, tid, nullptr,
                  reinterpret_cast<void*>(static_cast<long>(signal))) != 0 &&
      errno == ESRCH) {
    forget(tid);  // killed meanwhile (SIGKILL needs no stop)
  }
}

void Tracer::program_ended(TraceEnd end) {
  if (ended_) return;
  ended_ = true;
  end_ = end;
}

void Tracer::handle_stop(pid_t tid, int status, SyscallHandler& handler) {
  if (WIFEXITED(status) || WIFSIGNALED(status)) {
    forget(tid);
    if (tid == pid_) exit_status_ = status;
    if (threads_.empty()) program_ended(TraceEnd::exited);
    return;
  }
  if (!WIFSTOPPED(status)) return;
  Thread& thread = threads_[tid];  // a new thread may stop before its clone event
  const int signal = WSTOPSIG(status);
  const int event = status >> 16;
  if (signal == syscall_stop) {
    handle_syscall_stop(tid, thread, handler);
    let_go(tid);
    return;
  }
  switch (event) {
    case PTRACE_EVENT_CLONE: {
      const pid_t child = static_cast<pid_t>(event_message(tid));
      if (!detaching_) threads_.emplace(child, Thread{});
      let_go(tid);
      return;
    }
    case PTRACE_EVENT_EXEC:
      // The other threads are gone; the program that runs now is not the
      // one whose descriptors were followed.
      for (auto it = threads_.begin(); it != threads_.end();) {
        it = it->first == tid ? std::next(it) : threads_.erase(it);
      }
      program_ended(TraceEnd::execed);
      detaching_ = true;
      let_go(tid);
      return;
    case PTRACE_EVENT_EXIT: {
      const int code = static_cast<int>(event_message(tid));
      if (tid == pid_ || !exit_status_) exit_status_ = code;
      const bool was_detaching = detaching_;
      detaching_ = true;
      let_go(tid);
      detaching_ = was_detaching;
      if (threads_.empty()) program_ended(TraceEnd::exited);
      return;
    }
    case PTRACE_EVENT_STOP:
      thread.stopped_by_us = false;  // our interrupt, or a new thread's first stop
      if (is_group_stop_signal(signal)) {
        // The program was stopped (SIGSTOP, Ctrl-Z): it stays so, and goes
        // on at its SIGCONT, traced or not.
        if (detaching_) {
          let_go(tid);
        } else {
          sys::ptrace(PTRACE_LISTEN, tid, nullptr, nullptr);
        }
        return;
      }
      let_go(tid);
      return;
    default:
      break;
  }
  // A signal for the program: delivered once, as it would have been.
  let_go(tid, signal);
}

void Tracer::handle_syscall_stop(pid_t tid, Thread& thread, SyscallHandler& handler) {
  __ptrace_syscall_info info{};
  if (sys::ptrace(PTRACE_GET_SYSCALL_INFO, tid, reinterpret_cast<void*>(sizeof info), &info) <= 0) {
    return;
  }
  if (info.op == PTRACE_SYSCALL_INFO_ENTRY) {
    thread.call.number = info.entry.nr;
    for (std::size_t i = 0; i < 6; ++i) thread.call.args[i] = info.entry.args[i];
    if (detaching_) {
      thread.in_syscall = false;  // it runs untraced
      return;
    }
    if (!first_stop_done_) {
      first_stop_done_ = true;
      StopInjector injector(tid);
      handler.first_stop(injector);
      if (injector.ran()) {
        injector.finish();  // the program's call is entered again, and seen then
        return;
      }
    }
    thread.in_syscall = true;
    handler.entered(tid, thread.call);
  } else if (info.op == PTRACE_SYSCALL_INFO_EXIT) {
    if (!thread.in_syscall) return;  // entered before the attach
    thread.in_syscall = false;
    handler.returned(tid, thread.call, info.exit.rval);
  }
}

void Tracer::detach_all(SyscallHandler& handler) {
  detaching_ = true;
  for (auto it = threads_.begin(); it != threads_.end();) {
    const pid_t tid = it->first;
    ++it;
    if (sys::ptrace(PTRACE_INTERRUPT, tid, nullptr, nullptr) != 0 && errno == ESRCH) {
      // Stopped by us already (the exec'ing thread), or gone.
      if (sys::ptrace(PTRACE_DETACH, tid, nullptr, nullptr) == 0 || errno == ESRCH) forget(tid);
    }
  }
  while (!threads_.empty()) {
    int status = 0;
    const pid_t tid = sys::waitpid(-1, &status, wait_flags);
    if (tid < 0) {
      if (errno == EINTR) continue;
      threads_.clear();
      break;
    }
    handle_stop(tid, status, handler);
  }
  // Threads that ended while traced: reaped here, never left as zombies.
  int status = 0;
  while (sys::waitpid(-1, &status, wait_flags | WNOHANG) > 0) {
  }
}

}  // namespace wiretape::detail
