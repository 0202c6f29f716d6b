// A program outside the wiretape tree, built against an installed wiretape.
#include <wiretape/wiretape.hpp>

#include <iostream>

int main() {
  auto port = wiretape::open_port("type=loopback,timeout=1");
  port->write_all("hello through wiretape\n");
  std::cout << port->read_line() << std::flush;
  return 0;
}
