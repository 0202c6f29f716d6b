// Fuzzes the flexiport log importer and exporter. The input is split in two:
// the first byte's low 7 bits give the split point as a fraction of the rest,
// the first part becomes name.logr, the second name.logw.
#include <cstdint>
#include <cstdlib>
#include <string>

#include "fuzz_files.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/session.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::size_t rest = size - 1;
  const std::size_t split = rest * (data[0] & 0x7F) / 0x7F;
  auto& scratch = wiretape::fuzz::scratch();
  scratch.write("in.logr", data + 1, split);
  scratch.write("in.logw", data + 1 + split, rest - split);
  const std::string prefix = scratch.file("in.log");
  try {
    wiretape::SessionReader reader(prefix);
    wiretape::Record record;
    std::size_t payload = 0;
    std::uint64_t last_write = 0;
    std::uint64_t last_read = 0;
    while (reader.next(record)) {
      payload += record.data.size();
      auto& last = record.kind == wiretape::RecordKind::tx ? last_write : last_read;
      last = record.t_ns;
    }
    if (payload > rest) std::abort();
    // What was read exports, and reads back the same.
    if (!reader.damage()) {
      const std::string out = scratch.file("out.log");
      scratch.file("out.logr");
      scratch.file("out.logw");
      wiretape::export_flexiport(prefix, out);
      wiretape::SessionReader exported(out);
      std::size_t exported_payload = 0;
      while (exported.next(record)) exported_payload += record.data.size();
      if (exported_payload != payload || exported.damage()) std::abort();
    }
  } catch (const wiretape::SessionError&) {
  }
  return 0;
}
