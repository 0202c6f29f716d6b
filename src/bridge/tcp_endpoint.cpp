// The TCP endpoint: a listener and the connections it accepts. One client
// controls the device at a time; with `shared`, later ones (up to
// max_monitors) get read-only monitoring instead of a refusal. With RFC 2217
// each connection carries a Telnet session whose COM-PORT requests act on
// the device.
//
// What the server holds for a client is its outgoing queue, bounded by
// buffer_limit (byte_queue.hpp): device data and, under RFC 2217, the
// answers to its requests. Answers come only from reading the client, so a
// client whose queue is full is not read until it drains: a client that
// never reads holds at most its queue, whatever it sends.
#include <sys/socket.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <deque>
#include <iterator>
#include <optional>
#include <string>
#include <vector>

#include "bridge/com_port_adapter.hpp"
#include "bridge/endpoint.hpp"
#include "core/rfc2217.hpp"
#include "posix/listener.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail::bridge {

namespace {

// A refused connection is closed only once the client has closed its end
// (or after kRefusalLinger): closing a socket with unread input resets the
// connection, and a reset discards the refusal message before a client that
// spoke first (a driver, pyserial's Telnet negotiation) reads it. Its input
// is read and dropped meanwhile. At most kMaxRefusalsLingering linger; the
// oldest is closed to make room.
constexpr auto kRefusalLinger = std::chrono::seconds(2);
constexpr std::size_t kMaxRefusalsLingering = 16;

struct Refusal {
  Connection connection;
  Clock::time_point close_at;
  PollSet::Slot slot = PollSet::none;
};

struct Client {
  Client(Connection accepted, std::size_t queue_limit)
      : connection(std::move(accepted)), outgoing(queue_limit) {}
  // Reading this client could add answers to a queue that is full already.
  bool input_held_back() const { return telnet && outgoing.full(); }

  Connection connection;
  bool monitor = false;
  ByteQueue outgoing;
  std::unique_ptr<ComPortAdapter> com_port;
  std::unique_ptr<rfc2217::ServerSession> telnet;
  bool gone = false;
  // The device's modem inputs changed and this client has not been told.
  bool modem_state_due = false;
  // Device data has been queued for this (controlling) client: what it is
  // sent from then on carries some.
  bool holds_device_data = false;
  PollSet::Slot slot = PollSet::none;
};

class TcpEndpoint final : public ClientEndpoint {
 public:
  TcpEndpoint(const BridgeOptions& options, DeviceSide& device, Status& status)
      : options_(options),
        device_(device),
        status_(status),
        listener_(options.listen_host, options.listen_port, options.listen_backlog) {
    const std::string& address = listener_.address();
    status_.set(&Status::listen_address, address);
    const std::string& host = options_.listen_host;
    if (host == "127.0.0.1" || host == "::1" || host == "localhost") {
      status_.message("listening on " + address +
                      " (this machine only; give HOST:PORT, e.g. 0.0.0.0:" +
                      address.substr(address.rfind(':') + 1) +
                      ", to accept other machines)");
    } else {
      status_.message("listening on " + address);
    }
  }

  void add_to_poll(PollSet& poll_set) override {
    // While the device is away, new clients wait in the listen queue and
    // are served once it is back: accepting them now could only end in
    // closing them.
    listener_slot_ = PollSet::none;
    if (device_.is_open() && !listener_.resting(Clock::now())) {
      listener_slot_ = poll_set.add(listener_.fd(), true, false);
    }
    for (auto& client : clients_) {
      client->slot = poll_set.add(client->connection.fd(), wants_input(*client),
                                  !client->outgoing.empty());
    }
    for (auto& refusal : refusals_) {
      refusal.slot = poll_set.add(refusal.connection.fd(), true, false);
    }
  }

  Clock::time_point next_timer() const override {
    Clock::time_point next =
        listener_.resting(Clock::now()) ? listener_.resume_at() : Clock::time_point::max();
    if (!refusals_.empty()) next = std::min(next, refusals_.front().close_at);
    return next;
  }

  void run_timers(Clock::time_point now) override {
    while (!refusals_.empty() && refusals_.front().close_at <= now) refusals_.pop_front();
  }

  void handle_events(const PollSet& poll_set) override {
    drain_refusals(poll_set);
    // Clients accepted below were not polled this round.
    const std::size_t polled = clients_.size();
    for (std::size_t i = 0; i < polled; ++i) {
      Client& client = *clients_[i];
      if (client.gone) continue;
      const Readiness ready = poll_set.ready(client.slot);
      if (ready.readable || (ready.hung_up && wants_input(client))) {
        read_client(client);
      } else if (ready.hung_up) {
        // Not read now, so no read will tell the end: without this, poll()
        // would report the hang-up again at once, round after round.
        write_client(client);
        drop_client(client, "the connection hung up");
      }
      if (!client.gone && !client.outgoing.empty()) write_client(client);
      if (!client.gone) tell_modem_state(client);
    }
    clients_.erase(std::remove_if(clients_.begin(), clients_.end(),
                                  [](const std::unique_ptr<Client>& c) { return c->gone; }),
                   clients_.end());
    if (poll_set.ready(listener_slot_).readable) {
      accept_clients();
      report_listener_rest();
    }
  }

  bool wants_device_data() const override {
    const Client* control = controller();
    if (!control) return false;  // the device waits for a client
    if (control->telnet && control->telnet->suspended()) return false;
    return !control->outgoing.full();
  }

  // A client dropped as data is sent to it is recorded leaving, before the
  // next client is sent the data: one client at most, whose sending is the
  // last use of it.
  bool delivers_without_recording() const override { return clients_.size() <= 1; }

  void deliver_from_device(const char* data, std::size_t size) override {
    std::string escaped;
    for (auto& client : clients_) {
      if (client->gone) continue;
      const char* bytes = data;
      std::size_t length = size;
      if (client->telnet) {
        if (escaped.empty()) rfc2217::ServerSession::escape(data, size, escaped);
        bytes = escaped.data();
        length = escaped.size();
      }
      if (client->monitor && length > client->outgoing.room()) {
        status_.update_stats([size](BridgeStats& s) { s.bytes_dropped += size; });
        continue;
      }
      if (!client->monitor) client->holds_device_data = true;
      send_or_queue(*client, bytes, length);
    }
  }

  // Clients learn it by their connection closing.
  void device_lost() override {
    for (auto& client : clients_) {
      if (device_.lost_by_fault() && !client->gone) {
        // A device lost by an injected fault: the connection is reset, as
        // when a networked device reboots.
        const struct linger reset{1, 0};
        sys::setsockopt(client->connection.fd(), SOL_SOCKET, SO_LINGER, &reset, sizeof reset);
      }
      drop_client(*client, "closed: the device went away");
    }
  }

  bool has_clients() const override { return !clients_.empty(); }

  bool served_device_data() const override { return served_device_data_; }

  void modem_inputs_changed() override {
    for (auto& client : clients_) {
      if (client->gone || !client->telnet) continue;
      client->modem_state_due = true;
      tell_modem_state(*client);
    }
  }

  void shut_down() override {
    refusals_.clear();
    for (auto& client : clients_) {
      if (!client->gone) {
        write_client(*client);
        drop_client(*client, "closed: the bridge stopped");
      }
    }
    clients_.clear();
  }

 private:
  Client* controller() const {
    for (auto& client : clients_) {
      if (!client->monitor && !client->gone) return client.get();
    }
    return nullptr;
  }

  std::size_t monitor_count() const {
    return static_cast<std::size_t>(std::count_if(
        clients_.begin(), clients_.end(),
        [](const std::unique_ptr<Client>& c) { return c->monitor && !c->gone; }));
  }

  // Whether to read the client now: not while its answers could overflow
  // its queue, nor (the controller) while the device's queue is full.
  bool wants_input(const Client& client) const {
    if (client.input_held_back()) return false;
    return client.monitor || device_.room_for_client_data() > 0;
  }

  // Said once when the listener starts resting (out of descriptors), not
  // on every retry, and once when a connection is accepted after that.
  void report_listener_rest() {
    const int error = listener_.rest_error();
    if (error != 0 && !rest_reported_) {
      rest_reported_ = true;
      status_.message(system_error_message("cannot accept clients", error) +
                      "; new clients wait in the listen queue, tried again at most every " +
                      std::to_string(Listener::kLongestRest.count()) + " ms");
    }
  }

  void accept_clients() {
    // The device can go away during this round: the rest wait for it.
    while (device_.is_open()) {
      auto connection = listener_.accept();
      if (!connection) return;
      if (rest_reported_) {
        rest_reported_ = false;
        status_.message("accepting clients again");
      }
      const std::string peer = connection->peer();
      const auto refuse = [&](const std::string& why) {
        const std::string text = "wiretape: " + why + "\r\n";
        // A short text fits in a fresh socket's buffer: no need to wait.
        connection->send(text.data(), text.size());
        connection->shutdown_sending();
        if (refusals_.size() >= kMaxRefusalsLingering) refusals_.pop_front();
        refusals_.push_back({std::move(*connection), Clock::now() + kRefusalLinger});
        status_.update_stats([](BridgeStats& s) { ++s.clients_refused; });
        status_.message("refused client " + peer + ": " + why);
      };
      Client* control = controller();
      if (control && !options_.shared) {
        refuse("the device is in use by another client (" + control->connection.peer() +
               "); try again later, or start the server with --shared to let "
               "more clients watch");
        continue;
      }
      if (control && monitor_count() >= options_.max_monitors) {
        refuse(std::to_string(options_.max_monitors) +
               " monitors are connected already, the most this server takes "
               "(--max-monitors); try again later");
        continue;
      }
      auto client = std::make_unique<Client>(std::move(*connection), options_.buffer_limit);
      client->monitor = control != nullptr;
      if (!client->monitor && options_.restart && had_client_) device_.restart();
      if (options_.protocol == BridgeProtocol::rfc2217) {
        client->com_port = std::make_unique<ComPortAdapter>(device_, !client->monitor);
        client->telnet = std::make_unique<rfc2217::ServerSession>(*client->com_port);
        // Bytes the client sent before a setting reach the device before it.
        client->telnet->set_device_data_sink([this, monitor = client->monitor](std::string& data) {
          if (!monitor) device_.send(data.data(), data.size());
          data.clear();
        });
        client->outgoing.append(client->telnet->greeting());
      }
      if (!client->monitor) had_client_ = true;
      device_.client_connected(peer, client->monitor ? "monitor" : "control");
      status_.message("client " + peer + " connected" +
                      (client->monitor ? " (read-only monitor)" : ""));
      clients_.push_back(std::move(client));
      write_client(*clients_.back());
    }
  }

  void read_client(Client& client) {
    if (client.input_held_back()) return;
    std::array<char, kChunk> buffer;
    std::size_t want = buffer.size();
    if (!client.monitor) {
      want = std::min(want, device_.room_for_client_data());
      if (want == 0) return;
    }
    const Transfer got = client.connection.receive(buffer.data(), want);
    switch (got.status) {
      case Transfer::Status::closed: drop_client(client, "disconnected"); return;
      case Transfer::Status::would_block: return;
      case Transfer::Status::failed:
        drop_client(client, system_error_message("connection failed", got.error));
        return;
      case Transfer::Status::done: break;
    }
    std::string for_device;
    const char* data = buffer.data();
    std::size_t size = got.bytes;
    if (client.telnet) {
      // Earlier data reaches the device before a setting the client sent
      // after it.
      device_.flush();
      std::string answers;
      client.telnet->receive(buffer.data(), got.bytes, for_device, answers);
      client.outgoing.append(answers);
      data = for_device.data();
      size = for_device.size();
    }
    if (client.monitor) return;  // a monitor's input is ignored
    device_.send(data, size);
  }

  // Sent from the caller's buffer while nothing waits before it: only what
  // the connection does not take now is copied into the client's queue.
  void send_or_queue(Client& client, const char* bytes, std::size_t length) {
    if (!client.outgoing.empty()) {
      client.outgoing.append(bytes, length);
      write_client(client);
      return;
    }
    const Transfer sent = client.connection.send(bytes, length);
    std::size_t taken = 0;
    switch (sent.status) {
      case Transfer::Status::failed:
        drop_client(client, system_error_message("connection failed", sent.error));
        return;
      case Transfer::Status::done: taken = sent.bytes; break;
      case Transfer::Status::would_block:
      case Transfer::Status::closed: break;
    }
    if (taken > 0 && client.holds_device_data) served_device_data_ = true;
    if (taken == length) return;
    client.outgoing.append(bytes + taken, length - taken);
    if (taken > 0) write_client(client);  // as the queue's loop does, till it would block
  }

  void write_client(Client& client) {
    while (!client.gone && !client.outgoing.empty()) {
      const Transfer sent =
          client.connection.send(client.outgoing.data(), client.outgoing.size());
      if (sent.status == Transfer::Status::would_block) return;
      if (sent.status == Transfer::Status::failed) {
        drop_client(client, system_error_message("connection failed", sent.error));
        return;
      }
      client.outgoing.consume(sent.bytes);
      if (sent.bytes > 0 && client.holds_device_data) served_device_data_ = true;
    }
  }

  // Reads and drops what refused clients still send; closes the ones that
  // have closed their end (or failed) without a reset.
  void drain_refusals(const PollSet& poll_set) {
    std::array<char, 4096> discard;
    for (auto it = refusals_.begin(); it != refusals_.end();) {
      const Readiness ready = poll_set.ready(it->slot);
      bool done = false;
      if (ready.readable || ready.hung_up) {
        const Transfer got = it->connection.receive(discard.data(), discard.size());
        done = got.status == Transfer::Status::closed || got.status == Transfer::Status::failed;
      }
      it = done ? refusals_.erase(it) : std::next(it);
    }
  }

  // A client whose queue is full is told the modem state once it has room,
  // the state as it is then: changes coalesce instead of piling up behind
  // a client that does not read.
  void tell_modem_state(Client& client) {
    if (!client.modem_state_due || client.outgoing.full()) return;
    client.modem_state_due = false;
    client.outgoing.append(client.telnet->modem_state_notification());
    write_client(client);
  }

  void drop_client(Client& client, const std::string& reason) {
    if (client.gone) return;
    client.gone = true;
    client.connection.close();
    client.outgoing.clear();
    device_.client_disconnected(client.connection.peer(), reason);
    status_.message("client " + client.connection.peer() + " " + reason);
  }

  const BridgeOptions& options_;
  DeviceSide& device_;
  Status& status_;
  Listener listener_;
  std::vector<std::unique_ptr<Client>> clients_;
  // Oldest first: their close_at times are in order.
  std::deque<Refusal> refusals_;
  bool had_client_ = false;
  bool rest_reported_ = false;
  bool served_device_data_ = false;
  PollSet::Slot listener_slot_ = PollSet::none;
};

}  // namespace

std::unique_ptr<ClientEndpoint> make_tcp_endpoint(const BridgeOptions& options,
                                                  DeviceSide& device, Status& status) {
  return std::make_unique<TcpEndpoint>(options, device, status);
}

}  // namespace wiretape::detail::bridge
