// The TCP endpoint: a listener and the connections it accepts. One client
// controls the device at a time; with `shared`, later ones get read-only
// monitoring instead of a refusal. With RFC 2217 each connection carries a
// Telnet session whose COM-PORT requests act on the device.
#include <algorithm>
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "bridge/com_port_adapter.hpp"
#include "bridge/endpoint.hpp"
#include "bridge/rfc2217.hpp"
#include "posix/listener.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail::bridge {

namespace {

struct Client {
  explicit Client(Connection accepted) : connection(std::move(accepted)) {}
  Connection connection;
  bool monitor = false;
  ByteQueue outgoing;
  std::unique_ptr<ComPortAdapter> com_port;
  std::unique_ptr<rfc2217::ServerSession> telnet;
  bool gone = false;
  PollSet::Slot slot = PollSet::none;
};

class TcpEndpoint final : public ClientEndpoint {
 public:
  TcpEndpoint(const BridgeOptions& options, DeviceSide& device, Status& status)
      : options_(options),
        device_(device),
        status_(status),
        listener_(options.listen_host, options.listen_port) {
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
    listener_slot_ = poll_set.add(listener_.fd(), true, false);
    const bool device_has_room = device_.room_for_client_data() > 0;
    for (auto& client : clients_) {
      client->slot = poll_set.add(client->connection.fd(), client->monitor || device_has_room,
                                  !client->outgoing.empty());
    }
  }

  void handle_events(const PollSet& poll_set) override {
    // Clients accepted below were not polled this round.
    const std::size_t polled = clients_.size();
    for (std::size_t i = 0; i < polled; ++i) {
      Client& client = *clients_[i];
      if (client.gone) continue;
      const Readiness ready = poll_set.ready(client.slot);
      if (ready.readable || ready.hung_up) read_client(client);
      if (!client.gone && !client.outgoing.empty()) write_client(client);
    }
    clients_.erase(std::remove_if(clients_.begin(), clients_.end(),
                                  [](const std::unique_ptr<Client>& c) { return c->gone; }),
                   clients_.end());
    if (poll_set.ready(listener_slot_).readable) accept_clients();
  }

  bool wants_device_data() const override {
    const Client* control = controller();
    if (!control) return false;  // the device waits for a client
    if (control->telnet && control->telnet->suspended()) return false;
    return control->outgoing.size() < options_.buffer_limit;
  }

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
      if (client->monitor && client->outgoing.size() + length > options_.buffer_limit) {
        status_.update_stats([size](BridgeStats& s) { s.bytes_dropped += size; });
        continue;
      }
      client->outgoing.append(bytes, length);
      write_client(*client);
    }
  }

  // Clients learn it by their connection closing.
  void device_lost() override {
    for (auto& client : clients_) drop_client(*client, "closed: the device went away");
  }

  bool has_clients() const override { return !clients_.empty(); }

  void modem_inputs_changed() override {
    for (auto& client : clients_) {
      if (client->gone || !client->telnet) continue;
      client->outgoing.append(client->telnet->modem_state_notification());
      write_client(*client);
    }
  }

  void shut_down() override {
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

  void accept_clients() {
    while (auto connection = listener_.accept()) {
      const std::string peer = connection->peer();
      const auto refuse = [&](const std::string& why) {
        const std::string text = "wiretape: " + why + "\r\n";
        // A short text fits in a fresh socket's buffer: no need to wait.
        connection->send(text.data(), text.size());
        status_.update_stats([](BridgeStats& s) { ++s.clients_refused; });
        status_.message("refused client " + peer + ": " + why);
      };
      if (!device_.is_open()) {
        refuse("the device (" + device_.description() + ") is unavailable" +
               (options_.reopen ? "; waiting for it to come back, try again later" : ""));
        continue;
      }
      Client* control = controller();
      if (control && !options_.shared) {
        refuse("the device is in use by another client (" + control->connection.peer() +
               "); try again later, or start the server with --shared to let "
               "more clients watch");
        continue;
      }
      auto client = std::make_unique<Client>(std::move(*connection));
      client->monitor = control != nullptr;
      if (!client->monitor && options_.restart && had_client_) device_.restart();
      if (options_.protocol == BridgeProtocol::rfc2217) {
        client->com_port = std::make_unique<ComPortAdapter>(device_, !client->monitor);
        client->telnet = std::make_unique<rfc2217::ServerSession>(*client->com_port);
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
    }
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
  bool had_client_ = false;
  PollSet::Slot listener_slot_ = PollSet::none;
};

}  // namespace

std::unique_ptr<ClientEndpoint> make_tcp_endpoint(const BridgeOptions& options,
                                                  DeviceSide& device, Status& status) {
  return std::make_unique<TcpEndpoint>(options, device, status);
}

}  // namespace wiretape::detail::bridge
