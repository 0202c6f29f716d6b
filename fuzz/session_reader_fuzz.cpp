// Fuzzes the .wtape reader: any bytes must either be refused at open with a
// SessionError, or read record by record until the end or a reported damage.
#include <cstdint>
#include <cstdlib>
#include <string>

#include "fuzz_files.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/session.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = wiretape::fuzz::scratch().write("input.wtape", data, size);
  try {
    wiretape::SessionReader reader(path);
    wiretape::Record record;
    std::size_t payload = 0;
    while (reader.next(record)) payload += record.data.size();
    // A record's payload never exceeds what the file holds.
    if (payload > size) std::abort();
    if (reader.damage() && reader.damage()->offset() >= size) std::abort();
    // Reading again gives the same.
    reader.rewind();
    std::size_t again = 0;
    while (reader.next(record)) again += record.data.size();
    if (again != payload) std::abort();
  } catch (const wiretape::SessionError& e) {
    if (e.offset() > size) std::abort();
  }
  return 0;
}
