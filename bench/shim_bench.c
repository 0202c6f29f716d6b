/* The --as shim's added cost (DESIGN §20, docs/benchmarks.md): run once
 * with the shim preloaded and once without, by bench/run.py's `shim`
 * figure, which reports the differences.
 *
 *   shim_bench PATH MASTER_FD ROUNDS
 *
 * PATH is the terminal to open (under the shim: a name redirected to it),
 * MASTER_FD its master, inherited. Prints one JSON line of nanoseconds per
 * call: `redirected_write` (a 1-byte write to the terminal; the bytes are
 * taken at the master between blocks, untimed), `redirected_read` (a 1-byte
 * read of the terminal, the bytes given at the master before, untimed), `unrelated_write` (a 1-byte write to /dev/null),
 * `unrelated_close` (close of a dup of /dev/null's descriptor, with the dup),
 * `unrelated_getpid` (a call the shim does not wrap). */
#define _GNU_SOURCE
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

static double now_ns(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec * 1e9 + (double)t.tv_nsec;
}

int main(int argc, char **argv) {
  if (argc != 4) {
    fprintf(stderr, "usage: shim_bench PATH MASTER_FD ROUNDS\n");
    return 2;
  }
  const int master = atoi(argv[2]);
  const long rounds = atol(argv[3]);
  int fd = open(argv[1], O_RDWR | O_NOCTTY);
  int null = open("/dev/null", O_WRONLY);
  if (fd < 0 || null < 0) {
    perror("shim_bench: open");
    return 1;
  }
  struct termios raw;
  tcgetattr(fd, &raw);
  cfmakeraw(&raw);
  tcsetattr(fd, TCSANOW, &raw);
  char byte = 'x';

  /* Only the calls on the terminal are timed, in blocks that fit its
   * buffer; moving the bytes through the other end is not. */
  enum { kBlock = 256 };
  char block[kBlock];
  memset(block, 'x', sizeof block);
  double writing = 0, reading = 0;
  const long blocks = rounds / kBlock + 1;
  for (long b = 0; b < blocks; ++b) {
    double start = now_ns();
    for (int i = 0; i < kBlock; ++i) {
      if (write(fd, &byte, 1) != 1) return 1;
    }
    writing += now_ns() - start;
    for (size_t got = 0; got < kBlock;) {
      ssize_t n = read(master, block, kBlock - got);
      if (n <= 0) return 1;
      got += (size_t)n;
    }

    if (write(master, block, kBlock) != kBlock) return 1;
    for (int waiting = 0; waiting < kBlock;) {
      if (ioctl(fd, FIONREAD, &waiting) != 0) return 1;
    }
    start = now_ns();
    for (int i = 0; i < kBlock; ++i) {
      if (read(fd, &byte, 1) != 1) return 1;
    }
    reading += now_ns() - start;
  }
  const double redirected_write = writing / (double)(blocks * kBlock);
  const double redirected_read = reading / (double)(blocks * kBlock);

  const long many = rounds * 20;
  double start = now_ns();
  for (long i = 0; i < many; ++i) {
    if (write(null, &byte, 1) != 1) return 1;
  }
  const double unrelated_write = (now_ns() - start) / (double)many;

  start = now_ns();
  for (long i = 0; i < many; ++i) {
    int copy = dup(null);
    if (copy < 0 || close(copy) != 0) return 1;
  }
  const double unrelated_close = (now_ns() - start) / (double)many;

  start = now_ns();
  for (long i = 0; i < many; ++i) {
    if (getpid() <= 0) return 1;
  }
  const double unrelated_getpid = (now_ns() - start) / (double)many;

  printf("{\"redirected_write\": %.1f, \"redirected_read\": %.1f, \"unrelated_write\": %.1f, "
         "\"unrelated_close\": %.1f, \"unrelated_getpid\": %.1f}\n",
         redirected_write, redirected_read, unrelated_write, unrelated_close, unrelated_getpid);
  return 0;
}
