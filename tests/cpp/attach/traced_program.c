/* A program to attach to (tests/cpp/attach, tests/python/cli/test_attach*.py):
 * it serves a device descriptor, answering each read with "ok:" and what it
 * read, and obeys a few commands that exercise what an attached recording
 * follows. Any EINTR it sees is a failure of the tracer (an interrupted
 * system call must restart): it says so on stdout and exits 3.
 *
 *   traced_program tty PATH        read/write on a terminal (raw mode)
 *   traced_program threads PATH    a reader thread (readv) and a writer
 *                                  thread (writev, one line per byte on stdin)
 *   traced_program tcp HOST PORT   recv/send on a TCP connection
 *   traced_program udp HOST PORT   recvmsg/sendmsg on a connected UDP socket
 *   traced_program bench N         (bench/attach_bench.py) prints "ready FD" (a pipe's
 *                                  write end), then at each line on stdin writes
 *                                  and reads one byte through the pipe N times and
 *                                  prints the ns per system call
 *
 * Commands (a read that starts with one): "baud N" (TCSETS2, any rate),
 * "dtr" (a DTR pulse: TIOCMBIC then TIOCMBIS), "break", "flush" (TCIOFLUSH),
 * "reopen" (close and open PATH again), "closerange" (the same with close_range), "dup" (move to a dup of the
 * descriptor), "splice" (a splice from it), "signals" (answers usr1=COUNT), "exit N", "exec" (executes
 * itself again with the same arguments).
 * It prints "ready" on stdout once serving (with its port for udp). */
#define _GNU_SOURCE
#include <arpa/inet.h>
#include <asm/termbits.h>
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <sys/uio.h>
#include <time.h>
#include <unistd.h>

static volatile sig_atomic_t usr1_count = 0;
static char** program_argv;

static void on_usr1(int signal) {
  (void)signal;
  ++usr1_count;
}

static void fail(const char* what) {
  printf("%s: %s\n", what, errno == EINTR ? "EINTR" : strerror(errno));
  fflush(stdout);
  exit(3);
}

static void make_raw(int fd) {
  struct termios2 t;
  if (ioctl(fd, TCGETS2, &t) != 0) fail("TCGETS2");
  t.c_iflag &= ~(IGNBRK | BRKINT | PARMRK | ISTRIP | INLCR | IGNCR | ICRNL | IXON);
  t.c_oflag &= ~OPOST;
  t.c_lflag &= ~(ECHO | ECHONL | ICANON | ISIG | IEXTEN);
  t.c_cflag &= ~(CSIZE | PARENB);
  t.c_cflag |= CS8;
  if (ioctl(fd, TCSETS2, &t) != 0) fail("TCSETS2");
}

static void set_baud(int fd, unsigned baud) {
  struct termios2 t;
  if (ioctl(fd, TCGETS2, &t) != 0) fail("TCGETS2");
  t.c_cflag &= ~CBAUD;
  t.c_cflag |= BOTHER;
  t.c_ispeed = baud;
  t.c_ospeed = baud;
  if (ioctl(fd, TCSETS2, &t) != 0) fail("TCSETS2 baud");
}

enum kind { TTY, TCP, UDP };

static ssize_t get(enum kind kind, int fd, char* buffer, size_t size) {
  if (kind == TCP) return recv(fd, buffer, size, 0);
  if (kind == UDP) {
    struct iovec iov = {buffer, size};
    struct msghdr message = {0};
    message.msg_iov = &iov;
    message.msg_iovlen = 1;
    return recvmsg(fd, &message, 0);
  }
  return read(fd, buffer, size);
}

static void put(enum kind kind, int fd, const char* data, size_t size) {
  ssize_t done;
  if (kind == TCP) {
    done = send(fd, data, size, 0);
  } else if (kind == UDP) {
    struct iovec iov = {(void*)data, size};
    struct msghdr message = {0};
    message.msg_iov = &iov;
    message.msg_iovlen = 1;
    done = sendmsg(fd, &message, 0);
  } else {
    done = write(fd, data, size);
  }
  if (done != (ssize_t)size) fail("write");
}

static int open_tty(const char* path) {
  const int fd = open(path, O_RDWR | O_NOCTTY);
  if (fd < 0) fail("open");
  return fd;
}

static int connect_to(int type, const char* host, const char* port) {
  struct sockaddr_in address = {0};
  address.sin_family = AF_INET;
  address.sin_port = htons((unsigned short)atoi(port));
  inet_pton(AF_INET, host, &address.sin_addr);
  const int fd = socket(AF_INET, type, 0);
  if (fd < 0 || connect(fd, (struct sockaddr*)&address, sizeof address) != 0) fail("connect");
  return fd;
}

static int starts(const char* data, const char* command) {
  return strncmp(data, command, strlen(command)) == 0;
}

static void serve(enum kind kind, int fd, const char* path) {
  char buffer[4096];
  char answer[4200];
  for (;;) {
    const ssize_t got = get(kind, fd, buffer, sizeof buffer - 1);
    if (got < 0) fail("read");
    if (got == 0) exit(0);
    buffer[got] = '\0';
    if (starts(buffer, "baud ")) {
      set_baud(fd, (unsigned)atoi(buffer + 5));
    } else if (starts(buffer, "dtr")) {
      int dtr = TIOCM_DTR;
      ioctl(fd, TIOCMBIC, &dtr);  /* a pty has no modem lines: ENOTTY, recorded as not applied */
      ioctl(fd, TIOCMBIS, &dtr);
    } else if (starts(buffer, "break")) {
      if (ioctl(fd, TCSBRK, 0) != 0) fail("TCSBRK");
    } else if (starts(buffer, "flush")) {
      if (ioctl(fd, TCFLSH, TCIOFLUSH) != 0) fail("TCFLSH");
    } else if (starts(buffer, "reopen")) {
      close(fd);
      fd = open_tty(path);
    } else if (starts(buffer, "closerange")) {
      /* closed by close_range (as glibc's closefrom), then opened again */
      if (syscall(SYS_close_range, fd, fd, 0) != 0) fail("close_range");
      fd = open_tty(path);
    } else if (starts(buffer, "splice")) {
      /* Bytes moved in the kernel, which an attached recording cannot see:
       * its warning is the point, whether the terminal splices or not. */
      int pipe_fds[2];
      if (pipe(pipe_fds) != 0) fail("pipe");
      const int flags = fcntl(fd, F_GETFL);
      fcntl(fd, F_SETFL, flags | O_NONBLOCK);  /* nothing to read: EAGAIN, not a wait */
      (void)splice(fd, NULL, pipe_fds[1], NULL, 1, SPLICE_F_NONBLOCK);
      fcntl(fd, F_SETFL, flags);
      close(pipe_fds[0]);
      close(pipe_fds[1]);
    } else if (starts(buffer, "dup")) {
      const int moved = dup(fd);
      if (moved < 0) fail("dup");
      close(fd);
      fd = moved;
    }
    int length;
    if (starts(buffer, "signals")) {
      length = snprintf(answer, sizeof answer, "usr1=%d\n", (int)usr1_count);
    } else {
      length = snprintf(answer, sizeof answer, "ok:%s", buffer);
    }
    put(kind, fd, answer, (size_t)length);
    if (starts(buffer, "exit ")) exit(atoi(buffer + 5));
    if (starts(buffer, "exec")) {
      execv("/proc/self/exe", program_argv);
      fail("exec");
    }
  }
}

static int threads_fd;

static void* reader(void* unused) {
  (void)unused;
  char buffer[4096];
  for (;;) {
    struct iovec iov[2] = {{buffer, 3}, {buffer + 3, sizeof buffer - 3}};
    const ssize_t got = readv(threads_fd, iov, 2);
    if (got < 0) fail("readv");
    if (got == 0) exit(0);
    /* what it read, on stdout: the test's tee of the rx direction */
    printf("read %zd\n", got);
    fflush(stdout);
  }
  return NULL;
}

static void* writer(void* unused) {
  (void)unused;
  char byte;
  int count = 0;
  for (;;) {
    const ssize_t got = read(0, &byte, 1);
    if (got < 0) fail("stdin");
    if (got == 0) exit(0);
    char line[64];
    const int length = snprintf(line, sizeof line, "line %d from the writer\n", ++count);
    struct iovec iov[2] = {{line, 5}, {line + 5, (size_t)length - 5}};
    if (writev(threads_fd, iov, 2) != length) fail("writev");
  }
  return NULL;
}

static void bench(long rounds) {
  int fds[2];
  if (pipe(fds) != 0) fail("pipe");
  printf("ready %d\n", fds[1]);
  fflush(stdout);
  char line[16];
  while (fgets(line, sizeof line, stdin) != NULL) {
    struct timespec start, end;
    char byte = 'x';
    clock_gettime(CLOCK_MONOTONIC, &start);
    for (long i = 0; i < rounds; ++i) {
      if (write(fds[1], &byte, 1) != 1 || read(fds[0], &byte, 1) != 1) fail("bench");
    }
    clock_gettime(CLOCK_MONOTONIC, &end);
    const double ns = (double)(end.tv_sec - start.tv_sec) * 1e9 + (double)(end.tv_nsec - start.tv_nsec);
    printf("%.1f\n", ns / (2.0 * (double)rounds));
    fflush(stdout);
  }
}

int main(int argc, char** argv) {
  program_argv = argv;
  struct sigaction action = {0};
  action.sa_handler = on_usr1;
  action.sa_flags = SA_RESTART;
  sigemptyset(&action.sa_mask);
  sigaction(SIGUSR1, &action, NULL);
  if (argc == 3 && strcmp(argv[1], "tty") == 0) {
    const int fd = open_tty(argv[2]);
    make_raw(fd);
    printf("ready\n");
    fflush(stdout);
    serve(TTY, fd, argv[2]);
  } else if (argc == 3 && strcmp(argv[1], "threads") == 0) {
    threads_fd = open_tty(argv[2]);
    make_raw(threads_fd);
    pthread_t threads[2];
    pthread_create(&threads[0], NULL, reader, NULL);
    pthread_create(&threads[1], NULL, writer, NULL);
    printf("ready\n");
    fflush(stdout);
    pthread_join(threads[0], NULL);
  } else if (argc == 3 && strcmp(argv[1], "bench") == 0) {
    bench(atol(argv[2]));
  } else if (argc == 4 && (strcmp(argv[1], "tcp") == 0 || strcmp(argv[1], "udp") == 0)) {
    const int udp = strcmp(argv[1], "udp") == 0;
    const int fd = connect_to(udp ? SOCK_DGRAM : SOCK_STREAM, argv[2], argv[3]);
    struct sockaddr_in local;
    socklen_t length = sizeof local;
    getsockname(fd, (struct sockaddr*)&local, &length);
    printf("ready %d\n", ntohs(local.sin_port));
    fflush(stdout);
    serve(udp ? UDP : TCP, fd, NULL);
  } else {
    fprintf(stderr, "usage: traced_program tty|threads PATH | tcp|udp HOST PORT\n");
    return 2;
  }
  return 0;
}
