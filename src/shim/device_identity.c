/* The recorded device's identity, presented to CMD under
 * `wiretape replay FILE --as PATH -- CMD` (DESIGN §20, "Identity";
 * docs/replay.md, "Device identity").
 *
 * python/wiretape/redirect.py writes a small sysfs tree for the recording's
 * identity (_core.write_device_tree) and sets:
 *
 *   WIRETAPE_IDENTITY_TTY    the kernel name presented (ttyACM0): listed in
 *                            /dev, and /dev/NAME is the virtual device
 *   WIRETAPE_IDENTITY_SYSFS  the tree's folder that stands for
 *                            /sys/class/tty/NAME
 *   WIRETAPE_IDENTITY_BY_ID  optional: the recorded /dev/serial/by-id name,
 *                            redirected to the virtual device even when no
 *                            such link exists on this machine
 *
 * Each redirected device of a command has its own (device N: the names
 * ending in _N, as in redirect_device.c), so that each answers for itself.
 *
 * What pyserial's list_ports_linux does is then answered from the tree: it
 * lists /dev (opendir, readdir), follows /sys/class/tty/NAME/device
 * (lstat, readlink, stat) and reads the USB device's attributes (open); the
 * tree's own links lead on with absolute paths, so only /sys/class/tty/NAME
 * is mapped. libudev's enumeration (its database under /run/udev) is not
 * presented.
 *
 * C only, no allocation after start-up, errno preserved. */

#define _GNU_SOURCE
#undef _FORTIFY_SOURCE
#include "device_identity.h"
#include "serial_lines.h"

#include <dirent.h>
#include <dlfcn.h>
#include <errno.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

struct presented_identity {
  char tty_name[NAME_MAX + 1];
  char tty_device_path[PATH_MAX];  /* /dev/NAME */
  char class_tty_path[PATH_MAX];   /* /sys/class/tty/NAME */
  size_t class_tty_path_length;
  char presented_folder[PATH_MAX]; /* the tree's folder for it */
  char by_id_path[PATH_MAX];
  int tree_active; /* the name and its sysfs tree are presented */
};
static struct presented_identity identities[WIRETAPE_SHIM_DEVICES];
static int any_tree_active;

/* Each thread maps into its own buffer: initial-exec, so that no thread's
 * first use allocates. */
static __thread char mapped_path[PATH_MAX] __attribute__((tls_model("initial-exec")));

static const char *mapped_into(const char *presented_folder, const char *rest);

static int copy_text(char *destination, size_t size, const char *source) {
  size_t length = strlen(source);
  if (length >= size) return 0;
  memcpy(destination, source, length + 1);
  return 1;
}

static void read_identity(int device) {
  struct presented_identity *identity = &identities[device];
  const char *name = wiretape_device_variable("WIRETAPE_IDENTITY_TTY", device);
  const char *folder = wiretape_device_variable("WIRETAPE_IDENTITY_SYSFS", device);
  const char *by_id = wiretape_device_variable("WIRETAPE_IDENTITY_BY_ID", device);
  if (by_id != NULL && by_id[0] == '/') {
    copy_text(identity->by_id_path, sizeof identity->by_id_path, by_id);
  }
  if (name == NULL || folder == NULL || name[0] == '\0' || strchr(name, '/') != NULL ||
      folder[0] != '/') {
    return;
  }
  if (!copy_text(identity->tty_name, sizeof identity->tty_name, name) ||
      !copy_text(identity->presented_folder, sizeof identity->presented_folder, folder)) {
    return;
  }
  strcpy(identity->tty_device_path, "/dev/");
  strcat(identity->tty_device_path, identity->tty_name);
  strcpy(identity->class_tty_path, "/sys/class/tty/");
  strcat(identity->class_tty_path, identity->tty_name);
  identity->class_tty_path_length = strlen(identity->class_tty_path);
  identity->tree_active = 1;
  any_tree_active = 1;
}

__attribute__((constructor)) static void read_identity_configuration(void) {
  for (int device = 0; device < WIRETAPE_SHIM_DEVICES; ++device) read_identity(device);
}

int wiretape_identity_names_device(const char *path) {
  if (path == NULL) return 0;
  for (int device = 0; device < WIRETAPE_SHIM_DEVICES; ++device) {
    const struct presented_identity *identity = &identities[device];
    if ((identity->tree_active && strcmp(path, identity->tty_device_path) == 0) ||
        (identity->by_id_path[0] != '\0' && strcmp(path, identity->by_id_path) == 0)) {
      return device + 1;
    }
  }
  return 0;
}

const char *wiretape_identity_sysfs_path(const char *path) {
  if (!any_tree_active || path == NULL) return NULL;
  for (int device = 0; device < WIRETAPE_SHIM_DEVICES; ++device) {
    const struct presented_identity *identity = &identities[device];
    if (!identity->tree_active ||
        strncmp(path, identity->class_tty_path, identity->class_tty_path_length) != 0) {
      continue;
    }
    const char *rest = path + identity->class_tty_path_length;
    if (rest[0] != '\0' && rest[0] != '/') continue;  /* ttyACM0 is not ttyACM01 */
    return mapped_into(identity->presented_folder, rest);
  }
  return NULL;
}

static const char *mapped_into(const char *presented_folder, const char *rest) {
  size_t folder_length = strlen(presented_folder);
  size_t rest_length = strlen(rest);
  if (folder_length + rest_length >= sizeof mapped_path) return NULL;
  memcpy(mapped_path, presented_folder, folder_length);
  memcpy(mapped_path + folder_length, rest, rest_length + 1);
  return mapped_path;
}

/* The next definition of `name` (libc's), looked up on first use. */
#define REAL_OR(type, name, params, failure)                                  \
  static type(*real_##name) params;                                           \
  if (real_##name == NULL) real_##name = (type(*) params)dlsym(RTLD_NEXT, #name); \
  if (real_##name == NULL) {                                                  \
    errno = ENOSYS;                                                           \
    return failure;                                                           \
  }

static const char *mapped(const char *path) {
  const char *presented = wiretape_identity_sysfs_path(path);
  return presented != NULL ? presented : path;
}

/* readlink is not redirected to the virtual device (a by-id name is no link
 * under the shim); only the presented tree is mapped. */
ssize_t readlink(const char *path, char *buffer, size_t size) {
  REAL_OR(ssize_t, readlink, (const char *, char *, size_t), -1)
  return real_readlink(mapped(path), buffer, size);
}

ssize_t readlinkat(int directory, const char *path, char *buffer, size_t size) {
  REAL_OR(ssize_t, readlinkat, (int, const char *, char *, size_t), -1)
  return real_readlinkat(directory, mapped(path), buffer, size);
}

/* --- /dev listings that name the presented device ------------------------ */

/* A listing of /dev being read: the presented name is added at its end
 * unless the listing held it. A few at once are enough (a listing is
 * opened, read and closed); past them, listings are left as they are. */
struct dev_listing {
  DIR *dir;
  unsigned seen;  /* a bit per device: its name was listed */
  unsigned added; /* a bit per device: its name was added */
  struct dirent entry;
  struct dirent64 entry64;
};
static struct dev_listing dev_listings[8];

static int is_dev_folder(const char *path) {
  return path != NULL && (strcmp(path, "/dev") == 0 || strcmp(path, "/dev/") == 0);
}

static struct dev_listing *listing_of(DIR *dir) {
  if (!any_tree_active || dir == NULL) return NULL;
  for (size_t i = 0; i < sizeof dev_listings / sizeof dev_listings[0]; ++i) {
    if (__atomic_load_n(&dev_listings[i].dir, __ATOMIC_ACQUIRE) == dir) return &dev_listings[i];
  }
  return NULL;
}

DIR *opendir(const char *path) {
  REAL_OR(DIR *, opendir, (const char *), NULL)
  DIR *dir = real_opendir(mapped(path));
  if (dir == NULL || !any_tree_active || !is_dev_folder(path)) return dir;
  for (size_t i = 0; i < sizeof dev_listings / sizeof dev_listings[0]; ++i) {
    DIR *expected = NULL;
    struct dev_listing *listing = &dev_listings[i];
    /* Nobody reads `dir` before it is returned: its marks can follow. */
    if (__atomic_compare_exchange_n(&listing->dir, &expected, dir, 0, __ATOMIC_ACQ_REL,
                                    __ATOMIC_ACQUIRE)) {
      listing->seen = 0;
      listing->added = 0;
      break;
    }
  }
  return dir;
}

int closedir(DIR *dir) {
  REAL_OR(int, closedir, (DIR *), -1)
  struct dev_listing *listing = listing_of(dir);
  /* Released first: once closed, the same pointer may be another listing. */
  if (listing != NULL) __atomic_store_n(&listing->dir, NULL, __ATOMIC_RELEASE);
  return real_closedir(dir);
}

/* The presented name due now, or NULL: at the end of a listing of /dev,
 * each presented name it has not held, one per call. `found` is the entry
 * readdir returned (NULL at the end). */
static const char *add_presented_name(struct dev_listing *listing, const char *found) {
  if (listing == NULL) return NULL;
  for (int device = 0; device < WIRETAPE_SHIM_DEVICES; ++device) {
    const struct presented_identity *identity = &identities[device];
    if (!identity->tree_active) continue;
    unsigned bit = 1u << device;
    if (found != NULL) {
      if (strcmp(found, identity->tty_name) == 0) listing->seen |= bit;
    } else if (!((listing->seen | listing->added) & bit)) {
      listing->added |= bit;
      return identity->tty_name;
    }
  }
  return NULL;
}

struct dirent *readdir(DIR *dir) {
  REAL_OR(struct dirent *, readdir, (DIR *), NULL)
  int saved_errno = errno;
  struct dirent *entry = real_readdir(dir);
  struct dev_listing *listing = listing_of(dir);
  const char *added = add_presented_name(listing, entry != NULL ? entry->d_name : NULL);
  if (added == NULL) return entry;
  memset(&listing->entry, 0, sizeof listing->entry);
  listing->entry.d_ino = 1;
  listing->entry.d_reclen = sizeof listing->entry;
  listing->entry.d_type = DT_CHR;
  strcpy(listing->entry.d_name, added);
  errno = saved_errno;
  return &listing->entry;
}

struct dirent64 *readdir64(DIR *dir) {
  REAL_OR(struct dirent64 *, readdir64, (DIR *), NULL)
  int saved_errno = errno;
  struct dirent64 *entry = real_readdir64(dir);
  struct dev_listing *listing = listing_of(dir);
  const char *added = add_presented_name(listing, entry != NULL ? entry->d_name : NULL);
  if (added == NULL) return entry;
  memset(&listing->entry64, 0, sizeof listing->entry64);
  listing->entry64.d_ino = 1;
  listing->entry64.d_reclen = sizeof listing->entry64;
  listing->entry64.d_type = DT_CHR;
  strcpy(listing->entry64.d_name, added);
  errno = saved_errno;
  return &listing->entry64;
}
