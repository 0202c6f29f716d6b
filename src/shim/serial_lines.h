/* The serial lines of the redirected descriptors (src/shim/serial_lines.c):
 * what redirect_device.c tells it about the descriptors it opened on the
 * virtual devices. */
#ifndef WIRETAPE_SHIM_SERIAL_LINES_H
#define WIRETAPE_SHIM_SERIAL_LINES_H

/* How many devices one command may have redirected (device 0 reads the
 * unsuffixed variables, device N the ones ending in _N: docs/replay.md). */
#define WIRETAPE_SHIM_DEVICES 8

/* `fd` was opened on the redirected path of `device` (its bridge's pty). */
__attribute__((visibility("hidden"))) void wiretape_lines_opened(int fd, int device);

/* The value of variable `name` for `device`: `name` itself for device 0,
 * `name`_N for device N; NULL when unset. For start-up only (getenv). */
__attribute__((visibility("hidden"))) const char *wiretape_device_variable(const char *name,
                                                                           int device);

#endif
