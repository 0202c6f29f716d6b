// Fuzzes the replay engine through the port a client sees: the input encodes
// a session (written with the real SessionWriter, so every record's CRC is
// valid and the fuzzer explores content, not CRC rejection), replay options,
// and a sequence of client calls. Every call must return or raise one of
// wiretape's documented errors (OptionError, PortError/PortClosed,
// ReplayMismatch, SessionError); anything else aborts.
//
// Replay never paces in real time here: timing=none, or timing=session at
// speed 1e6 (a session of microsecond steps plays in nanoseconds; data
// stamped decades ahead is simply never due) for the check=timing event
// checks, which timing=none refuses. Reads wait at most
// 1 ms and never block without a timeout, so no input can hang.
//
// Layout (every field optional: a short input uses defaults):
//   byte 0   options: match, check, unmatched, repeat, at_end, unused
//   byte 1   port type (serial, tcp, udp) and capture
//   byte 2   record count (mod 48); then per record:
//            kind, time step (µs, or with the top bit set (step & 0x7F) << 57
//            ns), size (mod 64), that many payload bytes
//            (an event's payload is a canned valid JSON when the kind byte's
//            top bit is set, else the raw bytes)
//   rest     client calls: an opcode byte and its arguments, at most 256
#include <poll.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <iterator>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz_files.hpp"
#include "session/format.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

namespace {

using wiretape::RecordKind;

// WIRETAPE_FUZZ_TRACE=1 prints each call's outcome, to read a finding.
bool tracing() {
  static const bool on = std::getenv("WIRETAPE_FUZZ_TRACE") != nullptr;
  return on;
}

void trace(const char* what, const std::string& detail) {
  if (tracing()) std::fprintf(stderr, "  %s: %s\n", what, detail.c_str());
}

class InputBytes {
 public:
  InputBytes(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}
  bool empty() const { return position_ >= size_; }
  std::uint8_t byte() { return empty() ? 0 : data_[position_++]; }
  std::string bytes(std::size_t count) {
    const std::size_t taken = std::min(count, size_ - std::min(position_, size_));
    std::string out(reinterpret_cast<const char*>(data_ + position_), taken);
    position_ += taken;
    return out;
  }

 private:
  const std::uint8_t* data_;
  std::size_t size_;
  std::size_t position_ = 0;
};

constexpr RecordKind kKinds[] = {
    RecordKind::rx,           RecordKind::tx,           RecordKind::rx,
    RecordKind::tx,           RecordKind::open,         RecordKind::close,
    RecordKind::flush_input,  RecordKind::flush_output, RecordKind::drain,
    RecordKind::settings,     RecordKind::modem_lines,  RecordKind::line_break,
    RecordKind::client_connect, RecordKind::client_disconnect, RecordKind::device_lost,
    static_cast<RecordKind>(0x42),  // a kind of a newer version: readers skip it
};

std::string canned_event(RecordKind kind, std::uint8_t variant) {
  switch (kind) {
    case RecordKind::settings:
      return variant & 1 ? R"({"baud":115200,"databits":8,"parity":"none","stopbits":1})"
                         : R"({"baud":9600})";
    case RecordKind::modem_lines:
      return variant & 1 ? R"({"dtr":true})" : R"({"rts":false})";
    case RecordKind::line_break:
      return R"({"duration_ms":0})";
    default:
      return "{}";
  }
}

struct Session {
  std::string rx_stream;            // every rx payload, in order
  std::vector<std::string> tx;      // each tx payload
  bool datagrams = false;
};

Session write_session(InputBytes& input, const std::string& path) {
  Session session;
  const std::uint8_t type = input.byte();
  static const char* const kTypes[] = {"serial", "tcp", "udp", ""};
  wiretape::SessionHeader header;
  wiretape::FlushPolicy flush;
  header.port_type = kTypes[type & 3];
  session.datagrams = header.port_type == "udp";
  header.capture = type & 4 ? wiretape::Capture::wire : wiretape::Capture::client;
  flush.interval = std::chrono::milliseconds(1000);
  header.start_utc = "2026-11-23T00:00:00Z";
  header.host = "fuzz";
  header.wiretape_version = "fuzz";
  wiretape::SessionWriter writer(path, header, flush);
  const std::size_t count = input.byte() % 48;
  std::uint64_t t_ns = 0;
  for (std::size_t i = 0; i < count && !input.empty(); ++i) {
    const std::uint8_t kind_byte = input.byte();
    const RecordKind kind = kKinds[(kind_byte & 0x7F) % std::size(kKinds)];
    // A step with the top bit set is huge, for the due-time arithmetic at
    // its limits: it saturates at the format's bound (a writer refuses
    // later times, so no valid file has them); otherwise microseconds.
    const std::uint8_t step = input.byte();
    const std::uint64_t room = wiretape::detail::max_record_t_ns - t_ns;
    const std::uint64_t delta =
        step & 0x80 ? std::uint64_t{step & 0x7Fu} << 57 : std::uint64_t{step} * 1000;
    t_ns += delta < room ? delta : room;
    const std::size_t size = input.byte() % 64;
    std::string payload = input.bytes(size);
    const bool data_kind = kind == RecordKind::rx || kind == RecordKind::tx;
    if (!data_kind && (kind_byte & 0x80)) payload = canned_event(kind, kind_byte);
    try {
      writer.write(kind, t_ns, payload);
    } catch (const std::invalid_argument&) {
      // Content no valid file holds (an event payload that is not a JSON
      // object): the reader's refusal of it is session_reader_fuzz's job.
      continue;
    }
    if (kind == RecordKind::rx) session.rx_stream += payload;
    if (kind == RecordKind::tx) session.tx.push_back(payload);
  }
  writer.close();
  return session;
}

std::string replay_options(std::uint8_t bits, const std::string& path) {
  std::string options = "type=replay,file=" + path + ",timeout=0";
  options += bits & 1 ? ",match=request" : ",match=sequence";
  switch ((bits >> 1) & 3) {
    case 0: options += ",check=off,timing=none"; break;
    case 1: options += ",check=data,timing=none"; break;
    case 2: options += ",strictness=0,ignoretimes"; break;  // flexiport's spellings
    default: options += ",check=timing,timing=session,speed=1000000,tolerance=1000000000"; break;
  }
  options += bits & 8 ? ",unmatched=silent" : ",unmatched=error";
  static const char* const kRepeat[] = {",repeat=none", ",repeat=last", ",repeat=cycle", ""};
  options += kRepeat[(bits >> 4) & 3];
  options += bits & 0x40 ? ",at_end=closed" : ",at_end=silent";
  options += bits & 0x80 ? ",unused=error" : ",unused=ignore";
  return options;
}

std::chrono::nanoseconds small_timeout(std::uint8_t arg) {
  // Mostly zero; now and then up to 1 ms, so that waiting paths run too.
  return std::chrono::nanoseconds(arg & 0x80 ? (arg & 0x7F) * 8000 : 0);
}

// What a client read since it opened the port; in match=sequence, with no
// flush_input and no datagram truncation, it must be a prefix of the
// recorded rx stream.
class ReadCheck {
 public:
  ReadCheck(const Session& session, bool sequence)
      : session_(session), exact_(sequence && !session.datagrams) {}
  void reset() { read_.clear(); }
  void lose_exactness() { exact_ = false; }
  void got(std::string_view bytes) {
    if (!exact_) return;
    read_ += bytes;
    if (read_.size() > session_.rx_stream.size() ||
        session_.rx_stream.compare(0, read_.size(), read_) != 0) {
      std::abort();  // the replay handed out bytes that were never recorded
    }
  }

 private:
  const Session& session_;
  bool exact_;
  std::string read_;
};

bool handle_readable(int fd) {
  pollfd entry{fd, POLLIN, 0};
  return ::poll(&entry, 1, 0) == 1 && (entry.revents & POLLIN);
}

void run_call(InputBytes& input, std::unique_ptr<wiretape::Port>& port,
              const std::string& options, const Session& session, ReadCheck& check,
              int& waits) {
  const std::uint8_t opcode = input.byte();
  const std::uint8_t arg = input.byte();
  char buffer[256];
  trace("call", std::to_string(opcode % 16) + " " + std::to_string(arg));
  switch (opcode % 16) {
    case 0: {  // write fuzzed bytes
      const std::string bytes = input.bytes(arg % 32);
      const std::size_t written = port->write(bytes.data(), bytes.size(), std::chrono::nanoseconds(0));
      if (written > bytes.size()) std::abort();
      break;
    }
    case 1: {  // write a recorded tx payload, whole or a prefix of it
      if (session.tx.empty()) break;
      const std::string& recorded = session.tx[input.byte() % session.tx.size()];
      const std::size_t size = arg & 0x80 ? recorded.size() : std::min<std::size_t>(recorded.size(), arg);
      port->write_all(recorded.data(), size, std::chrono::nanoseconds(0));
      break;
    }
    case 2:
    case 3: {  // read
      const std::size_t want = arg % sizeof(buffer) + 1;
      auto timeout = small_timeout(input.byte());
      if (timeout.count() > 0 && ++waits > 8) timeout = std::chrono::nanoseconds(0);
      const std::size_t got = port->read(buffer, want, timeout);
      if (got > want) std::abort();
      check.got(std::string_view(buffer, got));
      break;
    }
    case 4: {  // read_until (peeks ahead)
      const char delimiter[] = {static_cast<char>(input.byte())};
      const std::string got = port->read_until(std::string_view(delimiter, 1), arg + 1,
                                               std::chrono::nanoseconds(0));
      if (got.size() > std::size_t{arg} + 1) std::abort();
      check.got(got);
      break;
    }
    case 5: {
      const std::string got = port->read_exactly(arg, std::chrono::nanoseconds(0));
      if (got.size() > arg) std::abort();
      check.got(got);
      break;
    }
    case 6: {  // skip_until: bytes are consumed without being seen
      check.lose_exactness();
      const char delimiter[] = {static_cast<char>(arg)};
      port->skip_until(std::string_view(delimiter, 1), std::chrono::nanoseconds(0));
      break;
    }
    case 7: {  // what available() promises: a readable handle, a read that takes it at once
      const std::size_t available = port->available();
      if (available == 0) break;
      if (!handle_readable(port->native_handle())) std::abort();
      if (!port->wait_readable(std::chrono::nanoseconds(0))) std::abort();
      if (arg & 1) {
        const std::size_t want = std::min(available, sizeof(buffer));
        const std::size_t got = port->read(buffer, want, std::chrono::nanoseconds(0));
        if (got != want) std::abort();
        check.got(std::string_view(buffer, got));
      }
      break;
    }
    case 8:
      port->wait_readable(std::chrono::nanoseconds(0));
      break;
    case 9:
      check.lose_exactness();
      port->flush_input();
      break;
    case 10:
      if (arg & 1) port->flush_output(); else port->drain();
      break;
    case 11:
      port->close();
      break;
    case 12:  // close and reopen: a new client from the start of the session
      try {
        port->close();
      } catch (const wiretape::ReplayMismatch&) {  // unused=error
      }
      port = wiretape::open_port(options);
      check.reset();
      break;
    case 13:
      if (arg & 1) port->set_baud(arg & 2 ? 115200 : 9600);
      else {
        wiretape::SerialSettings settings;
        settings.baud = arg & 2 ? 115200 : 9600;
        port->configure(settings);
      }
      break;
    case 14:
      if (arg & 1) port->set_dtr(arg & 2); else port->set_rts(arg & 2);
      break;
    default:
      port->send_break(std::chrono::milliseconds(0));
      port->serial_settings();
      break;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  InputBytes input(data, size);
  const std::uint8_t option_bits = input.byte();
  const std::string path = wiretape::fuzz::scratch().file("replay.wtape");
  ::unlink(path.c_str());
  const Session session = write_session(input, path);
  const std::string options = replay_options(option_bits, path);
  std::unique_ptr<wiretape::Port> port;
  try {
    port = wiretape::open_port(options);
  } catch (const wiretape::OptionError& e) {
    trace("OptionError", e.what());
    return 0;
  }
  trace("options", options);
  ReadCheck check(session, (option_bits & 1) == 0);
  int waits = 0;
  for (int calls = 0; calls < 256 && !input.empty(); ++calls) {
    try {
      run_call(input, port, options, session, check, waits);
    } catch (const wiretape::ReplayMismatch& e) {
      trace("ReplayMismatch", e.what());
    } catch (const wiretape::PortError& e) {  // PortClosed included
      trace("PortError", e.what());
    } catch (const wiretape::SessionError& e) {
      trace("SessionError", e.what());
    }
  }
  try {
    port->close();
  } catch (const wiretape::ReplayMismatch&) {
  } catch (const wiretape::PortError&) {
  }
  return 0;
}
