/* The LD_PRELOAD shim that runs a command on a clock K times faster than
 * real time (`wiretape replay ... --speed K -- CMD`, `wiretape faults
 * --speed K`; DESIGN §22, docs/replay.md "Faster than real time").
 *
 * Scaled clocks (REALTIME, MONOTONIC, MONOTONIC_RAW, BOOTTIME and the
 * _COARSE variants) read  anchor + (real - anchor) * K, where the anchor is
 * a point shared by CMD and every process it starts (WIRETAPE_CLOCK_ANCHOR,
 * set by wiretape or, when missing, by the first process that loads the
 * shim), so a child's clocks go on from its parent's. Absolute deadlines
 * are converted back to real time (anchor + (deadline - anchor) / K) and
 * relative ones divided by K. CPU-time clocks are never scaled.
 *
 * A slowed clock (K < 1) leaves CMD's code as fast as ever: a wait of zero
 * that finds nothing (a timeout that rounded down to 0 ms while less than
 * 1 ms was left, a zero sleep in a loop until a deadline) would spin 1/K
 * times longer than at K = 1, a million times at K = 1e-6. So there a zero
 * wait lasts the least span a wait can have on CMD's clock (1 us), in real
 * time at most 1 ms: it still returns as soon as a descriptor is ready.
 *
 * Not libfaketime: 0.9.10 with `x10` hangs futex waits on CLOCK_MONOTONIC
 * deadlines (Python's Lock.acquire(timeout=) goes through sem_clockwait),
 * which this shim converts like every other deadline.
 *
 * Hooks allocate nothing, keep errno as the real call leaves it, and only
 * read state written once at load. */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE
#endif
#include <dlfcn.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <poll.h>
#include <pthread.h>
#include <semaphore.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/select.h>
#include <sys/time.h>
#include <sys/timerfd.h>
#include <time.h>
#include <unistd.h>

#define EXPORT __attribute__((visibility("default")))

enum { NS_PER_S = 1000000000 };

/* The environment the shim reads (python/wiretape/scaled_clock.py). */
static const char kSpeedVariable[] = "WIRETAPE_CLOCK_SPEED";
static const char kAnchorVariable[] = "WIRETAPE_CLOCK_ANCHOR";

/* The clocks scaled, each with its own anchor (the anchors are read at one
 * instant). The _COARSE clocks share their fine clock's anchor. */
enum { ANCHOR_REALTIME, ANCHOR_MONOTONIC, ANCHOR_RAW, ANCHOR_BOOTTIME, ANCHOR_COUNT };
static const clockid_t kAnchorClocks[ANCHOR_COUNT] = {CLOCK_REALTIME, CLOCK_MONOTONIC,
                                                      CLOCK_MONOTONIC_RAW, CLOCK_BOOTTIME};

/* A zero wait under a slowed clock (see the top of the file): 1 us of CMD's
 * clock, at most 1 ms of real time. */
enum { LEAST_WAIT_NS = 1000, LONGEST_NAP_NS = 1000000 };

static double g_speed = 1.0;
static int64_t g_nap_ns; /* 0: a zero wait returns at once (K >= 1) */
static int64_t g_anchor[ANCHOR_COUNT];
static int g_scaling; /* 0: every hook passes through (K = 1 or no K) */
static int g_ready;

typedef int (*clock_gettime_fn)(clockid_t, struct timespec *);
typedef int (*clock_nanosleep_fn)(clockid_t, int, const struct timespec *, struct timespec *);
typedef int (*nanosleep_fn)(const struct timespec *, struct timespec *);
typedef int (*select_fn)(int, fd_set *, fd_set *, fd_set *, struct timeval *);
typedef int (*pselect_fn)(int, fd_set *, fd_set *, fd_set *, const struct timespec *,
                          const sigset_t *);
typedef int (*poll_fn)(struct pollfd *, nfds_t, int);
typedef int (*ppoll_fn)(struct pollfd *, nfds_t, const struct timespec *, const sigset_t *);
typedef int (*epoll_wait_fn)(int, struct epoll_event *, int, int);
typedef int (*epoll_pwait_fn)(int, struct epoll_event *, int, int, const sigset_t *);
typedef int (*cond_clockwait_fn)(pthread_cond_t *, pthread_mutex_t *, clockid_t,
                                 const struct timespec *);
typedef int (*sem_clockwait_fn)(sem_t *, clockid_t, const struct timespec *);
typedef int (*mutex_clocklock_fn)(pthread_mutex_t *, clockid_t, const struct timespec *);
typedef int (*timerfd_settime_fn)(int, int, const struct itimerspec *, struct itimerspec *);
typedef int (*timerfd_gettime_fn)(int, struct itimerspec *);
typedef int (*setitimer_fn)(int, const struct itimerval *, struct itimerval *);
typedef int (*getitimer_fn)(int, struct itimerval *);
typedef int (*sigtimedwait_fn)(const sigset_t *, siginfo_t *, const struct timespec *);

static struct {
  clock_gettime_fn clock_gettime;
  clock_nanosleep_fn clock_nanosleep;
  nanosleep_fn nanosleep;
  select_fn select;
  pselect_fn pselect;
  poll_fn poll;
  ppoll_fn ppoll;
  epoll_wait_fn epoll_wait;
  epoll_pwait_fn epoll_pwait;
  cond_clockwait_fn cond_clockwait;
  sem_clockwait_fn sem_clockwait;
  mutex_clocklock_fn mutex_clocklock;
  timerfd_settime_fn timerfd_settime;
  timerfd_gettime_fn timerfd_gettime;
  setitimer_fn setitimer;
  getitimer_fn getitimer;
  sigtimedwait_fn sigtimedwait;
} real;

static int64_t ns_of(const struct timespec *ts) {
  return (int64_t)ts->tv_sec * NS_PER_S + ts->tv_nsec;
}

static struct timespec timespec_of(int64_t ns) {
  struct timespec ts;
  ts.tv_sec = (time_t)(ns / NS_PER_S);
  ts.tv_nsec = (long)(ns % NS_PER_S);
  if (ts.tv_nsec < 0) {
    ts.tv_nsec += NS_PER_S;
    ts.tv_sec -= 1;
  }
  return ts;
}

/* A double of nanoseconds as an int64, saturated (a deadline of "forever"
 * slowed down by K < 1 must not wrap around into the past). */
static int64_t saturated(double ns) {
  if (ns >= 9.2e18) return INT64_MAX / 2;
  if (ns <= -9.2e18) return INT64_MIN / 2;
  return (int64_t)ns;
}

static int anchor_index(clockid_t clock) {
  switch (clock) {
    case CLOCK_REALTIME:
    case CLOCK_REALTIME_COARSE:
      return ANCHOR_REALTIME;
    case CLOCK_MONOTONIC:
    case CLOCK_MONOTONIC_COARSE:
      return ANCHOR_MONOTONIC;
    case CLOCK_MONOTONIC_RAW:
      return ANCHOR_RAW;
    case CLOCK_BOOTTIME:
      return ANCHOR_BOOTTIME;
    default:
      return -1; /* CPU-time and other clocks run at their own pace */
  }
}

static int parse_anchor(const char *text) {
  /* "REALTIME,MONOTONIC,RAW,BOOTTIME" in nanoseconds. */
  for (int i = 0; i < ANCHOR_COUNT; ++i) {
    char *end = NULL;
    errno = 0;
    long long value = strtoll(text, &end, 10);
    if (errno != 0 || end == text) return 0;
    g_anchor[i] = value;
    if (i + 1 < ANCHOR_COUNT) {
      if (*end != ',') return 0;
      text = end + 1;
    } else if (*end != '\0') {
      return 0;
    }
  }
  return 1;
}

static void *next_symbol(const char *name) { return dlsym(RTLD_NEXT, name); }

static void initialise(void) {
  if (__atomic_load_n(&g_ready, __ATOMIC_ACQUIRE)) return;
  int saved = errno;
  real.clock_gettime = (clock_gettime_fn)next_symbol("clock_gettime");
  real.clock_nanosleep = (clock_nanosleep_fn)next_symbol("clock_nanosleep");
  real.nanosleep = (nanosleep_fn)next_symbol("nanosleep");
  real.select = (select_fn)next_symbol("select");
  real.pselect = (pselect_fn)next_symbol("pselect");
  real.poll = (poll_fn)next_symbol("poll");
  real.ppoll = (ppoll_fn)next_symbol("ppoll");
  real.epoll_wait = (epoll_wait_fn)next_symbol("epoll_wait");
  real.epoll_pwait = (epoll_pwait_fn)next_symbol("epoll_pwait");
  real.cond_clockwait = (cond_clockwait_fn)next_symbol("pthread_cond_clockwait");
  real.sem_clockwait = (sem_clockwait_fn)next_symbol("sem_clockwait");
  real.mutex_clocklock = (mutex_clocklock_fn)next_symbol("pthread_mutex_clocklock");
  real.timerfd_settime = (timerfd_settime_fn)next_symbol("timerfd_settime");
  real.timerfd_gettime = (timerfd_gettime_fn)next_symbol("timerfd_gettime");
  real.setitimer = (setitimer_fn)next_symbol("setitimer");
  real.getitimer = (getitimer_fn)next_symbol("getitimer");
  real.sigtimedwait = (sigtimedwait_fn)next_symbol("sigtimedwait");

  const char *speed_text = getenv(kSpeedVariable);
  double speed = 1.0;
  if (speed_text != NULL && *speed_text != '\0') {
    char *end = NULL;
    speed = strtod(speed_text, &end);
    if (end == speed_text || *end != '\0' || !isfinite(speed) || speed <= 0) {
      fprintf(stderr, "wiretape scaled clock: %s=%s is not a number above 0: the clock is "
                      "not scaled\n", kSpeedVariable, speed_text);
      speed = 1.0;
    }
  }
  g_speed = speed;
  int every_call_found = real.clock_gettime && real.clock_nanosleep && real.nanosleep &&
                         real.cond_clockwait && real.sem_clockwait && real.mutex_clocklock;
  g_scaling = speed != 1.0 && every_call_found;
  if (g_scaling && speed < 1.0 && real.ppoll != NULL && real.pselect != NULL) {
    double nap = (double)LEAST_WAIT_NS / speed;
    g_nap_ns = nap > LONGEST_NAP_NS ? LONGEST_NAP_NS : (int64_t)nap;
  }
  if (g_scaling) {
    const char *anchor_text = getenv(kAnchorVariable);
    if (anchor_text == NULL || !parse_anchor(anchor_text)) {
      /* Run without wiretape: this process is the anchor of its children. */
      struct timespec now;
      for (int i = 0; i < ANCHOR_COUNT; ++i) {
        real.clock_gettime(kAnchorClocks[i], &now);
        g_anchor[i] = ns_of(&now);
      }
      char text[128];
      snprintf(text, sizeof text, "%lld,%lld,%lld,%lld", (long long)g_anchor[0],
               (long long)g_anchor[1], (long long)g_anchor[2], (long long)g_anchor[3]);
      setenv(kAnchorVariable, text, 1);
    }
  }
  errno = saved;
  __atomic_store_n(&g_ready, 1, __ATOMIC_RELEASE);
}

__attribute__((constructor)) static void load(void) { initialise(); }

/* Real nanoseconds of a scaled clock -> scaled, and back. */
static int64_t scaled_of_real(int anchor, int64_t real_ns) {
  int64_t origin = g_anchor[anchor];
  return origin + saturated((double)(real_ns - origin) * g_speed);
}

static int64_t real_of_scaled(int anchor, int64_t scaled_ns) {
  int64_t origin = g_anchor[anchor];
  return origin + saturated((double)(scaled_ns - origin) / g_speed);
}

static int64_t real_span(int64_t scaled_ns) { return saturated((double)scaled_ns / g_speed); }

static int64_t scaled_span(int64_t real_ns) { return saturated((double)real_ns * g_speed); }

static struct timespec real_deadline(clockid_t clock, const struct timespec *deadline) {
  return timespec_of(real_of_scaled(anchor_index(clock), ns_of(deadline)));
}

static int64_t real_now(clockid_t clock) {
  struct timespec now;
  real.clock_gettime(clock, &now);
  return ns_of(&now);
}

static int is_zero(const struct timespec *span) { return span->tv_sec == 0 && span->tv_nsec == 0; }

/* The real wait a zero wait becomes (see g_nap_ns). */
static struct timespec nap(void) { return timespec_of(g_nap_ns); }

/* A zero-length sleep under a slowed clock: the nap (nothing is left of a
 * zero sleep should a signal interrupt it). */
static int napped(struct timespec *remaining) {
  struct timespec span = nap();
  int result = real.nanosleep(&span, NULL);
  if (result != 0 && remaining != NULL) {
    int saved = errno;
    remaining->tv_sec = 0;
    remaining->tv_nsec = 0;
    errno = saved;
  }
  return result;
}

/* An absolute deadline on CMD's clock, in real time; under a slowed clock
 * one that has passed already is the nap from now (a zero wait). */
static struct timespec real_deadline_or_nap(clockid_t clock, const struct timespec *deadline) {
  struct timespec converted = real_deadline(clock, deadline);
  if (g_nap_ns > 0) {
    int64_t now = real_now(clock);
    if (ns_of(&converted) <= now) converted = timespec_of(now + g_nap_ns);
  }
  return converted;
}

/* Whether an absolute deadline whose clock the call does not say (a
 * condition variable's attribute, a timerfd's clock) is on REALTIME or
 * MONOTONIC: the one whose scaled now is nearer (decades apart). */
static clockid_t clock_of_deadline(const struct timespec *deadline) {
  int64_t target = ns_of(deadline);
  int64_t realtime = scaled_of_real(ANCHOR_REALTIME, real_now(CLOCK_REALTIME));
  int64_t monotonic = scaled_of_real(ANCHOR_MONOTONIC, real_now(CLOCK_MONOTONIC));
  double to_realtime = fabs((double)target - (double)realtime);
  double to_monotonic = fabs((double)target - (double)monotonic);
  return to_realtime < to_monotonic ? CLOCK_REALTIME : CLOCK_MONOTONIC;
}

/* ---- clocks ------------------------------------------------------------ */

EXPORT int clock_gettime(clockid_t clock, struct timespec *ts) {
  initialise();
  int result = real.clock_gettime(clock, ts);
  int anchor = anchor_index(clock);
  if (result == 0 && g_scaling && anchor >= 0) *ts = timespec_of(scaled_of_real(anchor, ns_of(ts)));
  return result;
}

EXPORT int gettimeofday(struct timeval *tv, void *timezone) {
  (void)timezone; /* obsolete: glibc fills nothing either */
  struct timespec now;
  clock_gettime(CLOCK_REALTIME, &now);
  tv->tv_sec = now.tv_sec;
  tv->tv_usec = now.tv_nsec / 1000;
  return 0;
}

EXPORT time_t time(time_t *out) {
  struct timespec now;
  clock_gettime(CLOCK_REALTIME, &now);
  if (out != NULL) *out = now.tv_sec;
  return now.tv_sec;
}

/* ---- sleeps ------------------------------------------------------------ */

EXPORT int clock_nanosleep(clockid_t clock, int flags, const struct timespec *request,
                           struct timespec *remaining) {
  initialise();
  if (!g_scaling || anchor_index(clock) < 0 || request == NULL)
    return real.clock_nanosleep(clock, flags, request, remaining);
  if (flags & TIMER_ABSTIME) {
    /* A deadline now or past (Python's time.sleep(0)) is a zero sleep. */
    struct timespec deadline = real_deadline_or_nap(clock, request);
    return real.clock_nanosleep(clock, flags, &deadline, remaining);
  }
  if (g_nap_ns > 0 && is_zero(request)) {
    struct timespec span = nap();
    return real.clock_nanosleep(clock, 0, &span, NULL);
  }
  struct timespec span = timespec_of(real_span(ns_of(request)));
  int result = real.clock_nanosleep(clock, flags, &span, remaining);
  if (result == EINTR && remaining != NULL) *remaining = timespec_of(scaled_span(ns_of(remaining)));
  return result;
}

EXPORT int nanosleep(const struct timespec *request, struct timespec *remaining) {
  initialise();
  if (!g_scaling || request == NULL) return real.nanosleep(request, remaining);
  if (g_nap_ns > 0 && is_zero(request)) return napped(remaining);
  struct timespec span = timespec_of(real_span(ns_of(request)));
  int result = real.nanosleep(&span, remaining);
  if (result != 0 && errno == EINTR && remaining != NULL) {
    int saved = errno;
    *remaining = timespec_of(scaled_span(ns_of(remaining)));
    errno = saved;
  }
  return result;
}

EXPORT int usleep(useconds_t microseconds) {
  struct timespec request = timespec_of((int64_t)microseconds * 1000);
  return nanosleep(&request, NULL);
}

EXPORT unsigned int sleep(unsigned int seconds) {
  struct timespec request = {(time_t)seconds, 0};
  struct timespec remaining = {0, 0};
  if (nanosleep(&request, &remaining) == 0) return 0;
  return (unsigned int)remaining.tv_sec + (remaining.tv_nsec > 0);
}

/* ---- waits on descriptors ---------------------------------------------- */

/* A timeout in milliseconds divided by K; never 0 when it was not (0 polls). */
static int real_milliseconds(int milliseconds) {
  if (!g_scaling || milliseconds <= 0) return milliseconds;
  double span = ceil((double)milliseconds / g_speed);
  return span < 1 ? 1 : span > INT_MAX ? INT_MAX : (int)span;
}

EXPORT int select(int count, fd_set *readable, fd_set *writable, fd_set *exceptional,
                  struct timeval *timeout) {
  initialise();
  if (!g_scaling || timeout == NULL) return real.select(count, readable, writable, exceptional, timeout);
  if (g_nap_ns > 0 && timeout->tv_sec == 0 && timeout->tv_usec == 0) {
    struct timespec span = nap();
    return real.pselect(count, readable, writable, exceptional, &span, NULL);
  }
  int64_t span = real_span(((int64_t)timeout->tv_sec * 1000000 + timeout->tv_usec) * 1000);
  struct timeval scaled = {(time_t)(span / NS_PER_S), (suseconds_t)((span % NS_PER_S) / 1000)};
  int result = real.select(count, readable, writable, exceptional, &scaled);
  int saved = errno;
  /* Linux writes back what is left: on CMD's clock. */
  int64_t left = scaled_span(((int64_t)scaled.tv_sec * 1000000 + scaled.tv_usec) * 1000);
  timeout->tv_sec = (time_t)(left / NS_PER_S);
  timeout->tv_usec = (suseconds_t)((left % NS_PER_S) / 1000);
  errno = saved;
  return result;
}

EXPORT int pselect(int count, fd_set *readable, fd_set *writable, fd_set *exceptional,
                   const struct timespec *timeout, const sigset_t *mask) {
  initialise();
  if (!g_scaling || timeout == NULL)
    return real.pselect(count, readable, writable, exceptional, timeout, mask);
  struct timespec span = g_nap_ns > 0 && is_zero(timeout) ? nap()
                                                           : timespec_of(real_span(ns_of(timeout)));
  return real.pselect(count, readable, writable, exceptional, &span, mask);
}

EXPORT int poll(struct pollfd *fds, nfds_t count, int milliseconds) {
  initialise();
  if (g_nap_ns > 0 && milliseconds == 0) {
    struct timespec span = nap();
    return real.ppoll(fds, count, &span, NULL);
  }
  return real.poll(fds, count, real_milliseconds(milliseconds));
}

EXPORT int ppoll(struct pollfd *fds, nfds_t count, const struct timespec *timeout,
                 const sigset_t *mask) {
  initialise();
  if (!g_scaling || timeout == NULL) return real.ppoll(fds, count, timeout, mask);
  struct timespec span = g_nap_ns > 0 && is_zero(timeout) ? nap()
                                                           : timespec_of(real_span(ns_of(timeout)));
  return real.ppoll(fds, count, &span, mask);
}

/* A zero wait on an epoll set under a slowed clock: the set's own
 * descriptor is readable while an event is ready, so the nap is a ppoll of
 * it, and the events are then taken as the caller asked. */
static int epoll_napped(int epoll, struct epoll_event *events, int capacity,
                        const sigset_t *mask) {
  int ready = real.epoll_pwait(epoll, events, capacity, 0, mask);
  if (ready != 0) return ready;
  struct pollfd set = {epoll, POLLIN, 0};
  struct timespec span = nap();
  if (real.ppoll(&set, 1, &span, mask) <= 0) return 0; /* the nap, or its interruption */
  return real.epoll_pwait(epoll, events, capacity, 0, mask);
}

EXPORT int epoll_wait(int epoll, struct epoll_event *events, int capacity, int milliseconds) {
  initialise();
  if (g_nap_ns > 0 && milliseconds == 0 && real.epoll_pwait != NULL)
    return epoll_napped(epoll, events, capacity, NULL);
  return real.epoll_wait(epoll, events, capacity, real_milliseconds(milliseconds));
}

EXPORT int epoll_pwait(int epoll, struct epoll_event *events, int capacity, int milliseconds,
                       const sigset_t *mask) {
  initialise();
  if (g_nap_ns > 0 && milliseconds == 0) return epoll_napped(epoll, events, capacity, mask);
  return real.epoll_pwait(epoll, events, capacity, real_milliseconds(milliseconds), mask);
}

/* ---- timed waits of threads (futex deadlines) --------------------------- */

EXPORT int pthread_cond_clockwait(pthread_cond_t *cond, pthread_mutex_t *mutex, clockid_t clock,
                                  const struct timespec *deadline) {
  initialise();
  if (!g_scaling || anchor_index(clock) < 0)
    return real.cond_clockwait(cond, mutex, clock, deadline);
  struct timespec converted = real_deadline_or_nap(clock, deadline);
  return real.cond_clockwait(cond, mutex, clock, &converted);
}

/* The condition's own clock (pthread_condattr_setclock) is not in its
 * public interface: the deadline tells it, and the real wait is on it. */
EXPORT int pthread_cond_timedwait(pthread_cond_t *cond, pthread_mutex_t *mutex,
                                  const struct timespec *deadline) {
  initialise();
  clockid_t clock = CLOCK_REALTIME;
  if (g_scaling) {
    int saved = errno;
    clock = clock_of_deadline(deadline);
    errno = saved;
  } else {
    /* Unscaled, the condition's own clock must be kept: find it the same way. */
    int64_t target = ns_of(deadline);
    double to_realtime = fabs((double)target - (double)real_now(CLOCK_REALTIME));
    double to_monotonic = fabs((double)target - (double)real_now(CLOCK_MONOTONIC));
    clock = to_realtime < to_monotonic ? CLOCK_REALTIME : CLOCK_MONOTONIC;
  }
  return pthread_cond_clockwait(cond, mutex, clock, deadline);
}

EXPORT int sem_clockwait(sem_t *semaphore, clockid_t clock, const struct timespec *deadline) {
  initialise();
  if (!g_scaling || anchor_index(clock) < 0)
    return real.sem_clockwait(semaphore, clock, deadline);
  struct timespec converted = real_deadline_or_nap(clock, deadline);
  return real.sem_clockwait(semaphore, clock, &converted);
}

EXPORT int sem_timedwait(sem_t *semaphore, const struct timespec *deadline) {
  return sem_clockwait(semaphore, CLOCK_REALTIME, deadline);
}

EXPORT int pthread_mutex_clocklock(pthread_mutex_t *mutex, clockid_t clock,
                                   const struct timespec *deadline) {
  initialise();
  if (!g_scaling || anchor_index(clock) < 0)
    return real.mutex_clocklock(mutex, clock, deadline);
  struct timespec converted = real_deadline_or_nap(clock, deadline);
  return real.mutex_clocklock(mutex, clock, &converted);
}

EXPORT int pthread_mutex_timedlock(pthread_mutex_t *mutex, const struct timespec *deadline) {
  return pthread_mutex_clocklock(mutex, CLOCK_REALTIME, deadline);
}

EXPORT int sigtimedwait(const sigset_t *set, siginfo_t *info, const struct timespec *timeout) {
  initialise();
  if (!g_scaling || timeout == NULL) return real.sigtimedwait(set, info, timeout);
  struct timespec span = g_nap_ns > 0 && is_zero(timeout) ? nap()
                                                           : timespec_of(real_span(ns_of(timeout)));
  return real.sigtimedwait(set, info, &span);
}

/* ---- timers ------------------------------------------------------------- */

static struct timespec scaled_down(const struct timespec *span) {
  return timespec_of(real_span(ns_of(span)));
}

static struct timespec scaled_up(const struct timespec *span) {
  return timespec_of(scaled_span(ns_of(span)));
}

EXPORT int timerfd_settime(int timer, int flags, const struct itimerspec *value,
                           struct itimerspec *previous) {
  initialise();
  if (!g_scaling || value == NULL) return real.timerfd_settime(timer, flags, value, previous);
  struct itimerspec converted;
  converted.it_interval = scaled_down(&value->it_interval);
  int zero = value->it_value.tv_sec == 0 && value->it_value.tv_nsec == 0;  /* disarms */
  if (zero) {
    converted.it_value = value->it_value;
  } else if (flags & TFD_TIMER_ABSTIME) {
    int saved = errno;
    converted.it_value = real_deadline(clock_of_deadline(&value->it_value), &value->it_value);
    errno = saved;
  } else {
    converted.it_value = scaled_down(&value->it_value);
  }
  int result = real.timerfd_settime(timer, flags, &converted, previous);
  if (result == 0 && previous != NULL) {
    previous->it_interval = scaled_up(&previous->it_interval);
    previous->it_value = scaled_up(&previous->it_value);
  }
  return result;
}

EXPORT int timerfd_gettime(int timer, struct itimerspec *current) {
  initialise();
  int result = real.timerfd_gettime(timer, current);
  if (result == 0 && g_scaling && current != NULL) {
    current->it_interval = scaled_up(&current->it_interval);
    current->it_value = scaled_up(&current->it_value);
  }
  return result;
}

static struct timeval timeval_scaled(const struct timeval *span, int down) {
  int64_t ns = ((int64_t)span->tv_sec * 1000000 + span->tv_usec) * 1000;
  int64_t scaled = down ? real_span(ns) : scaled_span(ns);
  if (down && ns > 0 && scaled < 1000) scaled = 1000; /* 0 would disarm */
  struct timeval out = {(time_t)(scaled / NS_PER_S), (suseconds_t)((scaled % NS_PER_S) / 1000)};
  return out;
}

/* Only ITIMER_REAL counts wall time; the others count CPU time. */
EXPORT int setitimer(__itimer_which_t which, const struct itimerval *value,
                     struct itimerval *previous) {
  initialise();
  if (!g_scaling || which != ITIMER_REAL || value == NULL)
    return real.setitimer(which, value, previous);
  struct itimerval converted = {timeval_scaled(&value->it_interval, 1),
                                timeval_scaled(&value->it_value, 1)};
  if (value->it_value.tv_sec == 0 && value->it_value.tv_usec == 0) converted.it_value = value->it_value;
  if (value->it_interval.tv_sec == 0 && value->it_interval.tv_usec == 0)
    converted.it_interval = value->it_interval;
  int result = real.setitimer(which, &converted, previous);
  if (result == 0 && previous != NULL) {
    previous->it_interval = timeval_scaled(&previous->it_interval, 0);
    previous->it_value = timeval_scaled(&previous->it_value, 0);
  }
  return result;
}

EXPORT int getitimer(__itimer_which_t which, struct itimerval *current) {
  initialise();
  int result = real.getitimer(which, current);
  if (result == 0 && g_scaling && which == ITIMER_REAL && current != NULL) {
    current->it_interval = timeval_scaled(&current->it_interval, 0);
    current->it_value = timeval_scaled(&current->it_value, 0);
  }
  return result;
}

EXPORT unsigned int alarm(unsigned int seconds) {
  struct itimerval value = {{0, 0}, {(time_t)seconds, 0}};
  struct itimerval previous = {{0, 0}, {0, 0}};
  if (setitimer(ITIMER_REAL, &value, &previous) != 0) return 0;
  /* As glibc: a partial second left counts as one. */
  return (unsigned int)previous.it_value.tv_sec + (previous.it_value.tv_usec > 0);
}
