// The ptrace side of attaching to a running program (DESIGN §26): every
// thread seized and followed, stopped at each system call's entry and exit,
// its memory copied, and every thread let go as it was. What the system
// calls mean for a recording is syscall_recorder's; this knows only ptrace.
// x86_64 Linux (the registers of the injected system calls).
#pragma once

#include <sys/types.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>

namespace wiretape::detail {

// A system call of a traced thread, as its entry stop showed it.
struct SyscallCall {
  std::uint64_t number = 0;
  std::array<std::uint64_t, 6> args{};
};

// Runs system calls of ours inside a stopped thread of the program (the
// settings and lines at attach are read there, never by opening the device
// again), and copies its memory.
class Injector {
 public:
  virtual ~Injector() = default;
  // The system call's result (-errno on failure). `scratch_size` bytes of
  // the thread's stack, below its red zone, are lent to the call: `arg` of
  // index `scratch_arg` is set to their address, and their content after the
  // call is returned in `scratch`.
  virtual long run(std::uint64_t number, std::array<std::uint64_t, 6> args, int scratch_arg,
                   std::size_t scratch_size, std::string& scratch) = 0;
};

// What the tracer tells about the program's system calls.
class SyscallHandler {
 public:
  virtual ~SyscallHandler() = default;
  virtual void entered(pid_t tid, const SyscallCall& call) = 0;
  // `result` as the kernel returned it (-errno on failure).
  virtual void returned(pid_t tid, const SyscallCall& call, std::int64_t result) = 0;
  // Once, at the first system call entry after the attach, before it.
  virtual void first_stop(Injector& injector) = 0;
};

// Copies `size` bytes at `address` of process `pid`; as many as could be read.
std::string read_tracee_memory(pid_t pid, std::uint64_t address, std::size_t size);

enum class TraceEnd {
  stopped,  // request_stop(): every thread detached
  exited,   // the program exited (exit_status says how)
  execed,   // the program executed a new program: detached from it
};

class Tracer {
 public:
  explicit Tracer(pid_t pid) : pid_(pid) {}
  ~Tracer();
  Tracer(const Tracer&) = delete;
  Tracer& operator=(const Tracer&) = delete;

  // Seizes every thread of the program (PTRACE_SEIZE; threads that start
  // meanwhile are followed). Throws OptionError("attach") saying why not
  // (no such process, permission, kernel.yama.ptrace_scope, already traced);
  // then nothing is left seized. Call from the thread that will run().
  void seize();
  // Stops the threads at system calls and tells `handler`, until
  // request_stop() or the program's end; then every thread is detached.
  // `on_tracing` is called once every seized thread stops at each system
  // call: from then on, no call of the program is missed.
  TraceEnd run(SyscallHandler& handler, const std::function<void()>& on_tracing = {});
  // From any thread: ends run() soon (wakes it if it waits).
  void request_stop();
  // The program's exit status (as waitpid's) once run() returned exited.
  std::optional<int> exit_status() const { return exit_status_; }
  pid_t pid() const { return pid_; }

 private:
  struct Thread {
    bool stopped_by_us = false;  // the interrupt that starts tracing not yet seen
    bool in_syscall = false;
    SyscallCall call;
  };
  class StopInjector;

  void handle_stop(pid_t tid, int status, SyscallHandler& handler);
  void handle_syscall_stop(pid_t tid, Thread& thread, SyscallHandler& handler);
  // Resumes a stopped thread to its next system call stop, or detaches it
  // once detaching; `signal` is delivered to it.
  void let_go(pid_t tid, int signal = 0);
  void program_ended(TraceEnd end);
  void detach_all(SyscallHandler& handler);
  void detach_all_quietly();
  void forget(pid_t tid) { threads_.erase(tid); }
  void say_when_tracing(const std::function<void()>& on_tracing);

  pid_t pid_;
  std::map<pid_t, Thread> threads_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> running_{false};
  std::atomic<unsigned long> runner_{0};  // pthread_t of run()
  bool first_stop_done_ = false;
  bool tracing_said_ = false;
  bool detaching_ = false;
  bool ended_ = false;
  TraceEnd end_ = TraceEnd::stopped;
  std::optional<int> exit_status_;
};

}  // namespace wiretape::detail
