/* A driver whose crash needs two conditions on the device's three-byte
 * reply ("ABC" as recorded), one after the other: byte 0 with its top bit
 * set, then byte 2 with its top bit set, byte 1 as recorded. Blind random
 * plans rarely change both bytes, and only them, in one plan; with AFL++'s
 * coverage the plan that meets the first condition lights a new edge,
 * joins the corpus, and its mutations meet the second
 * (tests/python/fuzz/test_afl_coverage.py and bench/fuzz_coverage_bench.py
 * build it with afl-clang-fast).
 *
 * Usage: two_step_driver PORT. Writes "Q\n", reads the reply (0.5 s at
 * most: past the replay's tolerance of 100 ms), exits 0 on any reply it
 * does not crash on, 1 on a short one. */
#include <fcntl.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <termios.h>
#include <unistd.h>

static void crash_if_both_set(const unsigned char* reply) {
  if (reply[0] & 0x80) {
    fprintf(stderr, "first condition met\n");
    if ((reply[2] & 0x80) && reply[1] == 'B') abort();
  }
}

int main(int argc, char** argv) {
  if (argc != 2) {
    fprintf(stderr, "usage: %s PORT\n", argv[0]);
    return 2;
  }
  int fd = open(argv[1], O_RDWR | O_NOCTTY);
  if (fd < 0) {
    perror(argv[1]);
    return 1;
  }
  struct termios tio;
  if (tcgetattr(fd, &tio) == 0) {
    cfmakeraw(&tio);
    tcsetattr(fd, TCSANOW, &tio);
  }
  if (write(fd, "Q\n", 2) != 2) return 1;
  unsigned char reply[3] = {0, 0, 0};
  size_t got = 0;
  while (got < sizeof reply) {
    struct pollfd ready = {fd, POLLIN, 0};
    if (poll(&ready, 1, 500) <= 0) break;
    ssize_t n = read(fd, reply + got, sizeof reply - got);
    if (n <= 0) break;
    got += (size_t)n;
  }
  if (got < sizeof reply) return 1;
  crash_if_both_set(reply);
  return 0;
}
