// Translation between SerialSettings and termios, on termios structures
// alone: what the serial port programs and the pty port reads back must be
// the same settings. Programming a real terminal is tested through the ports
// (serial_port_test.cpp, pty_port_test.cpp).
#include <termios.h>

#include <gtest/gtest.h>

#include <optional>

#include "posix/termios_settings.hpp"
#include "wiretape/port.hpp"

namespace wiretape::detail {
namespace {

termios raw_termios() {
  termios settings{};
  make_raw(settings);
  return settings;
}

TEST(TermiosSettings, StandardRatesMapToTheirConstantsAndBack) {
  EXPECT_EQ(standard_speed(9600), std::optional<speed_t>(B9600));
  EXPECT_EQ(standard_speed(115200), std::optional<speed_t>(B115200));
  EXPECT_EQ(standard_speed(12345), std::nullopt);
  EXPECT_EQ(baud_of_speed(B9600), 9600u);
  EXPECT_EQ(baud_of_speed(B115200), 115200u);
  for (const unsigned baud : {50u, 300u, 19200u, 57600u, 230400u}) {
    const auto speed = standard_speed(baud);
    ASSERT_TRUE(speed) << baud;
    EXPECT_EQ(baud_of_speed(*speed), baud);
  }
}

TEST(TermiosSettings, RawModeIsEightBitsWithoutEchoEditingOrTranslation) {
  termios settings{};
  settings.c_lflag = ECHO | ICANON | ISIG;
  settings.c_iflag = ICRNL | IXON;
  settings.c_oflag = OPOST;
  settings.c_cflag = CS7 | PARENB;
  make_raw(settings);
  EXPECT_EQ(settings.c_lflag & (ECHO | ICANON | ISIG), 0u);
  EXPECT_EQ(settings.c_iflag & (ICRNL | IXON), 0u);
  EXPECT_EQ(settings.c_oflag & OPOST, 0u);
  EXPECT_EQ(settings.c_cflag & CSIZE, static_cast<tcflag_t>(CS8));
  EXPECT_EQ(settings.c_cflag & PARENB, 0u);
  EXPECT_EQ(settings.c_cc[VMIN], 1);
  EXPECT_EQ(settings.c_cc[VTIME], 0);
}

TEST(TermiosSettings, EveryLineSettingReadsBackAsWritten) {
  for (const int data_bits : {5, 6, 7, 8}) {
    for (const int stop_bits : {1, 2}) {
      for (const Parity parity : {Parity::none, Parity::even, Parity::odd, Parity::mark,
                                  Parity::space}) {
        for (const FlowControl flow :
             {FlowControl::none, FlowControl::rtscts, FlowControl::xonxoff}) {
          SerialSettings wanted;
          wanted.baud = 19200;
          wanted.data_bits = data_bits;
          wanted.stop_bits = stop_bits;
          wanted.parity = parity;
          wanted.flow = flow;
          termios settings = raw_termios();
          apply_line_settings(settings, wanted, "test");
          EXPECT_EQ(line_settings_of(settings, 19200), wanted) << frame_name(wanted);
        }
      }
    }
  }
}

TEST(TermiosSettings, ApplyingSettingsReplacesThePreviousOnes) {
  SerialSettings first;
  first.data_bits = 7;
  first.stop_bits = 2;
  first.parity = Parity::odd;
  first.flow = FlowControl::xonxoff;
  termios settings = raw_termios();
  apply_line_settings(settings, first, "test");
  const SerialSettings plain;  // 8N1, no flow control
  apply_line_settings(settings, plain, "test");
  EXPECT_EQ(line_settings_of(settings, plain.baud), plain);
  EXPECT_EQ(settings.c_iflag & (IXON | IXOFF), 0u);
}

TEST(TermiosSettings, FrameNamesSayBitsParityStopsAndFlow) {
  SerialSettings settings;
  EXPECT_EQ(frame_name(settings), "8N1");
  settings.data_bits = 7;
  settings.parity = Parity::even;
  settings.stop_bits = 2;
  EXPECT_EQ(frame_name(settings), "7E2");
  settings.parity = Parity::space;
  settings.flow = FlowControl::rtscts;
  EXPECT_EQ(frame_name(settings), "7S2 rtscts");
  settings.parity = Parity::mark;
  settings.flow = FlowControl::xonxoff;
  EXPECT_EQ(frame_name(settings), "7M2 xonxoff");
  settings.parity = Parity::odd;
  settings.flow = FlowControl::none;
  EXPECT_EQ(frame_name(settings), "7O2");
}

}  // namespace
}  // namespace wiretape::detail
