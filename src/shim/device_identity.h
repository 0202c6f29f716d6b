/* The recorded device's identity as the shim presents it (DESIGN §20,
 * "Identity"; src/shim/device_identity.c). */
#ifndef WIRETAPE_SHIM_DEVICE_IDENTITY_H
#define WIRETAPE_SHIM_DEVICE_IDENTITY_H

/* N+1 when `path` is another name the identity of device N gives it (its
 * by-id link, its kernel name under /dev), which the shim redirects to that
 * virtual device as it does the path itself; else 0. */
__attribute__((visibility("hidden"))) int wiretape_identity_names_device(const char *path);

/* The presented tree's path for a path under /sys/class/tty/NAME (NAME the
 * presented kernel name), or NULL for any other path. The result is the
 * calling thread's, valid until its next call. errno is left as it was. */
__attribute__((visibility("hidden"))) const char *wiretape_identity_sysfs_path(const char *path);

#endif
