/* Serial lines on the redirected descriptor (DESIGN §20, docs/replay.md
 * "Serial lines under --as").
 *
 * A pty has no modem lines, break or custom baud, so on the descriptors
 * redirect_device.c opened on a virtual device this file answers the
 * ioctls drivers make for them, and tells that device's bridge what the
 * client set through its side channel (src/shim/line_protocol.h; not the
 * data path): WIRETAPE_LINE_CHANNEL for device 0, WIRETAPE_LINE_CHANNEL_N
 * for device N (up to WIRETAPE_SHIM_DEVICES, each with its own connection,
 * counts and emulated lines). Every other descriptor, and every ioctl not
 * listed in docs/replay.md, goes to libc untouched: the real result and
 * errno.
 *
 * Which descriptors are redirected is an atomic bitmap kept through open,
 * dup, dup2, dup3, fcntl(F_DUPFD) and close, with beside it the device each
 * one is. Writes to them are counted, so that each message says how many
 * client bytes of its device precede it.
 *
 * C only, no allocation after start-up, errno preserved where the call
 * succeeds as libc's would, thread-safe (one request at a time per process,
 * under a mutex), fork-safe (a child connects anew, its count from zero).
 * Without a channel (the variable unset, or the bridge gone) the lines are
 * emulated in the process alone: outputs remembered, CTS, DSR and CD
 * asserted. */

#define _GNU_SOURCE
#undef _FORTIFY_SOURCE
/* The kernel's termios2 and ioctl numbers; glibc's <termios.h> and
 * <sys/ioctl.h> would clash with them, so nothing here includes those. */
#include <asm/termios.h>
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <linux/serial.h>
#include <poll.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <sys/types.h>
#include <sys/uio.h>
#include <sys/un.h>
#include <unistd.h>

#include "line_protocol.h"
#include "serial_lines.h"

int ioctl(int fd, unsigned long request, ...);
struct termios;
int tcsetattr(int fd, int action, const struct termios *settings);
int tcsendbreak(int fd, int duration);
int tcdrain(int fd);

/* Descriptors beyond this are never redirected (not tracked). */
#define TRACKED_FDS 65536
/* Inherited descriptors are looked for among the first ones only. */
#define INHERITED_FDS_CHECKED 256
#define BITS_PER_WORD (8 * sizeof(unsigned long))
static _Atomic unsigned long redirected_fds[TRACKED_FDS / BITS_PER_WORD];
/* The device each redirected descriptor is (valid where its bit is set). */
static _Atomic unsigned char device_of_fd[TRACKED_FDS];
/* Any descriptor ever redirected: spares unrelated calls the bitmap. */
static atomic_int any_redirected;

/* One redirected device: its side channel, counts and emulated lines. */
struct line_device {
  atomic_uint_fast64_t written_since_hello;
  atomic_uint_fast64_t bytes_written;
  atomic_uint_fast64_t bytes_read;
  char channel_path[sizeof(((struct sockaddr_un *)0)->sun_path)];
  pthread_mutex_t channel_lock;
  int channel_fd;
  int channel_unavailable;
  /* The process's own view when there is no channel. */
  atomic_uint local_outputs;
  pthread_mutex_t stored_lock;
  struct serial_struct stored_serial;
  struct serial_rs485 stored_rs485;
};

static struct line_device devices[WIRETAPE_SHIM_DEVICES] = {
    [0 ... WIRETAPE_SHIM_DEVICES - 1] = {.channel_lock = PTHREAD_MUTEX_INITIALIZER,
                                         .channel_fd = -1,
                                         .local_outputs = TIOCM_DTR | TIOCM_RTS,
                                         .stored_lock = PTHREAD_MUTEX_INITIALIZER}};

const char *wiretape_device_variable(const char *name, int device) {
  if (device == 0) return getenv(name);
  char indexed[64];
  int length = snprintf(indexed, sizeof indexed, "%s_%d", name, device);
  if (length <= 0 || (size_t)length >= sizeof indexed) return NULL;
  return getenv(indexed);
}

/* libc's functions, looked up at start-up (lazily if called before). */
static ssize_t (*real_write)(int, const void *, size_t);
static ssize_t (*real_read)(int, void *, size_t);
static ssize_t (*real_writev)(int, const struct iovec *, int);
static int (*real_close)(int);
static int (*real_dup)(int);
static int (*real_dup2)(int, int);
static int (*real_dup3)(int, int, int);
static int (*real_fcntl)(int, int, ...);
static int (*real_fcntl64)(int, int, ...);
static int (*real_ioctl)(int, unsigned long, ...);
static int (*real_tcsetattr)(int, int, const struct termios *);
static int (*real_tcsendbreak)(int, int);
static int (*real_tcdrain)(int);

#define RESOLVE(name) \
  (real_##name != NULL ? 1 : ((real_##name = (__typeof__(real_##name))dlsym(RTLD_NEXT, #name)) != NULL))

static void resolve_all(void) {
  RESOLVE(write), RESOLVE(read), RESOLVE(writev), RESOLVE(close), RESOLVE(dup), RESOLVE(dup2),
      RESOLVE(dup3), RESOLVE(fcntl), RESOLVE(fcntl64), RESOLVE(ioctl), RESOLVE(tcsetattr), RESOLVE(tcsendbreak),
      RESOLVE(tcdrain);
}

/* The child of a fork shares the parent's connection: it must not speak on
 * it (their requests and replies would interleave). */
static void forked_child(void) {
  for (int index = 0; index < WIRETAPE_SHIM_DEVICES; ++index) {
    struct line_device *device = &devices[index];
    if (device->channel_fd >= 0) syscall(SYS_close, device->channel_fd);
    device->channel_fd = -1;
    device->channel_unavailable = 0;
    atomic_store(&device->written_since_hello, 0);
    pthread_mutex_init(&device->channel_lock, NULL);
    pthread_mutex_init(&device->stored_lock, NULL);
  }
}

static void mark(int fd, int device);
static void unmark(int fd);
static int ensure_connected(struct line_device *device);

/* Descriptors this program inherited open on the pty (a shell's `prog
 * </dev/ttyUSB0`, a launcher that opened the device and exec'd): the same
 * device as the ones it opens itself. Through system calls: the wrappers
 * of open and stat are not to be entered from here. */
static int adopt_inherited(int device) {
  const char *pty = wiretape_device_variable("WIRETAPE_REDIRECT_TO", device);
  if (pty == NULL || pty[0] != '/') return 0;
  int probe = (int)syscall(SYS_openat, AT_FDCWD, pty, O_PATH | O_CLOEXEC);
  if (probe < 0) return 0;
  struct stat terminal;
  int known = fstat(probe, &terminal) == 0 && S_ISCHR(terminal.st_mode);
  syscall(SYS_close, probe);
  if (!known) return 0;
  int adopted = 0;
  for (int fd = 0; fd < INHERITED_FDS_CHECKED; ++fd) {
    struct stat seen;
    if (fstat(fd, &seen) == 0 && S_ISCHR(seen.st_mode) && seen.st_rdev == terminal.st_rdev) {
      mark(fd, device);
      adopted = 1;
    }
  }
  return adopted;
}

__attribute__((constructor)) static void start_serial_lines(void) {
  resolve_all();
  int saved_errno = errno;
  pthread_atfork(NULL, NULL, forked_child);
  for (int index = 0; index < WIRETAPE_SHIM_DEVICES; ++index) {
    struct line_device *device = &devices[index];
    const char *path = wiretape_device_variable(WT_LINE_ENV, index);
    if (path != NULL && strlen(path) < sizeof device->channel_path) {
      strcpy(device->channel_path, path);
    }
    device->stored_serial.type = PORT_16550A;
    device->stored_serial.xmit_fifo_size = 16;
    device->stored_serial.baud_base = 115200;
    /* Connected before the program writes, as at an open. */
    if (adopt_inherited(index)) {
      pthread_mutex_lock(&device->channel_lock);
      ensure_connected(device);
      pthread_mutex_unlock(&device->channel_lock);
    }
  }
  errno = saved_errno;
}

/* The device `fd` is, or NULL when it is not redirected. */
static struct line_device *redirected_device(int fd) {
  if (!atomic_load_explicit(&any_redirected, memory_order_relaxed)) return NULL;
  if (fd < 0 || fd >= TRACKED_FDS) return NULL;
  unsigned long word = atomic_load_explicit(&redirected_fds[fd / BITS_PER_WORD],
                                            memory_order_relaxed);
  if (!((word >> (fd % BITS_PER_WORD)) & 1UL)) return NULL;
  return &devices[atomic_load_explicit(&device_of_fd[fd], memory_order_relaxed) %
                  WIRETAPE_SHIM_DEVICES];
}

static int device_index(const struct line_device *device) { return (int)(device - devices); }

/* The device is stored before the bit: a reader that sees the bit sees it. */
static void mark(int fd, int device) {
  if (fd < 0 || fd >= TRACKED_FDS || device < 0 || device >= WIRETAPE_SHIM_DEVICES) return;
  unsigned long bit = 1UL << (fd % BITS_PER_WORD);
  atomic_store(&device_of_fd[fd], (unsigned char)device);
  atomic_store(&any_redirected, 1);
  atomic_fetch_or(&redirected_fds[fd / BITS_PER_WORD], bit);
}

static void unmark(int fd) {
  if (fd < 0 || fd >= TRACKED_FDS) return;
  unsigned long bit = 1UL << (fd % BITS_PER_WORD);
  atomic_fetch_and(&redirected_fds[fd / BITS_PER_WORD], ~bit);
}

/* `copy` is now what `fd` is: the same device, or not redirected. */
static void mark_copy(int copy, int fd) {
  struct line_device *device = redirected_device(fd);
  if (device != NULL) {
    mark(copy, device_index(device));
  } else if (atomic_load_explicit(&any_redirected, memory_order_relaxed)) {
    unmark(copy);
  }
}

/* --- the side channel ------------------------------------------------------------ */

static int connect_channel(const struct line_device *device) {
  if (device->channel_path[0] == '\0') return -1;
  int fd = socket(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0);
  if (fd < 0) return -1;
  struct sockaddr_un address;
  memset(&address, 0, sizeof address);
  address.sun_family = AF_UNIX;
  memcpy(address.sun_path, device->channel_path, strlen(device->channel_path));
  if (connect(fd, (struct sockaddr *)&address, sizeof address) != 0) {
    syscall(SYS_close, fd);
    return -1;
  }
  return fd;
}

/* One request and its reply on `fd`; 0, or -1 when the channel failed. */
static int exchange(int fd, const struct wt_line_request *request, struct wt_line_reply *reply) {
  ssize_t sent;
  do {
    sent = send(fd, request, sizeof *request, MSG_NOSIGNAL);
  } while (sent < 0 && errno == EINTR);
  if (sent != (ssize_t)sizeof *request) return -1;
  ssize_t got;
  do {
    got = recv(fd, reply, sizeof *reply, 0);
  } while (got < 0 && errno == EINTR);
  return got == (ssize_t)sizeof *reply ? 0 : -1;
}

static struct wt_line_request request_of(struct line_device *device, uint32_t op, uint32_t set,
                                         uint32_t clear, uint32_t value) {
  struct wt_line_request request;
  memset(&request, 0, sizeof request);
  request.magic = WT_LINE_MAGIC;
  request.op = op;
  request.written = atomic_load(&device->written_since_hello);
  request.set = set;
  request.clear = clear;
  request.value = value;
  return request;
}

/* Called with the device's channel_lock held. */
static int ensure_connected(struct line_device *device) {
  if (device->channel_fd >= 0) return 1;
  if (device->channel_unavailable) return 0;
  device->channel_fd = connect_channel(device);
  if (device->channel_fd < 0) {
    device->channel_unavailable = 1;
    return 0;
  }
  atomic_store(&device->written_since_hello, 0);
  struct wt_line_request hello = request_of(device, WT_LINE_HELLO, 0, 0, 0);
  struct wt_line_reply reply;
  if (exchange(device->channel_fd, &hello, &reply) != 0) {
    syscall(SYS_close, device->channel_fd);
    device->channel_fd = -1;
    device->channel_unavailable = 1;
    return 0;
  }
  return 1;
}

/* Asks the bridge. 1 with `reply` filled; 0 when there is no channel (the
 * caller answers alone). */
static int ask_bridge(struct line_device *device, uint32_t op, uint32_t set, uint32_t clear,
                      uint32_t value, struct wt_line_reply *reply) {
  int saved_errno = errno;
  int answered = 0;
  pthread_mutex_lock(&device->channel_lock);
  if (ensure_connected(device)) {
    struct wt_line_request request = request_of(device, op, set, clear, value);
    if (exchange(device->channel_fd, &request, reply) == 0) {
      answered = 1;
    } else {
      /* The bridge has gone: the process goes on alone. */
      syscall(SYS_close, device->channel_fd);
      device->channel_fd = -1;
      device->channel_unavailable = 1;
    }
  }
  pthread_mutex_unlock(&device->channel_lock);
  errno = saved_errno;
  return answered;
}

/* Result of an emulated call: 0, or -1 with the bridge's errno. */
static int result_of(const struct wt_line_reply *reply) {
  if (reply->error == 0) return 0;
  errno = reply->error;
  return -1;
}

void wiretape_lines_opened(int fd, int device) {
  if (device < 0 || device >= WIRETAPE_SHIM_DEVICES) return;
  mark(fd, device);
  /* The connection starts before the first write, so that the bridge
   * counts this process's bytes from the right place. */
  int saved_errno = errno;
  pthread_mutex_lock(&devices[device].channel_lock);
  ensure_connected(&devices[device]);
  pthread_mutex_unlock(&devices[device].channel_lock);
  errno = saved_errno;
}

/* --- the emulated calls ---------------------------------------------------------- */

#define OUTPUT_LINES (TIOCM_DTR | TIOCM_RTS)
#define INPUT_LINES (TIOCM_CTS | TIOCM_DSR | TIOCM_RI | TIOCM_CD)

static int set_outputs(struct line_device *device, unsigned set, unsigned clear) {
  set &= OUTPUT_LINES;
  clear &= OUTPUT_LINES;
  struct wt_line_reply reply;
  if (ask_bridge(device, WT_LINE_SET_OUTPUTS, set, clear, 0, &reply)) return result_of(&reply);
  unsigned now = atomic_load(&device->local_outputs);
  atomic_store(&device->local_outputs, (now | set) & ~clear);
  return 0;
}

static int get_lines(struct line_device *device, struct wt_line_reply *reply) {
  if (ask_bridge(device, WT_LINE_GET, 0, 0, 0, reply)) return result_of(reply);
  memset(reply, 0, sizeof *reply);
  reply->lines = atomic_load(&device->local_outputs) | TIOCM_CTS | TIOCM_DSR | TIOCM_CD;
  return 0;
}

static int send_break_ms(struct line_device *device, unsigned ms) {
  struct wt_line_reply reply;
  if (ask_bridge(device, WT_LINE_BREAK, 0, 0, ms, &reply)) return result_of(&reply);
  return 0;
}

static int break_level(struct line_device *device, int on) {
  struct wt_line_reply reply;
  if (ask_bridge(device, on ? WT_LINE_BREAK_ON : WT_LINE_BREAK_OFF, 0, 0, 0, &reply)) {
    return result_of(&reply);
  }
  return 0;
}

static void settings_changed(struct line_device *device) {
  struct wt_line_reply reply;
  ask_bridge(device, WT_LINE_SETTINGS, 0, 0, 0, &reply);
}

static void drain(struct line_device *device) {
  struct wt_line_reply reply;
  ask_bridge(device, WT_LINE_DRAIN, 0, 0, 0, &reply);
}

/* TIOCMIWAIT: its own connection, so that the process's other requests are
 * not held up while it waits. */
static int wait_for_inputs(struct line_device *device, unsigned mask) {
  int saved_errno = errno;
  int fd = connect_channel(device);
  if (fd < 0) {
    /* No bridge: no input ever changes. A real port would wait for good;
     * an error tells the driver there is nothing to wait for. */
    errno = EIO;
    return -1;
  }
  struct wt_line_request request = request_of(device, WT_LINE_WAIT, mask & INPUT_LINES, 0, 0);
  struct wt_line_reply reply;
  int failed = exchange(fd, &request, &reply);
  syscall(SYS_close, fd);
  if (failed) {
    errno = EIO;
    return -1;
  }
  errno = saved_errno;
  return result_of(&reply);
}

/* The ioctls emulated on a redirected descriptor; 1 when `request` is one
 * (with its result in *result). */
static int emulated_ioctl(struct line_device *device, int fd, unsigned long request, void *argument,
                          int *result) {
  struct wt_line_reply reply;
  switch (request) {
    case TIOCMGET:
      *result = get_lines(device, &reply);
      if (*result == 0) *(int *)argument = (int)reply.lines;
      return 1;
    case TIOCMSET: {
      unsigned lines = (unsigned)*(const int *)argument;
      *result = set_outputs(device, lines, ~lines);
      return 1;
    }
    case TIOCMBIS:
      *result = set_outputs(device, (unsigned)*(const int *)argument, 0);
      return 1;
    case TIOCMBIC:
      *result = set_outputs(device, 0, (unsigned)*(const int *)argument);
      return 1;
    case TIOCMIWAIT:
      *result = wait_for_inputs(device, (unsigned)(unsigned long)argument);
      return 1;
    case TIOCGICOUNT: {
      *result = get_lines(device, &reply);
      if (*result != 0) return 1;
      struct serial_icounter_struct counts;
      memset(&counts, 0, sizeof counts);
      counts.cts = (int)reply.cts_changes;
      counts.dsr = (int)reply.dsr_changes;
      counts.rng = (int)reply.ri_changes;
      counts.dcd = (int)reply.cd_changes;
      counts.rx = (int)atomic_load(&device->bytes_read);
      counts.tx = (int)atomic_load(&device->bytes_written);
      memcpy(argument, &counts, sizeof counts);
      return 1;
    }
    case TCSBRK:
      /* 0: a break of 0.25 s; otherwise tcdrain's request. */
      if ((unsigned long)argument == 0) {
        *result = send_break_ms(device, 250);
      } else {
        drain(device);
        *result = real_ioctl(fd, request, argument);
      }
      return 1;
    case TCSBRKP: {
      unsigned long tenths = (unsigned long)argument;
      *result = send_break_ms(device, tenths == 0 ? 250 : (unsigned)(tenths * 100));
      return 1;
    }
    case TIOCSBRK:
      *result = break_level(device, 1);
      return 1;
    case TIOCCBRK:
      *result = break_level(device, 0);
      return 1;
    case TCSETS:
    case TCSETSW:
    case TCSETSF:
    case TCSETS2:
    case TCSETSW2:
    case TCSETSF2:
      /* The pty keeps the settings, custom baud included (the bridge reads
       * them from its master); the bridge is told where they changed. */
      *result = real_ioctl(fd, request, argument);
      if (*result == 0) settings_changed(device);
      return 1;
    case TIOCGSERIAL:
      pthread_mutex_lock(&device->stored_lock);
      memcpy(argument, &device->stored_serial, sizeof device->stored_serial);
      pthread_mutex_unlock(&device->stored_lock);
      *result = 0;
      return 1;
    case TIOCSSERIAL:
      pthread_mutex_lock(&device->stored_lock);
      memcpy(&device->stored_serial, argument, sizeof device->stored_serial);
      pthread_mutex_unlock(&device->stored_lock);
      *result = 0;
      return 1;
    case TIOCGRS485:
      pthread_mutex_lock(&device->stored_lock);
      memcpy(argument, &device->stored_rs485, sizeof device->stored_rs485);
      pthread_mutex_unlock(&device->stored_lock);
      *result = 0;
      return 1;
    case TIOCSRS485:
      pthread_mutex_lock(&device->stored_lock);
      memcpy(&device->stored_rs485, argument, sizeof device->stored_rs485);
      pthread_mutex_unlock(&device->stored_lock);
      *result = 0;
      return 1;
    default:
      /* TIOCEXCL, TIOCNXCL, TCGETS2, TCFLSH...: a pty does these itself. */
      return 0;
  }
}

int ioctl(int fd, unsigned long request, ...) {
  va_list arguments;
  va_start(arguments, request);
  void *argument = va_arg(arguments, void *);
  va_end(arguments);
  if (!RESOLVE(ioctl)) {
    errno = ENOSYS;
    return -1;
  }
  struct line_device *device = redirected_device(fd);
  if (device != NULL) {
    int saved_errno = errno;
    int result = 0;
    if (emulated_ioctl(device, fd, request, argument, &result)) {
      if (result == 0) errno = saved_errno;
      return result;
    }
  }
  return real_ioctl(fd, request, argument);
}

int tcsetattr(int fd, int action, const struct termios *settings) {
  if (!RESOLVE(tcsetattr)) {
    errno = ENOSYS;
    return -1;
  }
  int result = real_tcsetattr(fd, action, settings);
  struct line_device *device = result == 0 ? redirected_device(fd) : NULL;
  if (device != NULL) settings_changed(device);
  return result;
}

int tcsendbreak(int fd, int duration) {
  if (!RESOLVE(tcsendbreak)) {
    errno = ENOSYS;
    return -1;
  }
  struct line_device *device = redirected_device(fd);
  if (device == NULL) return real_tcsendbreak(fd, duration);
  /* As glibc asks the kernel: 0.25 s, or `duration` in tenths rounded up
   * from hundredths. */
  int saved_errno = errno;
  int result = send_break_ms(device, duration <= 0 ? 250 : (unsigned)((duration + 99) / 100) * 100);
  if (result == 0) errno = saved_errno;
  return result;
}

int tcdrain(int fd) {
  if (!RESOLVE(tcdrain)) {
    errno = ENOSYS;
    return -1;
  }
  struct line_device *device = redirected_device(fd);
  if (device != NULL) drain(device);
  return real_tcdrain(fd);
}

/* --- counting and following the descriptors --------------------------------------- */

ssize_t write(int fd, const void *data, size_t size) {
  if (!RESOLVE(write)) {
    errno = ENOSYS;
    return -1;
  }
  ssize_t written = real_write(fd, data, size);
  struct line_device *device = written > 0 ? redirected_device(fd) : NULL;
  if (device != NULL) {
    atomic_fetch_add(&device->written_since_hello, (uint64_t)written);
    atomic_fetch_add(&device->bytes_written, (uint64_t)written);
  }
  return written;
}

ssize_t writev(int fd, const struct iovec *parts, int count) {
  if (!RESOLVE(writev)) {
    errno = ENOSYS;
    return -1;
  }
  ssize_t written = real_writev(fd, parts, count);
  struct line_device *device = written > 0 ? redirected_device(fd) : NULL;
  if (device != NULL) {
    atomic_fetch_add(&device->written_since_hello, (uint64_t)written);
    atomic_fetch_add(&device->bytes_written, (uint64_t)written);
  }
  return written;
}

ssize_t read(int fd, void *data, size_t size) {
  if (!RESOLVE(read)) {
    errno = ENOSYS;
    return -1;
  }
  ssize_t got = real_read(fd, data, size);
  struct line_device *device = got > 0 ? redirected_device(fd) : NULL;
  if (device != NULL) atomic_fetch_add(&device->bytes_read, (uint64_t)got);
  return got;
}

int close(int fd) {
  if (!RESOLVE(close)) {
    errno = ENOSYS;
    return -1;
  }
  /* Unmarked first: the number may be reused by another thread's open as
   * soon as it is closed. */
  if (redirected_device(fd) != NULL) unmark(fd);
  return real_close(fd);
}

int dup(int fd) {
  if (!RESOLVE(dup)) {
    errno = ENOSYS;
    return -1;
  }
  int copy = real_dup(fd);
  if (copy >= 0) mark_copy(copy, fd);
  return copy;
}

int dup2(int fd, int target) {
  if (!RESOLVE(dup2)) {
    errno = ENOSYS;
    return -1;
  }
  int copy = real_dup2(fd, target);
  if (copy >= 0 && copy != fd) mark_copy(copy, fd);
  return copy;
}

int dup3(int fd, int target, int flags) {
  if (!RESOLVE(dup3)) {
    errno = ENOSYS;
    return -1;
  }
  int copy = real_dup3(fd, target, flags);
  if (copy >= 0) mark_copy(copy, fd);
  return copy;
}

/* fcntl64 is what programs built with 64-bit file offsets call (glibc
 * 2.28 and later). */
#define DEFINE_FCNTL(name)                                                          \
  int name(int fd, int command, ...) {                                              \
    va_list arguments;                                                              \
    va_start(arguments, command);                                                   \
    void *argument = va_arg(arguments, void *);                                     \
    va_end(arguments);                                                              \
    if (!RESOLVE(name)) {                                                           \
      errno = ENOSYS;                                                               \
      return -1;                                                                    \
    }                                                                               \
    int result = real_##name(fd, command, argument);                                \
    if (result >= 0 && (command == F_DUPFD || command == F_DUPFD_CLOEXEC)) {        \
      mark_copy(result, fd);                                                        \
    }                                                                               \
    return result;                                                                  \
  }

DEFINE_FCNTL(fcntl)
DEFINE_FCNTL(fcntl64)
