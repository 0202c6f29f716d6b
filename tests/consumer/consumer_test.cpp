// A driver test of a project outside the wiretape tree, built against an
// installed wiretape (find_package(wiretape COMPONENTS testing)): it records
// its cassette from the device once and replays it after.
#include <wiretape/testing.hpp>

class EchoTest : public wiretape::testing::CassetteTest {};

TEST_F(EchoTest, AnswersPing) {
  wiretape::Port& device = port();
  device.write_all("PING\n");
  EXPECT_EQ(device.read_line(), "PING\n");
}
