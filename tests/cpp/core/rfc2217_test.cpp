// The RFC 2217 sessions byte for byte, the server's and the client's: option
// commands and their answers, IAC escaping, and hostile input.
#include <gtest/gtest.h>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/rfc2217.hpp"

namespace {

using wiretape::FlowControl;
using wiretape::Parity;
using wiretape::detail::rfc2217::ComPort;
using wiretape::detail::rfc2217::LineState;
using wiretape::detail::rfc2217::ModemLines;
using wiretape::detail::rfc2217::StopBits;
using wiretape::detail::rfc2217::ServerSession;

std::string bytes(std::initializer_list<int> values) {
  std::string out;
  for (int v : values) out.push_back(static_cast<char>(v));
  return out;
}

class RecordingComPort final : public ComPort {
 public:
  std::uint32_t set_baud(std::optional<std::uint32_t> baud) override {
    calls.push_back("baud " + (baud ? std::to_string(*baud) : std::string("?")));
    if (baud) this->baud = *baud;
    return this->baud;
  }
  int set_data_bits(std::optional<int> bits) override {
    calls.push_back("datasize " + (bits ? std::to_string(*bits) : std::string("?")));
    return bits.value_or(8);
  }
  Parity set_parity(std::optional<Parity> parity) override {
    calls.push_back(std::string("parity ") + (parity ? to_string(*parity) : "?"));
    return parity.value_or(Parity::none);
  }
  StopBits set_stop_bits(std::optional<StopBits> stop_bits) override {
    calls.push_back(std::string("stopsize ") +
                    (stop_bits == StopBits::one_and_a_half ? "1.5"
                     : stop_bits == StopBits::two          ? "2"
                     : stop_bits == StopBits::one          ? "1"
                                                           : "?"));
    return stop_bits == StopBits::two ? StopBits::two : StopBits::one;  // 1.5 refused
  }
  FlowControl set_flow_control(std::optional<FlowControl> flow) override {
    calls.push_back(std::string("flow ") + (flow ? to_string(*flow) : "?"));
    return flow.value_or(FlowControl::none);
  }
  bool set_break(std::optional<bool> on) override { return level("break", on); }
  bool set_dtr(std::optional<bool> on) override { return level("dtr", on); }
  bool set_rts(std::optional<bool> on) override { return level("rts", on); }
  void purge(bool from_device, bool for_device) override {
    calls.push_back(std::string("purge") + (from_device ? " from_device" : "") +
                    (for_device ? " for_device" : ""));
  }
  ModemLines modem_lines() override {
    ModemLines lines;
    lines.cts = lines.dsr = true;  // 0x30
    return lines;
  }
  LineState line_state() override {
    LineState state;
    state.shift_register_empty = state.holding_register_empty = true;  // 0x60
    return state;
  }

  std::uint32_t baud = 9600;
  std::vector<std::string> calls;

 private:
  bool level(const char* line, std::optional<bool> on) {
    calls.push_back(std::string(line) + (on ? (*on ? " on" : " off") : " ?"));
    return on.value_or(true);
  }
};

struct Fed {
  std::string to_device;
  std::string to_client;
};

Fed feed(ServerSession& session, const std::string& input) {
  Fed fed;
  session.receive(input.data(), input.size(), fed.to_device, fed.to_client);
  return fed;
}

// IAC WILL/DO COM-PORT-OPTION as pyserial sends them on open.
const std::string kClientOpen = bytes({255, 253, 44, 255, 251, 44});

TEST(Rfc2217, GreetingOffersBinaryOnly) {
  RecordingComPort port;
  ServerSession session(port);
  EXPECT_EQ(session.greeting(), bytes({255, 251, 0, 255, 253, 0}));
  // Offers already made are not made again.
  EXPECT_EQ(session.greeting(), "");
}

TEST(Rfc2217, AgreesToComPortAndAnnouncesTheModemState) {
  RecordingComPort port;
  ServerSession session(port);
  const Fed fed = feed(session, kClientOpen);
  EXPECT_TRUE(session.com_port_active());
  EXPECT_EQ(fed.to_client, bytes({255, 251, 44,                  // WILL COM-PORT
                                  255, 250, 44, 107, 0x30, 255, 240,  // modem state
                                  255, 253, 44}));               // DO COM-PORT
  EXPECT_EQ(fed.to_device, "");
}

TEST(Rfc2217, RefusesUnknownOptionsAndEcho) {
  RecordingComPort port;
  ServerSession session(port);
  const Fed fed = feed(session, bytes({255, 253, 1, 255, 251, 99}));
  EXPECT_EQ(fed.to_client, bytes({255, 252, 1, 255, 254, 99}));
  EXPECT_FALSE(session.com_port_active());
}

TEST(Rfc2217, AnswersAnOfferOnlyOnce) {
  RecordingComPort port;
  ServerSession session(port);
  session.greeting();
  // The client accepts our BINARY offers: nothing more to say.
  EXPECT_EQ(feed(session, bytes({255, 253, 0, 255, 251, 0})).to_client, "");
  // Repeating an agreed option is not answered (no negotiation loops).
  EXPECT_EQ(feed(session, bytes({255, 253, 0})).to_client, "");
}

TEST(Rfc2217, SetBaudrateIsAppliedAndAnsweredWithTheRateInEffect) {
  RecordingComPort port;
  ServerSession session(port);
  feed(session, kClientOpen);
  // 115200 = 0x0001c200
  const Fed fed = feed(session, bytes({255, 250, 44, 1, 0x00, 0x01, 0xc2, 0x00, 255, 240}));
  EXPECT_EQ(port.calls.back(), "baud 115200");
  EXPECT_EQ(fed.to_client, bytes({255, 250, 44, 101, 0x00, 0x01, 0xc2, 0x00, 255, 240}));
}

TEST(Rfc2217, BaudrateValueWithIacIsUnescaped) {
  RecordingComPort port;
  ServerSession session(port);
  feed(session, kClientOpen);
  // 0x0000ff00 = 65280: the 0xff is doubled on the wire both ways.
  const Fed fed =
      feed(session, bytes({255, 250, 44, 1, 0x00, 0x00, 255, 255, 0x00, 255, 240}));
  EXPECT_EQ(port.calls.back(), "baud 65280");
  EXPECT_EQ(fed.to_client,
            bytes({255, 250, 44, 101, 0x00, 0x00, 255, 255, 0x00, 255, 240}));
}

TEST(Rfc2217, LineSettingsControlAndPurge) {
  RecordingComPort port;
  ServerSession session(port);
  feed(session, kClientOpen);
  const Fed fed = feed(session, bytes({255, 250, 44, 2, 7, 255, 240,     // 7 data bits
                                       255, 250, 44, 3, 3, 255, 240,     // even parity
                                       255, 250, 44, 4, 3, 255, 240,     // 1.5 stop bits
                                       255, 250, 44, 5, 9, 255, 240,     // DTR off
                                       255, 250, 44, 12, 1, 255, 240,    // purge rx
                                       255, 250, 44, 12, 9, 255, 240})); // bad purge
  EXPECT_EQ(port.calls, (std::vector<std::string>{"datasize 7", "parity even", "stopsize 1.5",
                                                  "dtr off", "purge from_device"}));
  EXPECT_EQ(fed.to_client, bytes({255, 250, 44, 102, 7, 255, 240,
                                  255, 250, 44, 103, 3, 255, 240,
                                  255, 250, 44, 104, 1, 255, 240,  // refused: still 1
                                  255, 250, 44, 105, 9, 255, 240,
                                  255, 250, 44, 112, 1, 255, 240,
                                  255, 250, 44, 112, 9, 255, 240}));
}

TEST(Rfc2217, StateRequestsAndMasks) {
  RecordingComPort port;
  ServerSession session(port);
  feed(session, kClientOpen);
  const Fed fed = feed(session, bytes({255, 250, 44, 11, 0x10, 255, 240,  // modem mask: CTS
                                       255, 250, 44, 7, 255, 240,         // modem state?
                                       255, 250, 44, 6, 255, 240}));      // line state?
  EXPECT_EQ(fed.to_client, bytes({255, 250, 44, 111, 0x10, 255, 240,
                                  255, 250, 44, 107, 0x30, 255, 240,
                                  255, 250, 44, 106, 0x60, 255, 240}));
  // The mask filters what the server sends unasked.
  EXPECT_EQ(session.modem_state_notification(), bytes({255, 250, 44, 107, 0x10, 255, 240}));
}

TEST(Rfc2217, FlowControlSuspendAndResume) {
  RecordingComPort port;
  ServerSession session(port);
  feed(session, bytes({255, 250, 44, 8, 255, 240}));
  EXPECT_TRUE(session.suspended());
  feed(session, bytes({255, 250, 44, 9, 255, 240}));
  EXPECT_FALSE(session.suspended());
}

TEST(Rfc2217, DataPassesWithIacUnescapedAcrossReads) {
  RecordingComPort port;
  ServerSession session(port);
  std::string to_device;
  std::string to_client;
  const std::string first = bytes({'a', 255});
  const std::string second = bytes({255, 'b', 255});
  const std::string third = bytes({251, 0, 'c'});
  session.receive(first.data(), first.size(), to_device, to_client);
  session.receive(second.data(), second.size(), to_device, to_client);
  session.receive(third.data(), third.size(), to_device, to_client);
  EXPECT_EQ(to_device, bytes({'a', 255, 'b', 'c'}));
}

TEST(Rfc2217, EscapeDoublesIac) {
  std::string out;
  const std::string data = bytes({1, 255, 2, 255, 255});
  ServerSession::escape(data.data(), data.size(), out);
  EXPECT_EQ(out, bytes({1, 255, 255, 2, 255, 255, 255, 255}));
}

TEST(Rfc2217, OverlongSubnegotiationIsDroppedWhole) {
  RecordingComPort port;
  ServerSession session(port);
  feed(session, kClientOpen);
  std::string input = bytes({255, 250, 44, 1, 0, 0, 0x25, 0x80});
  input += std::string(1000, 'x');
  input += bytes({255, 240});
  input += "after";
  const Fed fed = feed(session, input);
  EXPECT_TRUE(port.calls.empty());
  EXPECT_EQ(fed.to_client, "");
  EXPECT_EQ(fed.to_device, "after");
}

TEST(Rfc2217, CommandInsideSubnegotiationAbandonsIt) {
  RecordingComPort port;
  ServerSession session(port);
  feed(session, kClientOpen);
  // SB COM-PORT SET-BAUDRATE, then IAC DO ECHO before any SE.
  const Fed fed = feed(session, bytes({255, 250, 44, 1, 0, 255, 253, 1, 'z'}));
  EXPECT_TRUE(port.calls.empty());
  EXPECT_EQ(fed.to_client, bytes({255, 252, 1}));
  EXPECT_EQ(fed.to_device, "z");
}

TEST(Rfc2217, MalformedCommandsAreIgnored) {
  RecordingComPort port;
  ServerSession session(port);
  feed(session, kClientOpen);
  const Fed fed = feed(session, bytes({255, 250, 255, 240,            // empty SB
                                       255, 250, 44, 1, 1, 255, 240,  // short baud
                                       255, 250, 44, 2, 255, 240,     // no value
                                       255, 250, 44, 200, 1, 255, 240,  // unknown
                                       255, 250, 24, 0, 255, 240,     // other option
                                       255, 240, 255, 241}));         // stray SE, NOP
  EXPECT_TRUE(port.calls.empty());
  EXPECT_EQ(fed.to_client, "");
  EXPECT_EQ(fed.to_device, "");
}

TEST(Rfc2217, DataBeforeACommandGoesToTheSinkBeforeTheCommandIsApplied) {
  RecordingComPort port;
  ServerSession session(port);
  session.set_device_data_sink([&](std::string& data) {
    port.calls.push_back("data " + data);
    data.clear();
  });
  feed(session, kClientOpen);
  // HELLO, DTR low, SYNC, DTR high, PING in one read, as a client that
  // pulses DTR between its writes may send them.
  const Fed fed = feed(session, "HELLO" + bytes({255, 250, 44, 5, 9, 255, 240}) + "SYNC" +
                                    bytes({255, 250, 44, 5, 8, 255, 240}) + "PING");
  EXPECT_EQ(port.calls, (std::vector<std::string>{"data HELLO", "dtr off", "data SYNC",
                                                  "dtr on"}));
  EXPECT_EQ(fed.to_device, "PING");
}

// --- the client side ---------------------------------------------------------

using wiretape::detail::rfc2217::Answer;
using wiretape::detail::rfc2217::ClientSession;

// Runs a client and a server session against each other until neither has
// anything left to say; returns the device data each side received.
struct Pair {
  RecordingComPort port;
  ServerSession server{port};
  ClientSession client;
  std::string client_data;
  std::string device_data;

  void exchange(std::string to_server, std::string to_client = "") {
    for (int round = 0; round < 16 && (!to_server.empty() || !to_client.empty()); ++round) {
      std::string answers_to_client;
      server.receive(to_server.data(), to_server.size(), device_data, answers_to_client);
      std::string answers_to_server;
      const std::string incoming = to_client + answers_to_client;
      client.receive(incoming.data(), incoming.size(), client_data, answers_to_server);
      to_server = answers_to_server;
      to_client.clear();
    }
  }
};

TEST(Rfc2217Client, GreetingAsksBinaryAndSgaBothWaysAndOffersComPort) {
  ClientSession client;
  EXPECT_EQ(client.greeting(), bytes({255, 251, 0, 255, 253, 0, 255, 251, 3, 255, 253, 3,
                                      255, 251, 44}));
  EXPECT_EQ(client.greeting(), "");  // offers are made once
}

TEST(Rfc2217Client, AgreesWithWiretapesServer) {
  Pair pair;
  const std::string greeting = pair.server.greeting();
  pair.exchange(pair.client.greeting(), greeting);
  EXPECT_TRUE(pair.client.com_port_agreed());
  EXPECT_TRUE(pair.client.binary_settled());
  EXPECT_FALSE(pair.client.binary_refused());
  EXPECT_TRUE(pair.server.com_port_active());
  // The server's announcement of the modem lines reached the client.
  ASSERT_TRUE(pair.client.state().modem_lines);
  EXPECT_TRUE(pair.client.state().modem_lines->cts);
  EXPECT_TRUE(pair.client.state().modem_lines->dsr);
  EXPECT_FALSE(pair.client.state().modem_lines->cd);
  EXPECT_EQ(pair.client_data, "");
  EXPECT_EQ(pair.device_data, "");
}

TEST(Rfc2217Client, RequestsAreAnsweredAndCounted) {
  Pair pair;
  pair.exchange(pair.client.greeting(), pair.server.greeting());
  pair.exchange(ClientSession::set_baud(0x0001ffff) + ClientSession::set_data_bits(7) +
                ClientSession::set_parity(Parity::odd) +
                ClientSession::set_stop_bits(StopBits::two) +
                ClientSession::set_flow_control(FlowControl::rtscts) +
                ClientSession::set_dtr(false) + ClientSession::set_rts(true) +
                ClientSession::set_break(true) + ClientSession::purge(true, true));
  EXPECT_EQ(pair.port.calls,
            (std::vector<std::string>{"baud 131071", "datasize 7", "parity odd", "stopsize 2",
                                      "flow rtscts", "dtr off", "rts on", "break on",
                                      "purge from_device for_device"}));
  const auto& state = pair.client.state();
  EXPECT_EQ(state.baud, 131071u);
  EXPECT_EQ(state.data_bits, 7);
  EXPECT_EQ(state.parity, Parity::odd);
  EXPECT_EQ(state.stop_bits, StopBits::two);
  EXPECT_EQ(state.flow, FlowControl::rtscts);
  EXPECT_EQ(state.dtr, false);
  EXPECT_EQ(state.rts, true);
  EXPECT_EQ(state.break_on, true);
  EXPECT_EQ(pair.client.answers(Answer::baud), 1u);
  EXPECT_EQ(pair.client.answers(Answer::control), 4u);
  EXPECT_EQ(pair.client.answers(Answer::purge), 1u);
}

TEST(Rfc2217Client, ABaudRateWithIacIsEscapedInTheRequest) {
  // 0x0000ff00: the byte 255 doubled inside the subnegotiation.
  EXPECT_EQ(ClientSession::set_baud(0xff00),
            bytes({255, 250, 44, 1, 0, 0, 255, 255, 0, 255, 240}));
  Pair pair;
  pair.exchange(pair.client.greeting(), pair.server.greeting());
  pair.exchange(ClientSession::set_baud(0xff00));
  EXPECT_EQ(pair.client.state().baud, 0xff00u);
}

TEST(Rfc2217Client, DeviceDataIsUnescapedAndNotificationsAreTaken) {
  ClientSession client;
  client.greeting();
  std::string data;
  std::string answers;
  // IAC IAC, a modem-state notification (CD, RI) and a line-state one
  // (break detected) between data bytes.
  const std::string input = bytes({'a', 255, 255, 'b', 255, 250, 44, 107, 0xc0, 255, 240, 'c',
                                   255, 250, 44, 106, 0x10, 255, 240});
  client.receive(input.data(), 3, data, answers);
  client.receive(input.data() + 3, input.size() - 3, data, answers);
  EXPECT_EQ(data, bytes({'a', 255, 'b', 'c'}));
  ASSERT_TRUE(client.state().modem_lines);
  EXPECT_TRUE(client.state().modem_lines->cd);
  EXPECT_TRUE(client.state().modem_lines->ri);
  EXPECT_FALSE(client.state().modem_lines->cts);
  ASSERT_TRUE(client.state().line_state);
  EXPECT_TRUE(client.state().line_state->break_detected);
  EXPECT_EQ(answers, "");
}

TEST(Rfc2217Client, ARefusalIsSeenAndOtherOptionsAreRefused) {
  ClientSession client;
  client.greeting();
  std::string data;
  std::string answers;
  const std::string input = bytes({255, 254, 44, 255, 251, 1, 255, 253, 24});
  client.receive(input.data(), input.size(), data, answers);
  EXPECT_TRUE(client.com_port_refused());
  EXPECT_TRUE(client.heard_telnet());
  // WILL ECHO is refused (a server echoing our data would corrupt it), DO
  // TERMINAL-TYPE too.
  EXPECT_EQ(answers, bytes({255, 254, 1, 255, 252, 24}));
}

TEST(Rfc2217Client, MalformedAnswersAreIgnored) {
  ClientSession client;
  std::string data;
  std::string answers;
  const std::string input = bytes({255, 250, 44, 101, 1, 2, 255, 240,  // short baud answer
                                   255, 250, 44, 102, 255, 240,        // no value
                                   255, 250, 44, 1, 0, 0, 0, 1, 255, 240,  // a client's code
                                   255, 250, 44, 250, 1, 255, 240});  // unknown
  client.receive(input.data(), input.size(), data, answers);
  EXPECT_EQ(client.answers(Answer::baud), 0u);
  EXPECT_EQ(client.answers(Answer::data_size), 0u);
  EXPECT_FALSE(client.state().baud);
  EXPECT_EQ(data, "");
}

}  // namespace
