// Attaching to a running program (DESIGN §26) end to end: a small C
// program (traced_program.c) serves a pty or a socket, wiretape attaches in
// the middle of its work, and the recording must hold exactly the bytes that
// crossed while attached, in each direction, and the events of its ioctls;
// the program must go on unharmed after the detach.
#include "wiretape/attach.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "session/record_kinds.hpp"
#include "attach/traced_program.hpp"
#include "support/port_test_support.hpp"

namespace wiretape {
namespace {

using test::kEventDeadline;
using test::Program;

struct Directions {
  std::string rx, tx;
  std::vector<Record> events;
};

Directions directions(const std::string& path) {
  Directions d;
  for (const Record& r : test::load_records(path)) {
    if (r.kind == RecordKind::rx) d.rx += r.data;
    else if (r.kind == RecordKind::tx) d.tx += r.data;
    else d.events.push_back(r);
  }
  return d;
}

std::vector<std::string> event_texts(const Directions& d, RecordKind kind) {
  std::vector<std::string> out;
  for (const Record& r : d.events) {
    if (r.kind == kind) out.push_back(r.data);
  }
  return out;
}

// One exchange with the program over the pty: what it answers.
std::string ask(const test::PtyPair& pty, const std::string& request, std::size_t answer) {
  pty.write_master(request);
  return pty.read_master(answer);
}

AttachOptions options_for(pid_t pid) {
  AttachOptions options;
  options.pid = pid;
  return options;
}

void expect_unharmed(const Program& program) {
  EXPECT_EQ(program.proc_status("TracerPid"), "0");
  EXPECT_NE(program.proc_status("State").rfind("t", 0), 0u) << program.proc_status("State");
}

TEST(Attach, ATtyRecordsWhatCrossedWhileAttachedInEachDirection) {
  test::TempDir dir;
  test::PtyPair pty;
  Program program({"tty", pty.path});
  ASSERT_EQ(program.line(), "ready");
  EXPECT_EQ(ask(pty, "before\n", 10), "ok:before\n");
  const std::string file = dir.file("attached.wtape");
  {
    AttachOptions options = options_for(program.pid);
    options.path = pty.path;
    Attachment attachment(options, file);
    EXPECT_EQ(ask(pty, "one\n", 7), "ok:one\n");
    EXPECT_EQ(ask(pty, "two\n", 7), "ok:two\n");
    attachment.stop();
    ASSERT_TRUE(attachment.wait(kEventDeadline));
    const AttachSummary summary = attachment.summary();
    EXPECT_EQ(summary.ended_by, "stopped");
    EXPECT_EQ(summary.rx_bytes, 8u);
    EXPECT_EQ(summary.tx_bytes, 14u);
  }
  // The program goes on, untraced; its blocked read restarted (an EINTR
  // would have ended it).
  EXPECT_EQ(ask(pty, "after\n", 9), "ok:after\n");
  expect_unharmed(program);
  const Directions d = directions(file);
  EXPECT_EQ(d.rx, "one\ntwo\n");
  EXPECT_EQ(d.tx, "ok:one\nok:two\n");
  SessionReader reader(file);
  const SessionHeader& header = reader.header();
  EXPECT_EQ(header.capture, Capture::client);
  EXPECT_EQ(header.port_type, "serial");
  ASSERT_TRUE(header.attached.has_value());
  EXPECT_EQ(header.attached->pid, program.pid);
  EXPECT_EQ(header.attached->command, "traced_program");
  EXPECT_EQ(header.attached->device, pty.path);
  EXPECT_FALSE(header.attached->utc.empty());
  EXPECT_FALSE(header.attached->descriptors.empty());
}

TEST(Attach, SettingsLinesBreaksAndFlushesAreTheEventsABridgeRecords) {
  test::TempDir dir;
  test::PtyPair pty;
  Program program({"tty", pty.path});
  ASSERT_EQ(program.line(), "ready");
  const std::string file = dir.file("lines.wtape");
  {
    AttachOptions options = options_for(program.pid);
    options.path = pty.path;
    Attachment attachment(options, file);
    EXPECT_EQ(ask(pty, "baud 250000\n", 15), "ok:baud 250000\n");
    EXPECT_EQ(ask(pty, "dtr\n", 7), "ok:dtr\n");
    EXPECT_EQ(ask(pty, "break\n", 9), "ok:break\n");
    EXPECT_EQ(ask(pty, "flush\n", 9), "ok:flush\n");
  }
  const Directions d = directions(file);
  const auto settings = event_texts(d, RecordKind::settings);
  // The settings at attach (read inside the program), then the custom rate.
  ASSERT_EQ(settings.size(), 2u);
  EXPECT_NE(settings[0].find("\"databits\":8"), std::string::npos) << settings[0];
  EXPECT_NE(settings[1].find("\"baud\":250000"), std::string::npos) << settings[1];
  EXPECT_EQ(event_texts(d, RecordKind::modem_lines),
            (std::vector<std::string>{"{\"dtr\":false,\"applied\":false}",
                                      "{\"dtr\":true,\"applied\":false}"}));
  EXPECT_EQ(event_texts(d, RecordKind::line_break),
            std::vector<std::string>{"{\"duration_ms\":250}"});
  EXPECT_EQ(event_texts(d, RecordKind::flush_input).size(), 1u);
  EXPECT_EQ(event_texts(d, RecordKind::flush_output).size(), 1u);
  for (const Record& r : d.events) {
    EXPECT_EQ(detail::event_payload_problem(r.kind, r.data), std::nullopt) << r.data;
  }
}

TEST(Attach, AReaderThreadAndAWriterThreadAreBothRecorded) {
  test::TempDir dir;
  test::PtyPair pty;
  Program program({"threads", pty.path});
  ASSERT_EQ(program.line(), "ready");
  const std::string file = dir.file("threads.wtape");
  std::string sent, answered;
  {
    AttachOptions options = options_for(program.pid);
    options.path = pty.path;
    Attachment attachment(options, file);
    for (int i = 1; i <= 5; ++i) {
      const std::string chunk = "chunk-" + std::to_string(i);
      pty.write_master(chunk);
      sent += chunk;
      EXPECT_EQ(program.line(), "read " + std::to_string(chunk.size()));
      ASSERT_EQ(::write(program.stdin_fd, "x", 1), 1);
      const std::string line = "line " + std::to_string(i) + " from the writer\n";
      EXPECT_EQ(pty.read_master(line.size()), line);
      answered += line;
    }
  }
  const Directions d = directions(file);
  EXPECT_EQ(d.rx, sent);
  EXPECT_EQ(d.tx, answered);
  expect_unharmed(program);
}

TEST(Attach, ATcpClientsStreamIsRecordedFromItsOnlySocket) {
  test::TempDir dir;
  const int listener = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t length = sizeof address;
  ASSERT_EQ(::bind(listener, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
  ASSERT_EQ(::listen(listener, 1), 0);
  ::getsockname(listener, reinterpret_cast<sockaddr*>(&address), &length);
  Program program({"tcp", "127.0.0.1", std::to_string(ntohs(address.sin_port))});
  const int peer = ::accept(listener, nullptr, nullptr);
  ASSERT_GE(peer, 0);
  ASSERT_EQ(program.line().rfind("ready", 0), 0u);
  const auto exchange = [&](const std::string& request) {
    EXPECT_EQ(::write(peer, request.data(), request.size()),
              static_cast<ssize_t>(request.size()));
    return test::read_count(peer, request.size() + 3);
  };
  EXPECT_EQ(exchange("early"), "ok:early");
  const std::string file = dir.file("tcp.wtape");
  {
    Attachment attachment(options_for(program.pid), file);
    EXPECT_EQ(exchange("hello"), "ok:hello");
    EXPECT_EQ(exchange("world"), "ok:world");
  }
  EXPECT_EQ(exchange("late"), "ok:late");
  const Directions d = directions(file);
  EXPECT_EQ(d.rx, "helloworld");
  EXPECT_EQ(d.tx, "ok:hellook:world");
  EXPECT_EQ(SessionReader(file).header().port_type, "tcp");
  ::close(peer);
  ::close(listener);
}

TEST(Attach, AUdpClientsDatagramsAreOneRecordEach) {
  test::TempDir dir;
  const int socket = ::socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t length = sizeof address;
  ASSERT_EQ(::bind(socket, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
  ::getsockname(socket, reinterpret_cast<sockaddr*>(&address), &length);
  Program program({"udp", "127.0.0.1", std::to_string(ntohs(address.sin_port))});
  const std::string ready = program.line();
  ASSERT_EQ(ready.rfind("ready ", 0), 0u);
  sockaddr_in to = address;
  to.sin_port = htons(static_cast<unsigned short>(std::stoi(ready.substr(6))));
  ASSERT_EQ(::connect(socket, reinterpret_cast<sockaddr*>(&to), sizeof to), 0);
  const auto exchange = [&](const std::string& request) {
    EXPECT_EQ(::send(socket, request.data(), request.size(), 0),
              static_cast<ssize_t>(request.size()));
    char buffer[256];
    EXPECT_TRUE(test::fd_readable(socket, std::chrono::milliseconds(10000)));
    const ssize_t got = ::recv(socket, buffer, sizeof buffer, 0);
    return std::string(buffer, got > 0 ? static_cast<std::size_t>(got) : 0);
  };
  EXPECT_EQ(exchange("a"), "ok:a");
  const std::string file = dir.file("udp.wtape");
  {
    Attachment attachment(options_for(program.pid), file);
    EXPECT_EQ(exchange("ping"), "ok:ping");
    EXPECT_EQ(exchange("pong"), "ok:pong");
  }
  std::vector<std::string> rx, tx;
  for (const Record& r : test::load_records(file)) {
    if (r.kind == RecordKind::rx) rx.push_back(r.data);
    if (r.kind == RecordKind::tx) tx.push_back(r.data);
  }
  EXPECT_EQ(rx, (std::vector<std::string>{"ping", "pong"}));
  EXPECT_EQ(tx, (std::vector<std::string>{"ok:ping", "ok:pong"}));
  EXPECT_EQ(SessionReader(file).header().port_type, "udp");
  ::close(socket);
}

TEST(Attach, ASignalSentWhileAttachedArrivesOnce) {
  test::TempDir dir;
  test::PtyPair pty;
  Program program({"tty", pty.path});
  ASSERT_EQ(program.line(), "ready");
  {
    Attachment attachment(options_for(program.pid), dir.file("signal.wtape"));
    EXPECT_EQ(ask(pty, "x\n", 5), "ok:x\n");  // the program is being traced now
    ASSERT_EQ(::kill(program.pid, SIGUSR1), 0);
    EXPECT_EQ(ask(pty, "signals\n", 7), "usr1=1\n");
  }
  EXPECT_EQ(ask(pty, "signals\n", 7), "usr1=1\n");
  expect_unharmed(program);
}

TEST(Attach, AStopAndAContinueWhileAttachedAreTheProgramsOwn) {
  test::TempDir dir;
  test::PtyPair pty;
  Program program({"tty", pty.path});
  ASSERT_EQ(program.line(), "ready");
  const std::string file = dir.file("stopped.wtape");
  {
    Attachment attachment(options_for(program.pid), file);
    EXPECT_EQ(ask(pty, "a\n", 5), "ok:a\n");
    ASSERT_EQ(::kill(program.pid, SIGSTOP), 0);
    // Stopped (its group stop, seen by the tracer and listened to).
    const auto deadline = std::chrono::steady_clock::now() + kEventDeadline;
    while (program.proc_status("State").rfind("t", 0) != 0 &&
           program.proc_status("State").rfind("T", 0) != 0 &&
           std::chrono::steady_clock::now() < deadline) {
      std::this_thread::yield();
    }
    EXPECT_TRUE(program.proc_status("State").rfind("t", 0) == 0 ||
                program.proc_status("State").rfind("T", 0) == 0)
        << program.proc_status("State");
    ASSERT_EQ(::kill(program.pid, SIGCONT), 0);
    EXPECT_EQ(ask(pty, "b\n", 5), "ok:b\n");
  }
  EXPECT_EQ(ask(pty, "c\n", 5), "ok:c\n");
  expect_unharmed(program);
  EXPECT_EQ(directions(file).rx, "a\nb\n");
}

TEST(Attach, TheProgramsExitEndsTheRecordingWithItsOwnStatus) {
  test::TempDir dir;
  test::PtyPair pty;
  Program program({"tty", pty.path});
  ASSERT_EQ(program.line(), "ready");
  const std::string file = dir.file("exit.wtape");
  Attachment attachment(options_for(program.pid), file);
  EXPECT_EQ(ask(pty, "exit 7\n", 10), "ok:exit 7\n");
  ASSERT_TRUE(attachment.wait(kEventDeadline));
  EXPECT_EQ(attachment.summary().ended_by, "exited");
  const int status = program.wait_exit();
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 7);
  EXPECT_EQ(directions(file).rx, "exit 7\n");
}

TEST(Attach, AnExecEndsTheRecordingAndTheNewProgramRunsUntraced) {
  test::TempDir dir;
  test::PtyPair pty;
  Program program({"tty", pty.path});
  ASSERT_EQ(program.line(), "ready");
  Attachment attachment(options_for(program.pid), dir.file("exec.wtape"));
  EXPECT_EQ(ask(pty, "exec\n", 8), "ok:exec\n");
  ASSERT_TRUE(attachment.wait(kEventDeadline));
  EXPECT_EQ(attachment.summary().ended_by, "execed");
  ASSERT_EQ(program.line(), "ready");
  EXPECT_EQ(ask(pty, "again\n", 9), "ok:again\n");
  expect_unharmed(program);
}

TEST(Attach, ACloseIsRecordedAndAReopenOrADupIsFollowed) {
  test::TempDir dir;
  test::PtyPair pty;
  Program program({"tty", pty.path});
  ASSERT_EQ(program.line(), "ready");
  const std::string file = dir.file("reopen.wtape");
  {
    Attachment attachment(options_for(program.pid), file);
    EXPECT_EQ(ask(pty, "reopen\n", 10), "ok:reopen\n");
    EXPECT_EQ(ask(pty, "dup\n", 7), "ok:dup\n");
    EXPECT_EQ(ask(pty, "closerange\n", 14), "ok:closerange\n");
    EXPECT_EQ(ask(pty, "last\n", 8), "ok:last\n");
  }
  const Directions d = directions(file);
  EXPECT_EQ(d.rx, "reopen\ndup\ncloserange\nlast\n");
  EXPECT_EQ(d.tx, "ok:reopen\nok:dup\nok:closerange\nok:last\n");
  EXPECT_EQ(event_texts(d, RecordKind::close).size(), 2u);
  const auto opens = event_texts(d, RecordKind::open);
  ASSERT_EQ(opens.size(), 3u);  // the attach, and the two reopens
  EXPECT_NE(opens[1].find("\"reopened\":true"), std::string::npos) << opens[1];
}

TEST(Attach, BytesMovedBySpliceAreAWarningInTheSummaryAndTheHeader) {
  test::TempDir dir;
  test::PtyPair pty;
  Program program({"tty", pty.path});
  ASSERT_EQ(program.line(), "ready");
  const std::string file = dir.file("splice.wtape");
  AttachSummary summary;
  {
    Attachment attachment(options_for(program.pid), file);
    EXPECT_EQ(ask(pty, "splice\n", 10), "ok:splice\n");
    attachment.stop();
    summary = attachment.summary();
  }
  ASSERT_EQ(summary.warnings.size(), 1u);
  EXPECT_NE(summary.warnings[0].find("splice"), std::string::npos) << summary.warnings[0];
  const SessionHeader header = SessionReader(file).header();
  ASSERT_TRUE(header.attached.has_value());
  EXPECT_EQ(header.attached->warnings, summary.warnings);
}

TEST(Attach, AKilledTracerLeavesTheProgramRunning) {
  test::TempDir dir;
  test::PtyPair pty;
  Program program({"tty", pty.path});
  ASSERT_EQ(program.line(), "ready");
  int attached[2];
  ASSERT_EQ(::pipe(attached), 0);
  const pid_t tracer = ::fork();
  if (tracer == 0) {
    Attachment attachment(options_for(program.pid), dir.file("killed.wtape"));
    ::write(attached[1], "a", 1);
    for (;;) ::pause();
  }
  char c;
  ASSERT_TRUE(test::fd_readable(attached[0], std::chrono::milliseconds(10000)));
  ASSERT_EQ(::read(attached[0], &c, 1), 1);
  EXPECT_EQ(ask(pty, "traced\n", 10), "ok:traced\n");
  ::kill(tracer, SIGKILL);
  ::waitpid(tracer, nullptr, 0);
  EXPECT_EQ(ask(pty, "free\n", 8), "ok:free\n");
  expect_unharmed(program);
  ::close(attached[0]);
  ::close(attached[1]);
}

}  // namespace
}  // namespace wiretape
