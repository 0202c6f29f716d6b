// type=replay: a session file plays the device. The engine decides what may
// be read when; this port adds blocking with deadlines, close from another
// thread, and a pollable handle that is readable exactly when available() > 0
// (a scheduler thread raises it when timed data falls due; made when first
// asked for).
#include <fcntl.h>

#include <cerrno>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <optional>
#include <thread>

#include "posix/platform.hpp"
#include "posix/syscalls.hpp"
#include "posix/transports.hpp"
#include "replay/channel_hub.hpp"
#include "replay/client_session.hpp"
#include "replay/exchanges.hpp"
#include "replay/replay_engine.hpp"
#include "replay/replay_port.hpp"
#include "session/reader.hpp"
#include "session/record_kinds.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/session.hpp"

namespace wiretape::detail {

namespace {

std::string describe(const ReplayConfig& config) {
  const char* timing = config.timing == ReplayTiming::none      ? "none"
                       : config.timing == ReplayTiming::session ? "session"
                                                                : "causal";
  const char* match =
      config.match == ReplayMatch::sequence ? "sequence" : "request";
  const std::string channel =
      config.several_channels ? "channel=" + config.channel + ", " : std::string();
  return "replay " + config.file + " (" + channel + "timing=" + timing + ", match=" + match +
         ")";
}

// When a replay opening now starts its clock: now, or the first open of a
// channel of its file in this process.
ReplayTime open_time(const ReplayConfig& config) {
  const ReplayTime now = ReplayClock::now();
  return config.hub ? config.hub->open_time(now) : now;
}

}  // namespace

namespace {

class ReplayPort : public Port, public FaultSource {
 public:
  ReplayPort(ReplayConfig config, RecordSourceFactory sources)
      : description_(describe(config)),
        sources_(sources),
        config_(config),
        frozen_now_(config_.untimed ? std::optional<ReplayTime>(open_time(config_)) : std::nullopt),
        engine_(std::make_unique<ReplayEngine>(std::move(config), std::move(sources),
                                               frozen_now_ ? *frozen_now_ : open_time(config_))) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      update_signal(replay_now());
    }
    // Faults (delay, stall, trickle, reconnect) make data due later even
    // under timing=none: someone must raise the pipe then.
    if ((engine_->config().timing != ReplayTiming::none || !engine_->config().faults.empty()) &&
        !scheduler_.joinable()) {
      scheduler_ = std::thread([this] { schedule(); });
    }
    // Another channel's write may release rx here (timing=causal across
    // channels): the blocked reader and the pollable handle learn it.
    if (config_.member) {
      config_.member->set_waker([this] {
        std::lock_guard<std::mutex> lock(mutex_);
        if (closed_) return;
        update_signal(replay_now());
        changed_.notify_all();
      });
    }
  }

  ~ReplayPort() override {
    try {
      shut(/*may_throw=*/false);
    } catch (...) {
      // A destructor reports through stderr only (shut does).
    }
  }

  std::size_t available() override {
    std::lock_guard<std::mutex> lock(mutex_);
    check_open();
    if (awaiting_client_) return 0;
    return engine_->available(replay_now());
  }

  // A virtual device with no client: holds everything until the next client
  // session begins.
  void await_client() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (closed_) return;
    awaiting_client_ = true;
    update_signal(replay_now());
    changed_.notify_all();
  }

  // A client connected: the k-th session starts now, at the recording's
  // k-th client_connect (the first: at the recording's start when it has
  // none). A later client of a recording without one continues where the
  // previous one left off. True when the session starts afresh.
  bool begin_client_session() {
    const int k = client_sessions_ + 1;
    std::optional<std::uint64_t> connect_t_ns;
    std::uint64_t first_exchange = 0;  // exchanges are numbered per file (exchanges.hpp)
    // match=request: connection order is free; the k-th connection is
    // greeted as the k-th recorded one (the last, past them) and matches
    // every recorded session's exchanges, its own first (DESIGN.md 12).
    int served_session = k;
    {
      const std::unique_ptr<RecordSource> source = sources_();
      connect_t_ns = find_client_connect(*source, k);
      if (!connect_t_ns && config_.match == ReplayMatch::request && k > 1) {
        source->rewind();
        served_session = count_client_sessions(*source);
        source->rewind();
        if (served_session > 0) connect_t_ns = find_client_connect(*source, served_session);
      }
      if (connect_t_ns) {
        source->rewind();
        first_exchange = first_exchange_of_client_session(
            *source, Segmentation{config_.profile, config_.datagrams, config_.match},
            served_session);
      }
    }
    std::lock_guard<std::mutex> lock(mutex_);
    if (closed_) return false;
    client_sessions_ = k;
    awaiting_client_ = false;
    const auto now = ReplayClock::now();
    const bool afresh = connect_t_ns || k == 1;
    // The channels of one file start on one clock: the first client
    // session of any of them (DESIGN.md section 19).
    const ReplayTime start =
        config_.hub && !connect_t_ns && k == 1 ? config_.hub->first_client_time(now) : now;
    if (afresh) {
      const bool by_request = connect_t_ns && config_.match == ReplayMatch::request;
      RecordSourceFactory sources =
          by_request    ? sessions_first_sources(sources_, served_session)
          : connect_t_ns ? client_session_sources(sources_, k)
                         : sources_;
      ReplayConfig config = config_;
      config.first_exchange = first_exchange;
      if (by_request) config.client_session = served_session;
      engine_ = std::make_unique<ReplayEngine>(std::move(config), std::move(sources), start,
                                               connect_t_ns.value_or(0), fault_memory_);
      if (frozen_now_) frozen_now_ = start;
      engine_->on_fault(fault_reporter_);  // each session's fault stage reports here
    }
    update_signal(now);
    changed_.notify_all();
    return afresh;
  }

  // Injected faults go to `reporter` (see report_faults_to in
  // core/fault_hook.hpp); the engine's fault stage (fault_stage.hpp) does
  // the rest.
  void on_fault(FaultReporter reporter) override {
    std::lock_guard<std::mutex> lock(mutex_);
    fault_reporter_ = std::move(reporter);
    engine_->on_fault(fault_reporter_);
  }

  bool lost_by_fault() {
    std::lock_guard<std::mutex> lock(mutex_);
    return !closed_ && engine_->lost_by_fault(replay_now());
  }

  std::string silenced_by_fault() {
    std::lock_guard<std::mutex> lock(mutex_);
    return fault_memory_->silenced ? fault_memory_->silenced_by : std::string();
  }

  void flush_input() override {
    std::lock_guard<std::mutex> lock(mutex_);
    check_open();
    const auto now = replay_now();
    engine_->flush_input(now);
    update_signal(now);
    changed_.notify_all();
  }
  void flush_output() override {
    std::lock_guard<std::mutex> lock(mutex_);
    check_open();
    client_flushed_locked();
  }

  void client_flushed() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (closed_) return;
    client_flushed_locked();
  }
  void drain() override {
    std::lock_guard<std::mutex> lock(mutex_);
    check_open();
  }

  void close() override { shut(/*may_throw=*/true); }

  // One pass over the recording, stopping at its first rx.
  bool recording_has_rx() const {
    const std::unique_ptr<RecordSource> source = sources_();
    Record record;
    while (source->next(record)) {
      if (record.kind == RecordKind::rx) return true;
    }
    return false;
  }

  // Whether the first client session opens with rx before any tx.
  bool recording_greets() const {
    const bool sessions = [&] {
      const std::unique_ptr<RecordSource> source = sources_();
      return find_client_connect(*source, 1).has_value();
    }();
    const std::unique_ptr<RecordSource> source =
        sessions ? client_session_sources(sources_, 1)() : sources_();
    Record record;
    while (source->next(record)) {
      if (record.data.empty() && !replays_empty_datagrams(config_)) continue;
      if (record.kind == RecordKind::rx) return true;
      if (record.kind == RecordKind::tx) return false;
    }
    return false;
  }

  bool read_would_block_forever() {
    std::lock_guard<std::mutex> lock(mutex_);
    return !closed_ &&
           outlook_at(replay_now()).state ==
               ReplayEngine::ReadState::ended &&
           engine_->config().at_end == ReplayAtEnd::silent;
  }
  bool is_open() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return !closed_;
  }
  std::string description() const override { return description_; }
  std::string type() const override { return "replay"; }
  PortCapabilities capabilities() const override {
    PortCapabilities c;
    c.serial_settings = c.modem_lines = c.send_break = c.played_recording = true;
    return c;
  }
  std::string left_unused() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return left_unused_;
  }
  int native_handle() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!handle_handed_out_ && !closed_) {
      // Made when first asked for: most clients (a fuzzer's run, a
      // program's reads and writes) never poll, and its system calls
      // would be a good part of what a short replay costs.
      const_cast<ReplayPort*>(this)->open_readiness_pipe();
      // From now on someone may poll it: it must tell the truth.
      handle_handed_out_ = true;
      const_cast<ReplayPort*>(this)->update_signal(replay_now());
    }
    return signal_read_.get();
  }

  // The emulated device accepts line settings and keeps them; under
  // check=timing each call must match the recorded event at that point.
  void set_baud(unsigned baud) override {
    std::lock_guard<std::mutex> lock(mutex_);
    check_open();
    engine_->client_event(RecordKind::settings, {{event_field::baud, std::to_string(baud)}},
                         replay_now());
    settings_.baud = baud;
  }
  void configure(const SerialSettings& settings) override {
    std::lock_guard<std::mutex> lock(mutex_);
    check_open();
    engine_->client_event(RecordKind::settings,
                         {{event_field::baud, std::to_string(settings.baud)},
                          {event_field::databits, std::to_string(settings.data_bits)},
                          {event_field::stopbits, std::to_string(settings.stop_bits)},
                          {event_field::parity, to_string(settings.parity)},
                          {event_field::flow, to_string(settings.flow)}},
                         replay_now());
    settings_ = settings;
  }
  SerialSettings serial_settings() const override {
    std::lock_guard<std::mutex> lock(mutex_);
    return settings_;
  }
  void set_dtr(bool level) override { modem_line(event_field::dtr, level); }
  void set_rts(bool level) override { modem_line(event_field::rts, level); }
  // The device's lines as the recording released them so far (a modem with
  // the line up where it holds none).
  bool cts() override { return device_lines().cts; }
  bool dsr() override { return device_lines().dsr; }
  bool ri() override { return device_lines().ri; }
  bool cd() override { return device_lines().cd; }
  void send_break(std::chrono::milliseconds duration) override {
    std::lock_guard<std::mutex> lock(mutex_);
    check_open();
    engine_->client_event(RecordKind::line_break,
                         {{event_field::duration_ms, std::to_string(duration.count())}},
                         replay_now());
  }

 protected:
  std::size_t read_some(void* buffer, std::size_t size,
                        Deadline deadline) override {
    std::unique_lock<std::mutex> lock(mutex_);
    for (;;) {
      check_open();
      const auto now = replay_now();
      const std::size_t n =
          awaiting_client_ ? 0 : engine_->read(static_cast<char*>(buffer), size, now);
      const ReplayEngine::Outlook outlook = update_signal(now);
      if (n > 0) {
        reschedule(outlook);
        return n;
      }
      if (outlook.state == ReplayEngine::ReadState::ended) {
        if (engine_->config().at_end == ReplayAtEnd::closed) {
          throw PortClosed(description_ +
                           ": the recording has ended (at_end=closed)");
        }
        if (!deadline) {
          throw PortClosed(description_ +
                           ": the recording has ended and nothing more will "
                           "come; a read without a timeout would block forever");
        }
      }
      if (deadline_passed(now, deadline)) return 0;
      wait(lock, now, deadline, outlook);
    }
  }

  // What read_some would return, left in place: a compound read (a line)
  // then takes it in one read instead of a byte at a time. nullopt where
  // the engine cannot look ahead (a loss or close due, datagrams): the
  // compound read asks read_some, which says what it is.
  std::optional<std::size_t> peek_some(void* buffer, std::size_t size,
                                       Deadline deadline) override {
    std::unique_lock<std::mutex> lock(mutex_);
    for (;;) {
      check_open();
      const auto now = replay_now();
      std::optional<std::size_t> n =
          awaiting_client_ ? 0 : engine_->peek(static_cast<char*>(buffer), size, now);
      if (!n) return std::nullopt;
      const ReplayEngine::Outlook outlook = update_signal(now);
      if (*n > 0) return n;
      if (outlook.state == ReplayEngine::ReadState::ended) {
        if (engine_->config().at_end == ReplayAtEnd::closed || !deadline) return std::nullopt;
      }
      if (deadline_passed(now, deadline)) return 0;
      wait(lock, now, deadline, outlook);
    }
  }

  // A datagram session's next due datagram (see DatagramPort): nothing
  // when none is due; at_end=closed raises at the end as read() does.
  std::optional<std::size_t> read_datagram(void* buffer, std::size_t size) {
    std::lock_guard<std::mutex> lock(mutex_);
    check_open();
    const auto now = replay_now();
    const std::optional<std::size_t> n =
        awaiting_client_ ? std::nullopt
                         : engine_->read_datagram(static_cast<char*>(buffer), size, now);
    const ReplayEngine::Outlook outlook = update_signal(now);
    if (n) {
      reschedule(outlook);
      return n;
    }
    if (outlook.state == ReplayEngine::ReadState::ended &&
        engine_->config().at_end == ReplayAtEnd::closed) {
      throw PortClosed(description_ + ": the recording has ended (at_end=closed)");
    }
    return std::nullopt;
  }

  std::size_t write_some(const void* data, std::size_t size,
                         Deadline deadline) override {
    write_locked(data, size, deadline);
    // After this port's lock is let go: the replays of the other channels
    // take theirs when woken.
    if (config_.member) config_.member->wrote(size, ReplayClock::now());
    return size;
  }

  std::size_t write_locked(const void* data, std::size_t size, Deadline) {
    std::lock_guard<std::mutex> lock(mutex_);
    check_open();
    const auto now = replay_now();
    try {
      engine_->write(static_cast<const char*>(data), size, now);
    } catch (const ReplayMismatch&) {
      mismatched_ = true;
      update_signal(now);
      changed_.notify_all();
      throw;
    } catch (...) {
      update_signal(now);
      changed_.notify_all();
      throw;
    }
    update_signal(now);
    changed_.notify_all();
    return size;
  }

  bool wait_readable_until(Deadline deadline) override {
    std::unique_lock<std::mutex> lock(mutex_);
    for (;;) {
      if (closed_) return true;  // a read raises PortClosed at once
      const auto now = replay_now();
      const ReplayEngine::Outlook outlook = update_signal(now);
      switch (outlook.state) {
        case ReplayEngine::ReadState::readable:
        case ReplayEngine::ReadState::device_gone:
          return true;
        case ReplayEngine::ReadState::ended:
          // at_end=closed, or a read that would block forever: both raise.
          if (engine_->config().at_end == ReplayAtEnd::closed || !deadline) {
            return true;
          }
          break;
        case ReplayEngine::ReadState::waiting:
          break;
      }
      if (deadline_passed(now, deadline)) return false;
      wait(lock, now, deadline, outlook);
    }
  }

 private:
  void client_flushed_locked() {
    engine_->client_flushed();
    update_signal(replay_now());
    changed_.notify_all();
  }

  void open_readiness_pipe() {
    int fds[2];
    if (sys::pipe(fds) != 0) {
      throw PortError(errno, description_ + ": creating the readiness pipe");
    }
    signal_read_.reset(fds[0]);
    signal_write_.reset(fds[1]);
    for (int fd : fds) {
      sys::fcntl(fd, F_SETFL, sys::fcntl(fd, F_GETFL) | O_NONBLOCK);
      sys::fcntl(fd, F_SETFD, FD_CLOEXEC);
    }
  }

  ReplayEngine::Outlook outlook_at(ReplayTime now) {
    if (awaiting_client_) return {ReplayEngine::ReadState::waiting, std::nullopt};
    return engine_->outlook(now);
  }

  // The time the engine is told: the clock's, or the open time of an
  // untimed replay (ReplayConfig::untimed), whose every record is due at
  // once and whose reads then cost no clock read.
  ReplayTime replay_now() const { return frozen_now_ ? *frozen_now_ : ReplayClock::now(); }
  // A deadline is the caller's, on the real clock even in an untimed replay.
  bool deadline_passed(ReplayTime now, Deadline deadline) const {
    return deadline && (frozen_now_ ? ReplayClock::now() : now) >= *deadline;
  }

  void check_open() const {
    if (closed_) throw PortClosed(description_ + " is closed");
  }

  ModemInputs device_lines() {
    std::lock_guard<std::mutex> lock(mutex_);
    check_open();
    if (awaiting_client_) return lines_before_client_;
    lines_before_client_ = engine_->device_lines(replay_now());
    return lines_before_client_;
  }

  void modem_line(const char* line, bool level) {
    std::lock_guard<std::mutex> lock(mutex_);
    check_open();
    engine_->client_event(RecordKind::modem_lines, {{line, level ? "true" : "false"}},
                         replay_now());
  }


  // Blocks a reader until something may have changed: the deadline, the
  // next due time, or a notification. With a scheduler thread, a reader waits
  // to be woken kFinalSpin before the due time (see schedule()) and spins
  // itself through the rest, so that it returns the data on time from its own
  // CPU instead of waiting to be scheduled again after a wake-up at the due
  // time. Deadlines (timeouts) are waited for as usual, without spinning.
  void wait(std::unique_lock<std::mutex>& lock, ReplayTime now,
            Deadline deadline, const ReplayEngine::Outlook& outlook) {
    Deadline due;
    if (outlook.state == ReplayEngine::ReadState::waiting && outlook.wake &&
        (!deadline || *outlook.wake < *deadline)) {
      due = outlook.wake;
    }
    if (due && scheduler_.joinable()) {
      ++readers_awaiting_due_;
      if (*due - now <= kFinalSpin) {
        lock.unlock();
        while (ReplayClock::now() < *due) {
        }
        lock.lock();
      } else {
        changed_.wait_until(lock, *due - kFinalSpin);
      }
      --readers_awaiting_due_;
    } else if (due || deadline) {
      changed_.wait_until(lock, due ? *due : *deadline);
    } else {
      changed_.wait(lock);
    }
  }

  // Keeps the pipe readable exactly when a read would not block on data,
  // once native_handle() has handed it out: before, nobody can poll it, and
  // its two system calls per exchange would be most of what a client that
  // only reads and writes (pyserial through wiretape://) waits for.
  ReplayEngine::Outlook update_signal(ReplayTime now) {
    const ReplayEngine::Outlook outlook = outlook_at(now);
    // Under timing=none, nothing is timed but a strategy's wait (a flush
    // gate's flush_wait): the scheduler starts when one first waits.
    if (outlook.wake && !scheduler_.joinable() && !closed_) {
      scheduler_ = std::thread([this] { schedule(); });
    }
    if (!handle_handed_out_) return outlook;
    const bool readable =
        outlook.state == ReplayEngine::ReadState::readable ||
        outlook.state == ReplayEngine::ReadState::device_gone ||
        (outlook.state == ReplayEngine::ReadState::ended &&
         engine_->config().at_end == ReplayAtEnd::closed);
    if (readable && !signalled_) {
      const char byte = 1;
      while (sys::write(signal_write_.get(), &byte, 1) < 0 && errno == EINTR) {
      }
      signalled_ = true;
    } else if (!readable && signalled_) {
      char scratch[64];
      for (;;) {
        const ssize_t n = sys::read(signal_read_.get(), scratch, sizeof scratch);
        if (n > 0 || (n < 0 && errno == EINTR)) continue;
        break;
      }
      signalled_ = false;
    }
    return outlook;
  }

  // Raises the pipe when timed data falls due, and wakes blocked readers
  // just before.
  //
  // A client blocked in read() sleeps with its own thread's timer slack
  // (50 us by default on Linux, and not ours to change), so it is woken from
  // here instead: this thread asks for precise timers, wakes kFinalSpin
  // before each due time and notifies the readers, which spin through the
  // rest themselves (see wait()). With no reader blocked (a client polling
  // native_handle()), this thread spins to the due time and raises the pipe.
  // Either way at most one thread spins per blocked caller, for at most
  // kFinalSpin per due time: 10 % of a core for records 1 ms apart, nothing
  // while nothing is due; records closer together than kFinalSpin keep it
  // spinning while they play.
  void schedule() {
    platform::precise_timers_for_this_thread();
    std::unique_lock<std::mutex> lock(mutex_);
    while (!closed_) {
      const auto now = ReplayClock::now();
      const ReplayEngine::Outlook outlook = update_signal(now);
      if (outlook.state != ReplayEngine::ReadState::waiting || !outlook.wake) {
        sleep_scheduler(lock, ReplayTime::max());
        continue;
      }
      const ReplayTime due = *outlook.wake;
      if (due - now > kFinalSpin) {
        // Anything may have changed on waking: start over.
        sleep_scheduler(lock, due - kFinalSpin);
        continue;
      }
      if (readers_awaiting_due_ > 0) {
        // They spin to the due time themselves and take the data. Waking at
        // the due time as well would only make this thread compete with them
        // for a core and for the lock; it wakes later, to raise the pipe if
        // they gave up instead.
        changed_.notify_all();
        sleep_scheduler(lock, due + kFinalSpin);
        continue;
      }
      lock.unlock();
      while (ReplayClock::now() < due) {
      }
      lock.lock();
    }
  }

  // The scheduler waits until `until` (max: until notified) and records it,
  // so that others notify it only when it would wake too late.
  void sleep_scheduler(std::unique_lock<std::mutex>& lock, ReplayTime until) {
    scheduler_wake_ = until;
    if (until == ReplayTime::max()) {
      changed_.wait(lock);
    } else {
      changed_.wait_until(lock, until);
    }
    scheduler_wake_ = ReplayTime::min();  // awake: it looks again anyway
  }

  // After a read took data: wakes the scheduler if the next due time falls
  // before it would wake by itself. Skipping the needless wake-up keeps a
  // cross-core wake-up (costly, in virtual machines above all) out of the
  // reader's path in steady play.
  void reschedule(const ReplayEngine::Outlook& outlook) {
    if (!scheduler_.joinable()) return;
    if (outlook.state == ReplayEngine::ReadState::waiting && outlook.wake &&
        *outlook.wake - kFinalSpin < scheduler_wake_) {
      changed_.notify_all();
    }
  }

  // How long before a due time the scheduler stops sleeping and spins: above
  // the usual timer wake-up latency, small against typical record gaps.
  static constexpr std::chrono::microseconds kFinalSpin{100};

  void shut(bool may_throw) {
    std::string unused;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (closed_) return;
      closed_ = true;
      changed_.notify_all();
    }
    // Not woken any more, and no longer holding the other channels back.
    if (config_.member) config_.member->leave();
    if (scheduler_.joinable()) scheduler_.join();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      signal_read_.reset();
      signal_write_.reset();
      const ReplayUnused policy = engine_->config().unused;
      // Asked whatever the policy: rx a flush gate held from a client that
      // wrote past it raises here (sequence.cpp).
      unused = engine_->unused_report();
      left_unused_ = unused;
      if (unused.empty() || policy == ReplayUnused::ignore) return;
      if (policy == ReplayUnused::warn || !may_throw) {
        // After a mismatch what the client left unused follows from it: the
        // mismatch was said, a warning about its consequence is noise.
        if (mismatched_) return;
        std::fprintf(stderr, "wiretape: %s\n", unused.c_str());
        return;
      }
    }
    throw ReplayMismatch(unused + " (unused=error)", 0, 0, -1);
  }

  const std::string description_;
  // The recording, for questions about all of it (the engine reads as the
  // client goes).
  const RecordSourceFactory sources_;
  mutable std::mutex mutex_;
  // A write did not match the recording (ReplayMismatch was raised).
  bool mismatched_ = false;
  // What the client left of the recording, as close() found it (left_unused()).
  std::string left_unused_;
  std::condition_variable changed_;
  const ReplayConfig config_;  // for the engine of each client session
  // What faults left behind, for every client session's engine: a silenced
  // or lost device stays so for the next client (docs/faults.md). The
  // engine made before any client has its own: nobody was served by it.
  const std::shared_ptr<FaultMemory> fault_memory_ = std::make_shared<FaultMemory>();
  // Set for an untimed replay: the time replay_now() tells the engine.
  std::optional<ReplayTime> frozen_now_;
  std::unique_ptr<ReplayEngine> engine_;
  // A virtual device between client sessions: nothing is released to
  // nobody (see await_client()).
  bool awaiting_client_ = false;
  // The lines the last client session left, seen until the next begins.
  ModemInputs lines_before_client_;
  int client_sessions_ = 0;
  SerialSettings settings_ = config_.recorded_settings;
  std::function<void(const FaultEvent&)> fault_reporter_;  // empty: stderr
  bool closed_ = false;
  sys::UniqueFd signal_read_;
  sys::UniqueFd signal_write_;
  bool signalled_ = false;
  mutable bool handle_handed_out_ = false;  // see update_signal()
  int readers_awaiting_due_ = 0;  // threads in wait() for a due time
  ReplayTime scheduler_wake_ = ReplayTime::min();  // see sleep_scheduler()
  std::thread scheduler_;
};

// A replay of a session recorded over udp: empty datagrams too are served
// and checked (a Port's read of 0 bytes and write of 0 bytes cannot say
// them), for the bridge's udp endpoint.
class DatagramReplayPort final : public ReplayPort, public DatagramPort {
 public:
  using ReplayPort::ReplayPort;

  std::optional<std::size_t> receive_datagram(void* buffer, std::size_t size) override {
    return read_datagram(buffer, size);
  }
  bool send_empty_datagram() override {
    write_some("", 0, std::nullopt);  // the engine checks it (or ignores it, with a profile)
    return true;
  }
  std::uint64_t datagrams_from_others() const override { return 0; }
  int take_error() override { return 0; }
};

}  // namespace

std::unique_ptr<Port> open_replay_session(ReplayConfig config,
                                          RecordSourceFactory sources) {
  if (config.datagrams) {
    return std::make_unique<DatagramReplayPort>(std::move(config), std::move(sources));
  }
  return std::make_unique<ReplayPort>(std::move(config), std::move(sources));
}

bool replay_read_would_block_forever(Port& port) {
  auto* replay = dynamic_cast<ReplayPort*>(&port);
  return replay != nullptr && replay->read_would_block_forever();
}

bool replay_await_client(Port& port) {
  auto* replay = dynamic_cast<ReplayPort*>(&port);
  if (replay == nullptr) return false;
  replay->await_client();
  return true;
}

bool replay_begin_client_session(Port& port) {
  auto* replay = dynamic_cast<ReplayPort*>(&port);
  return replay != nullptr && replay->begin_client_session();
}

void replay_client_flushed(Port& port) {
  if (auto* replay = dynamic_cast<ReplayPort*>(&port)) replay->client_flushed();
}

bool replay_recording_greets(const Port& port) {
  const auto* replay = dynamic_cast<const ReplayPort*>(&port);
  return replay != nullptr && replay->recording_greets();
}

bool replay_lost_by_fault(Port& port) {
  auto* replay = dynamic_cast<ReplayPort*>(&port);
  return replay != nullptr && replay->lost_by_fault();
}

std::string replay_silenced_by_fault(Port& port) {
  auto* replay = dynamic_cast<ReplayPort*>(&port);
  return replay != nullptr ? replay->silenced_by_fault() : std::string();
}

bool replay_recording_has_rx(const Port& port) {
  const auto* replay = dynamic_cast<const ReplayPort*>(&port);
  return replay != nullptr && replay->recording_has_rx();
}

}  // namespace wiretape::detail
