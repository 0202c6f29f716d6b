// The bridge: forwards bytes between a device port and a client side (a
// pseudo-terminal a program opens, a TCP listener, or a UDP socket programs
// send datagrams to), optionally recording
// everything that crosses into a session file (capture=wire: every byte,
// stamped on arrival, time zero at the device's open). It is the engine of
// `wiretape record` (transparent proxy), `wiretape replay --pty/--listen`
// (virtual devices) and `wiretape serve` (port server, raw or RFC 2217).
//
// On UDP one datagram is one record both ways: each client datagram is one
// write to the device, each read of the device one datagram to the client.
// UDP cannot hold a client back, so a client that sends faster than the
// device takes its datagrams loses the excess (at most 1024 datagrams and
// buffer_limit bytes wait), counted in BridgeStats::datagrams_dropped and
// never recorded.
//
// Buffers are bounded (BridgeOptions::buffer_limit per direction and client):
//   - client -> device: when full, the bridge stops reading that client, so
//     TCP flow control (or the terminal's buffer) holds the client back;
//   - device -> the controlling client (or the pty): when full, the bridge
//     stops reading the device; the device's own buffer then fills (a serial
//     device that keeps sending may overrun in the kernel);
//   - device -> read-only monitor clients (--shared): when a monitor falls
//     behind by more than the bound, the new data is dropped for it (and
//     counted in BridgeStats::bytes_dropped); the device is never held back
//     for a monitor. At most max_monitors monitors are accepted;
//   - server -> a client, RFC 2217 answers and device data in one queue:
//     while it is full the bridge stops reading that client, whose requests
//     (and data) wait in TCP until it reads its answers.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "wiretape/recorder.hpp"
#include "wiretape/timeout.hpp"

namespace wiretape {

enum class BridgeClientSide {
  pty,  // a pseudo-terminal; a program opens it as if it were the device
  tcp,  // a TCP listener; programs connect to it
  udp,  // a UDP socket at listen_host:listen_port; programs send datagrams to it
};

enum class BridgeProtocol {
  raw,      // bytes both ways, unchanged
  rfc2217,  // Telnet COM-PORT-CONTROL (RFC 2217): clients set the line
};

struct BridgeOptions {
  // The device: a port option string ("type=serial,device=/dev/ttyUSB0",
  // "type=replay,file=a.wtape", ...). Reopened from this string by `reopen`
  // and `restart`.
  std::string device;

  BridgeClientSide client_side = BridgeClientSide::pty;
  // pty: a symbolic link to the terminal ("" for none; the terminal's own
  // path is in Bridge::pty_path()).
  std::string pty_link;
  // pty: who may open the terminal, set on its node (/dev/pts/N) as on a
  // real serial device, so that a client that drops root can open it:
  // permission bits (at most 0777) and a group, by name or number. "" means
  // dialout where that group exists (falling back, with a message, to the
  // process's group where this user may not give the terminal to it), else
  // the process's own group.
  unsigned pty_mode = 0660;
  std::string pty_group;
  // tcp (and udp): where to listen. 127.0.0.1 unless told otherwise; port 0 picks a
  // free port (see Bridge::listen_address()).
  std::string listen_host = "127.0.0.1";
  int listen_port = 0;
  // tcp: how many connections the kernel completes and holds for the bridge
  // to accept (listen(2)'s backlog; at least 1). Linux caps it at
  // net.core.somaxconn (4096 since Linux 5.4, 128 before). A small backlog
  // makes a burst of clients time out in their SYN retries.
  int listen_backlog = 4096;
  // udp: where device datagrams go. "" (the default): to the last sender,
  // and a client session starts with its first datagram; a host and port:
  // always there, and the client session starts at once.
  std::string udp_peer_host;
  int udp_peer_port = 0;
  BridgeProtocol protocol = BridgeProtocol::raw;
  // tcp: a client that connects while another one controls the device gets
  // read-only monitoring (device data, its input ignored) instead of being
  // refused.
  bool shared = false;
  // tcp, shared: at most this many monitors at once (at least 1); more are
  // refused with a message. Each may hold buffer_limit bytes the device sent.
  std::size_t max_monitors = 16;

  // pty: a Unix socket to create at this path ("" for none), where the
  // `--as` shim (WIRETAPE_LINE_CHANNEL) tells what its program does to the
  // serial lines a pty lacks: DTR/RTS, break, custom baud; and asks for the
  // device's CTS/DSR/RI/CD (DESIGN.md section 20). The path must not exist.
  std::string line_channel;

  // Session file to record into ("" records nothing), with free metadata.
  std::string output;
  std::map<std::string, std::string> metadata;
  int flush_ms = 100;
  // How `output` stores its records (`--compress zstd`: chunks, format 2.0).
  Compression compression = Compression::none;
  // Sessions of several ports (DESIGN §19): record into the channel named
  // `channel` (capture=wire, the device's options, identity and address in
  // its entry) of this recorder's file, on its clock, instead of opening
  // `output` (which must then be "", and `metadata` empty: it belongs in the
  // recorder's header; the recorder's flush policy applies, not flush_ms).
  // The file is the recorder's: the bridge neither closes nor removes it.
  std::shared_ptr<Recorder> recorder;
  std::string channel;

  // pty: apply the terminal settings the client sets (baud, stop bits...) to
  // the device, recording a settings event.
  bool mirror_settings = true;
  // When the device goes away: reopen it once it is back (retrying every
  // reopen_interval) instead of ending.
  bool reopen = false;
  std::chrono::milliseconds reopen_interval{250};
  // Each new client starts the device over (closes and reopens it; for a
  // replay, the session restarts). On a pty (Linux) a new client is the
  // first open of the terminal after every opener had closed it. Otherwise
  // a client that reconnects continues where the previous one left off.
  bool restart = false;
  // End by itself after this long (record --duration).
  Timeout duration = forever;
  std::size_t buffer_limit = 1 << 20;
  // Diagnostics (client connects, device loss, settings) go to stderr
  // prefixed "wiretape: " unless quiet; Bridge::messages() keeps them too.
  bool quiet = false;
};

struct BridgeStats {
  std::uint64_t bytes_to_device = 0;    // client -> device, delivered
  std::uint64_t bytes_from_device = 0;  // device -> bridge
  std::uint64_t bytes_dropped = 0;      // for monitors that fell behind
  std::uint64_t clients_accepted = 0;
  std::uint64_t clients_refused = 0;
  std::uint64_t settings_changes = 0;
  std::uint64_t device_losses = 0;
  std::uint64_t device_reopens = 0;
  std::uint64_t records_written = 0;
  // udp: datagrams a client sent while the queue to the device was full,
  // neither forwarded nor recorded.
  std::uint64_t datagrams_dropped = 0;
  // udp device side (record --udp): datagrams from a sender other than the
  // device, dropped, neither recorded nor forwarded. The kernel drops most
  // of them before they are read (the device side is connected to the
  // device); this counts those that reached the socket.
  std::uint64_t datagrams_from_others = 0;
  // udp with a peer (replay --udp --peer): datagrams the peer refused
  // (nobody listened there: ICMP port unreachable), not served.
  std::uint64_t datagrams_refused = 0;
};

enum class BridgeOutcome {
  running,
  stopped,        // stop() was called
  finished,       // the duration elapsed
  device_closed,  // the device went away (or a replay's recorded close) and
                  // reopen was off
  mismatch,       // the replayed client diverged from the recording
  failed,         // a runtime error (device or file I/O)
};

std::string_view to_string(BridgeOutcome outcome);

struct BridgeResult {
  BridgeOutcome outcome = BridgeOutcome::running;
  // The mismatch report, the error, or why the device closed.
  std::string message;
  BridgeStats stats;
  // A replay whose recording has rx but that served none of it to any
  // client says why here ("no client connected before the end", ...); ""
  // otherwise, and for every device that is not a replay. The outcome is
  // left as it was: `wiretape replay` turns this into exit 1.
  std::string nothing_served;
  // The replay's device was lost by an injected fault (disconnect), and that
  // ended the bridge: the client is not to blame, and a command run against
  // the replay is left to react to the loss.
  bool ended_by_fault = false;
  // True unless outcome is mismatch or failed.
  bool ok() const {
    return outcome != BridgeOutcome::mismatch && outcome != BridgeOutcome::failed;
  }
};

class Bridge {
 public:
  // Checks the options (OptionError naming the problem); opens nothing yet.
  explicit Bridge(BridgeOptions options);
  ~Bridge();  // stops and waits; never throws
  Bridge(const Bridge&) = delete;
  Bridge& operator=(const Bridge&) = delete;

  // Opens the device, the client side and the session file, then forwards on
  // a thread of its own. Throws OptionError / PortError / SessionError when
  // something cannot be opened (nothing is left running then).
  void start();
  // Ends forwarding; the session file is closed complete. Thread-safe,
  // idempotent, may be called before start().
  void stop();
  // True once the bridge has ended (by stop(), the duration, a mismatch, an
  // error); false if `timeout` expired first.
  bool wait(Timeout timeout = forever);
  bool running() const;
  BridgeResult result() const;
  BridgeStats stats() const;

  // The terminal a client opens (pty side), e.g. "/dev/pts/7".
  std::string pty_path() const;
  // The address clients connect (tcp) or send datagrams (udp) to, e.g.
  // "127.0.0.1:5000".
  std::string listen_address() const;
  std::string device_description() const;
  // The diagnostics so far (the most recent 1000).
  std::vector<std::string> messages() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace wiretape
