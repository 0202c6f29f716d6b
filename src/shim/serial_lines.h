/* The serial lines of the redirected descriptors (src/shim/serial_lines.c):
 * what redirect_device.c tells it about the descriptors it opened on the
 * virtual device. */
#ifndef WIRETAPE_SHIM_SERIAL_LINES_H
#define WIRETAPE_SHIM_SERIAL_LINES_H

/* `fd` was opened on the redirected path (the bridge's pty). */
void wiretape_lines_opened(int fd);

#endif
