// Fuzzes the .wtape reader: any bytes must either be refused at open with a
// SessionError, or read record by record until the end or a reported damage.
// Nobody writes the scratch file, so its end is never "still being written".
// verify's check of the index (chunks included) takes any file too.
#include <cstdint>
#include <cstdlib>
#include <string>

#include "fuzz_files.hpp"
#include "session/reader.hpp"
#include "session/session_index.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/session.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = wiretape::fuzz::scratch().write("input.wtape", data, size);
  try {
    wiretape::SessionReader reader(path);
    wiretape::Record record;
    std::size_t payload = 0;
    while (reader.next(record)) payload += record.data.size();
    // A record's payload never exceeds what the file holds; compressed
    // (2.0), what its chunks may decode to: 4 MiB each, a chunk record
    // taking at least its 20 bytes of framing.
    const std::size_t bound =
        reader.header().version_major >= 2 ? (size / 20 + 1) * (std::size_t{4} << 20) : size;
    if (payload > bound) std::abort();
    if (reader.damage() && reader.damage()->offset() >= size) std::abort();
    if (reader.unfinished()) std::abort();
    // Reading again gives the same.
    reader.rewind();
    std::size_t again = 0;
    while (reader.next(record)) again += record.data.size();
    if (again != payload) std::abort();
    // One channel of several, through the file's index when it holds one
    // (which passes over the other channels' records, and so over damage
    // in them): within what the file can hold, damage inside the file.
    if (reader.header().channels.size() > 1) {
      wiretape::SessionReader one(path, 1);
      std::size_t channel = 0;
      while (one.next(record)) channel += record.data.size();
      if (channel > bound) std::abort();
      if (one.damage() && one.damage()->offset() >= size) std::abort();
      // What verify says of the index: the index the records call for
      // (whole chunks for a compressed file) against the file's own.
      wiretape::SessionHeader header;
      wiretape::detail::IndexCheck check;
      auto source = wiretape::detail::open_session_source(
          path, header, wiretape::detail::Streams::refused, std::nullopt, {}, check.sink());
      while (source->next(record)) {
      }
      const auto status =
          check.status(path, header.channels.size(), source->damage().has_value());
      if (status.state == wiretape::detail::IndexState::current && source->damage()) std::abort();
    }
  } catch (const wiretape::SessionError& e) {
    if (e.offset() > size) std::abort();
  }
  return 0;
}
