/* An LD_PRELOAD shim that makes a program open a virtual device where it
 * opens a hard-coded device path (DESIGN §12, "Hard-coded device paths";
 * docs/replay.md, "Programs with a hard-coded device path").
 *
 * `wiretape record ... -- CMD` and `wiretape replay ... --as PATH -- CMD`
 * start CMD with this library preloaded and three variables set:
 *
 *   WIRETAPE_REDIRECT_FROM  the path CMD opens (/dev/ttyUSB0)
 *   WIRETAPE_REDIRECT_TO    the pty that stands in for it (/dev/pts/7)
 *   WIRETAPE_REDIRECT_HITS  optional: a file that gets one line per process
 *                           that used the path, so that wiretape can say at
 *                           the end when CMD never opened it
 *
 * A command that opens several hard-coded paths (a session of several
 * channels) gets one such set per path: the unsuffixed variables are device
 * 0, WIRETAPE_REDIRECT_FROM_N, _TO_N and _HITS_N device N (1 to 7; a device
 * without FROM and TO is absent). The other variables of a device
 * (WIRETAPE_LINE_CHANNEL, WIRETAPE_IDENTITY_*) take the same suffix.
 *
 * A path is redirected when it is FROM as written, or when FROM exists and
 * the path resolves to the same file (a /dev/serial/by-id/ link to it, or a
 * symbolic link to it elsewhere).
 * Only absolute paths are compared: a relative one, or one given relative to
 * a directory descriptor, never names a device under /dev in practice.
 *
 * It reaches dynamically linked programs only; calls glibc makes internally
 * (not through the symbols below) and static programs are not redirected.
 * C only, no allocation after start-up: it runs inside every function the
 * program calls to open or inspect a file. */

#define _GNU_SOURCE
/* The fortified inline wrappers of open() would clash with ours. */
#undef _FORTIFY_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

#include "serial_lines.h"
#include "device_identity.h"

struct redirected_path {
  char from[PATH_MAX];
  char from_resolved[PATH_MAX]; /* empty: FROM does not exist */
  char to[PATH_MAX];
  char hits_file[PATH_MAX];
  int active;
  int hit_noted;
};
static struct redirected_path paths[WIRETAPE_SHIM_DEVICES];
static int redirect_active; /* any path */

/* libc's realpath: ours (below) redirects, and would call back into the
 * matching that uses it. */
static char *real_realpath(const char *path, char *resolved) {
  static char *(*real)(const char *, char *);
  if (real == NULL) real = (char *(*)(const char *, char *))dlsym(RTLD_NEXT, "realpath");
  if (real == NULL) {
    errno = ENOSYS;
    return NULL;
  }
  return real(path, resolved);
}

static void copy_path(char *destination, const char *source) {
  size_t length = strlen(source);
  if (length >= PATH_MAX) length = PATH_MAX - 1;
  memcpy(destination, source, length);
  destination[length] = '\0';
}

__attribute__((constructor)) static void read_configuration(void) {
  for (int device = 0; device < WIRETAPE_SHIM_DEVICES; ++device) {
    struct redirected_path *redirect = &paths[device];
    const char *from = wiretape_device_variable("WIRETAPE_REDIRECT_FROM", device);
    const char *to = wiretape_device_variable("WIRETAPE_REDIRECT_TO", device);
    const char *hits = wiretape_device_variable("WIRETAPE_REDIRECT_HITS", device);
    if (from == NULL || to == NULL || from[0] != '/' || to[0] == '\0') continue;
    copy_path(redirect->from, from);
    copy_path(redirect->to, to);
    if (hits != NULL) copy_path(redirect->hits_file, hits);
    /* Resolved once, before the program runs: the real device (when there
     * is one on this machine) is what its by-id links point to. */
    char resolved[PATH_MAX];
    if (real_realpath(redirect->from, resolved) != NULL) {
      copy_path(redirect->from_resolved, resolved);
    }
    redirect->active = 1;
    redirect_active = 1;
  }
}

/* Records that this process used the path (once per process; a child that
 * CMD starts notes its own). Errors are ignored: the note is a courtesy and
 * must never change what the program sees, errno included. */
static void note_hit(struct redirected_path *redirect) {
  if (redirect->hit_noted || redirect->hits_file[0] == '\0') return;
  redirect->hit_noted = 1;
  int saved_errno = errno;
  static int (*real_open)(const char *, int, ...);
  if (real_open == NULL) real_open = (int (*)(const char *, int, ...))dlsym(RTLD_NEXT, "open");
  if (real_open != NULL) {
    int fd = real_open(redirect->hits_file, O_WRONLY | O_APPEND | O_CLOEXEC);
    if (fd >= 0) {
      char line[32];
      int length = snprintf(line, sizeof line, "%ld\n", (long)getpid());
      if (length > 0 && write(fd, line, (size_t)length) < 0) { /* ignored, see above */ }
      close(fd);
    }
  }
  errno = saved_errno;
}

/* readlink, which this shim does not redirect, tells a symbolic link in one
 * system call (lstat would come back through our own wrapper). */
static int is_symbolic_link(const char *path) {
  char target[1];
  return readlink(path, target, sizeof target) >= 0;
}

static const char *hit(int device) {
  note_hit(&paths[device]);
  return paths[device].to;
}

/* The path to use instead of `path`: the pty of the device `path` names,
 * else `path` itself. */
static const char *redirected(const char *path) {
  if (!redirect_active || path == NULL || path[0] != '/') return path;
  for (int device = 0; device < WIRETAPE_SHIM_DEVICES; ++device) {
    if (paths[device].active && strcmp(path, paths[device].from) == 0) return hit(device);
  }
  int named = wiretape_identity_names_device(path);
  if (named > 0 && paths[named - 1].active) return hit(named - 1);
  const char *presented = wiretape_identity_sysfs_path(path);
  if (presented != NULL) return presented;
  /* By-id links and other names of the real devices: resolving costs system
   * calls, so only paths under /dev and symbolic links (a by-id style link
   * made elsewhere) are resolved, and once. */
  int saved_errno = errno;
  char resolved[PATH_MAX];
  int have_resolved = -1; /* not tried yet */
  int found = -1;
  for (int device = 0; device < WIRETAPE_SHIM_DEVICES && found < 0; ++device) {
    if (!paths[device].active || paths[device].from_resolved[0] == '\0') continue;
    if (have_resolved < 0) {
      have_resolved = (strncmp(path, "/dev/", 5) == 0 || is_symbolic_link(path)) &&
                      real_realpath(path, resolved) != NULL;
    }
    if (have_resolved && strcmp(resolved, paths[device].from_resolved) == 0) found = device;
  }
  errno = saved_errno;
  return found >= 0 ? hit(found) : path;
}

/* The next definition of `name` (libc's), looked up on first use. */
#define REAL(type, name, params)                                        \
  static type(*real_##name) params;                                     \
  if (real_##name == NULL) real_##name = (type(*) params)dlsym(RTLD_NEXT, #name); \
  if (real_##name == NULL) {                                            \
    errno = ENOSYS;                                                     \
    return (type)-1;                                                    \
  }

/* A descriptor opened on the pty (through the redirection, or by its own
 * name after realpath gave it) gets the emulated serial lines. */
static int note_opened(const char *target, int fd) {
  if (fd < 0 || !redirect_active || target == NULL) return fd;
  for (int device = 0; device < WIRETAPE_SHIM_DEVICES; ++device) {
    if (paths[device].active && (target == paths[device].to || strcmp(target, paths[device].to) == 0)) {
      wiretape_lines_opened(fd, device);
      break;
    }
  }
  return fd;
}

/* open and friends take a mode only with O_CREAT or O_TMPFILE. */
static mode_t mode_argument(int flags, va_list arguments) {
#ifdef O_TMPFILE
  if ((flags & O_CREAT) || (flags & O_TMPFILE) == O_TMPFILE) return (mode_t)va_arg(arguments, int);
#else
  if (flags & O_CREAT) return (mode_t)va_arg(arguments, int);
#endif
  return 0;
}

#define DEFINE_OPEN(name)                                               \
  int name(const char *path, int flags, ...) {                          \
    va_list arguments;                                                  \
    va_start(arguments, flags);                                         \
    mode_t mode = mode_argument(flags, arguments);                      \
    va_end(arguments);                                                  \
    REAL(int, name, (const char *, int, ...))                           \
    const char *target = redirected(path);                              \
    return note_opened(target, real_##name(target, flags, mode));       \
  }

#define DEFINE_OPENAT(name)                                             \
  int name(int directory, const char *path, int flags, ...) {           \
    va_list arguments;                                                  \
    va_start(arguments, flags);                                         \
    mode_t mode = mode_argument(flags, arguments);                      \
    va_end(arguments);                                                  \
    REAL(int, name, (int, const char *, int, ...))                      \
    const char *target = redirected(path);                              \
    return note_opened(target, real_##name(directory, target, flags, mode)); \
  }

DEFINE_OPEN(open)
DEFINE_OPEN(open64)
DEFINE_OPENAT(openat)
DEFINE_OPENAT(openat64)

/* The _FORTIFY_SOURCE entry points. */
int __open_2(const char *path, int flags) {
  REAL(int, __open_2, (const char *, int))
  const char *target = redirected(path);
  return note_opened(target, real___open_2(target, flags));
}
int __open64_2(const char *path, int flags) {
  REAL(int, __open64_2, (const char *, int))
  const char *target = redirected(path);
  return note_opened(target, real___open64_2(target, flags));
}
int __openat_2(int directory, const char *path, int flags) {
  REAL(int, __openat_2, (int, const char *, int))
  const char *target = redirected(path);
  return note_opened(target, real___openat_2(directory, target, flags));
}
int __openat64_2(int directory, const char *path, int flags) {
  REAL(int, __openat64_2, (int, const char *, int))
  const char *target = redirected(path);
  return note_opened(target, real___openat64_2(directory, target, flags));
}

#define DEFINE_FOPEN(name)                                              \
  FILE *name(const char *path, const char *mode) {                      \
    static FILE *(*real)(const char *, const char *);                   \
    if (real == NULL) real = (FILE * (*)(const char *, const char *)) dlsym(RTLD_NEXT, #name); \
    if (real == NULL) {                                                 \
      errno = ENOSYS;                                                   \
      return NULL;                                                      \
    }                                                                   \
    const char *target = redirected(path);                              \
    FILE *stream = real(target, mode);                                  \
    if (stream != NULL) note_opened(target, fileno(stream));            \
    return stream;                                                      \
  }

DEFINE_FOPEN(fopen)
DEFINE_FOPEN(fopen64)

FILE *freopen(const char *path, const char *mode, FILE *stream) {
  static FILE *(*real)(const char *, const char *, FILE *);
  if (real == NULL) real = (FILE * (*)(const char *, const char *, FILE *)) dlsym(RTLD_NEXT, "freopen");
  if (real == NULL) {
    errno = ENOSYS;
    return NULL;
  }
  const char *target = redirected(path);
  FILE *reopened = real(target, mode, stream);
  if (reopened != NULL) note_opened(target, fileno(reopened));
  return reopened;
}

/* stat and its relatives: a program that checks the device exists before
 * opening it must see the pty. glibc before 2.33 exports the __xstat
 * family, later ones stat, lstat and fstatat themselves: both are defined. */
#define DEFINE_STAT(name, buffer_type)                                  \
  int name(const char *path, buffer_type *buffer) {                     \
    REAL(int, name, (const char *, buffer_type *))                      \
    return real_##name(redirected(path), buffer);                       \
  }
#define DEFINE_XSTAT(name, buffer_type)                                 \
  int name(int version, const char *path, buffer_type *buffer) {        \
    REAL(int, name, (int, const char *, buffer_type *))                 \
    return real_##name(version, redirected(path), buffer);              \
  }
#define DEFINE_FSTATAT(name, buffer_type)                               \
  int name(int directory, const char *path, buffer_type *buffer, int flags) { \
    REAL(int, name, (int, const char *, buffer_type *, int))            \
    return real_##name(directory, redirected(path), buffer, flags);     \
  }

DEFINE_STAT(stat, struct stat)
DEFINE_STAT(stat64, struct stat64)
DEFINE_STAT(lstat, struct stat)
DEFINE_STAT(lstat64, struct stat64)
DEFINE_FSTATAT(fstatat, struct stat)
DEFINE_FSTATAT(fstatat64, struct stat64)
DEFINE_XSTAT(__xstat, struct stat)
DEFINE_XSTAT(__xstat64, struct stat64)
DEFINE_XSTAT(__lxstat, struct stat)
DEFINE_XSTAT(__lxstat64, struct stat64)

int __fxstatat(int version, int directory, const char *path, struct stat *buffer, int flags) {
  REAL(int, __fxstatat, (int, int, const char *, struct stat *, int))
  return real___fxstatat(version, directory, redirected(path), buffer, flags);
}
int __fxstatat64(int version, int directory, const char *path, struct stat64 *buffer, int flags) {
  REAL(int, __fxstatat64, (int, int, const char *, struct stat64 *, int))
  return real___fxstatat64(version, directory, redirected(path), buffer, flags);
}

#ifdef STATX_BASIC_STATS
int statx(int directory, const char *path, int flags, unsigned int mask, struct statx *buffer) {
  REAL(int, statx, (int, const char *, int, unsigned int, struct statx *))
  return real_statx(directory, redirected(path), flags, mask, buffer);
}
#endif

int access(const char *path, int mode) {
  REAL(int, access, (const char *, int))
  return real_access(redirected(path), mode);
}
int euidaccess(const char *path, int mode) {
  REAL(int, euidaccess, (const char *, int))
  return real_euidaccess(redirected(path), mode);
}
int faccessat(int directory, const char *path, int mode, int flags) {
  REAL(int, faccessat, (int, const char *, int, int))
  return real_faccessat(directory, redirected(path), mode, flags);
}

/* A program that resolves the device before opening it (to follow a by-id
 * link) gets the pty's own name, which it then opens directly. */
char *realpath(const char *path, char *resolved) {
  return real_realpath(redirected(path), resolved);
}
