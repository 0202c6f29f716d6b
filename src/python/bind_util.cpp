// Byte rendering shared with the Python tools, so that a mismatch report, a
// diff and `wiretape show` print bytes the same way (src/util/hex.hpp); and
// the parent-death signal a child of wiretape.children sets between fork and
// exec (prctl: through ctypes, its import was 2 ms of every `-- CMD`).
#include <cerrno>
#include <string>
#include <string_view>

#ifdef __linux__
#include <sys/prctl.h>
#endif

#include "python/bindings.hpp"
#include "python/text_caster.hpp"
#include "util/hex.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace wiretape::python {

namespace {

std::string_view view_of(nb::bytes data) {
  return {data.c_str(), data.size()};
}

}  // namespace

void bind_util(nb::module_& m) {
  m.def(
      "hex_ascii",
      [](nb::bytes data) { return detail::hex_ascii(view_of(data)); },
      "data"_a,
      "The bytes as hex, then as ASCII with '.' for what is not printable: "
      "'56 56 0a  |VV.|'; '(none)' for no bytes.");
  m.def(
      "escape_bytes",
      [](nb::bytes data, long long limit) {
        if (limit < 0) {
          throw nb::value_error(
              ("escape_bytes: limit must be 0 or more, not " +
               std::to_string(limit))
                  .c_str());
        }
        return detail::escape_bytes(view_of(data),
                                    static_cast<std::size_t>(limit));
      },
      "data"_a, "limit"_a = 64,
      "The bytes as one line of terminal-safe text: printable ASCII kept, a "
      "backslash doubled, \\n \\r \\t and \\xNN for every other byte (ESC "
      "included); beyond `limit` bytes, '... (+N bytes)'.");
  // Called in the child between fork and exec: no allocation, no exception
  // on failure (the result says it), so it is safe there.
  m.def(
      "set_parent_death_signal",
      [](int signum) -> int {
#ifdef __linux__
        return prctl(PR_SET_PDEATHSIG, static_cast<unsigned long>(signum), 0UL, 0UL, 0UL) == 0
                   ? 0
                   : errno;
#else
        (void)signum;
        return ENOSYS;
#endif
      },
      "signum"_a,
      "prctl(PR_SET_PDEATHSIG, signum): this process gets `signum` when the thread "
      "that forked it ends (Linux). 0, or the errno of the failure (ENOSYS elsewhere).");
}

}  // namespace wiretape::python
