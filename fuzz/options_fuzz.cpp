// Fuzzes the option-string parser: any text either parses or raises an
// OptionError; what parses survives a round trip through to_string(); the
// typed accessors reject bad values with OptionError only.
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  wiretape::Options options;
  try {
    options = wiretape::Options::parse(text);
  } catch (const wiretape::OptionError&) {
    return 0;
  }
  const wiretape::Options again = wiretape::Options::parse(options.to_string());
  if (again.entries().size() != options.entries().size()) std::abort();
  for (std::size_t i = 0; i < options.entries().size(); ++i) {
    if (again.entries()[i].key != options.entries()[i].key ||
        again.entries()[i].value != options.entries()[i].value) {
      std::abort();
    }
  }
  auto attempt = [](auto&& take) {
    try {
      take();
    } catch (const wiretape::OptionError&) {
    }
  };
  attempt([&] { options.take_timeout("timeout", wiretape::forever); });
  attempt([&] { options.take_int("baud", 9600, 1, 4'000'000); });
  attempt([&] { options.take_bool("fsync", false); });
  attempt([&] { options.take_double("speed", 1.0, 0.001, 1000.0); });
  attempt([&] { options.take_choice("parity", "none", {"none", "even", "odd"}); });
  attempt([&] { options.take_prefixed("meta_"); });
  attempt([&] { options.finish("serial"); });
  return 0;
}
