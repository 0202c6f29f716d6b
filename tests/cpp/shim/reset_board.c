/* A board programmer's reset, as avrdude and esptool do it, on a hard-coded
 * device path: run under `wiretape record/replay ... -- CMD` (the --as shim,
 * DESIGN §20), whose pty has none of the lines it uses.
 *
 *   reset_board [--no-pulse]
 *
 * Opens /dev/ttyUSB0, sets raw 8N1 at a custom 250000 baud with TCSETS2,
 * writes "HELLO\n", pulses DTR low and high with TIOCMBIC/TIOCMBIS (unless
 * --no-pulse), writes "SYNC\n", sends a break with tcsendbreak, reads CTS
 * with TIOCMGET, writes "PING\n" and prints the line it reads back. Exits 0,
 * or 4 naming the call that failed. */
#include <asm/termios.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

/* <sys/ioctl.h> and <termios.h> clash with the kernel's termios2. */
int ioctl(int fd, unsigned long request, ...);
int tcsendbreak(int fd, int duration);

#define DEVICE "/dev/ttyUSB0"
#define CUSTOM_BAUD 250000

static int fail(const char *what) {
  fprintf(stderr, "reset_board: %s: %s\n", what, strerror(errno));
  return 4;
}

static int write_all(int fd, const char *text) {
  size_t length = strlen(text);
  return write(fd, text, length) == (ssize_t)length ? 0 : -1;
}

int main(int argc, char **argv) {
  int pulse = !(argc > 1 && strcmp(argv[1], "--no-pulse") == 0);
  int fd = open(DEVICE, O_RDWR | O_NOCTTY);
  if (fd < 0) return fail("open " DEVICE);

  struct termios2 settings;
  if (ioctl(fd, TCGETS2, &settings) != 0) return fail("TCGETS2");
  settings.c_iflag = 0;
  settings.c_oflag = 0;
  settings.c_lflag = 0;
  settings.c_cflag = CS8 | CREAD | CLOCAL | BOTHER | (BOTHER << IBSHIFT);
  settings.c_ispeed = CUSTOM_BAUD;
  settings.c_ospeed = CUSTOM_BAUD;
  settings.c_cc[VMIN] = 1;
  settings.c_cc[VTIME] = 0;
  if (ioctl(fd, TCSETS2, &settings) != 0) return fail("TCSETS2");
  struct termios2 applied;
  if (ioctl(fd, TCGETS2, &applied) != 0) return fail("TCGETS2");
  if (applied.c_ospeed != CUSTOM_BAUD) {
    fprintf(stderr, "reset_board: the line runs at %u baud, not %d\n", applied.c_ospeed,
            CUSTOM_BAUD);
    return 4;
  }

  if (write_all(fd, "HELLO\n") != 0) return fail("write HELLO");
  if (pulse) {
    int dtr = TIOCM_DTR;
    if (ioctl(fd, TIOCMBIC, &dtr) != 0) return fail("TIOCMBIC");
    int lines = 0;
    if (ioctl(fd, TIOCMGET, &lines) != 0) return fail("TIOCMGET");
    if (lines & TIOCM_DTR) {
      fprintf(stderr, "reset_board: DTR is still high after TIOCMBIC\n");
      return 4;
    }
    if (ioctl(fd, TIOCMBIS, &dtr) != 0) return fail("TIOCMBIS");
  }
  if (write_all(fd, "SYNC\n") != 0) return fail("write SYNC");
  if (tcsendbreak(fd, 0) != 0) return fail("tcsendbreak");

  int lines = 0;
  if (ioctl(fd, TIOCMGET, &lines) != 0) return fail("TIOCMGET");
  printf("cts=%d dtr=%d\n", (lines & TIOCM_CTS) != 0, (lines & TIOCM_DTR) != 0);

  if (write_all(fd, "PING\n") != 0) return fail("write PING");
  char line[64];
  size_t length = 0;
  while (length < sizeof line - 1) {
    ssize_t got = read(fd, line + length, 1);
    if (got <= 0) return fail("read");
    length += (size_t)got;
    if (line[length - 1] == '\n') break;
  }
  line[length] = '\0';
  printf("read: %s", line);
  fflush(stdout);
  close(fd);
  return 0;
}
