// The README's C++ example, built outside the wiretape tree against an
// installed wiretape (find_package). Keep the two identical.
#include <wiretape/wiretape.hpp>

#include <iostream>

int main() {
  {  // Record: any port with log=FILE writes a session file.
    auto device = wiretape::open_port("type=loopback,timeout=1,log=hello.wtape");
    device->write_all("PING\n");
    std::cout << "live:   " << device->read_line();
  }
  // Replay: the recording plays the device.
  auto device = wiretape::open_port("type=replay,file=hello.wtape,timing=none");
  device->write_all("PING\n");
  std::cout << "replay: " << device->read_line();
}
