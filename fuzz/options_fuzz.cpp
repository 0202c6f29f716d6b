// Fuzzes the option-string parser: any text either parses or raises an
// OptionError; what parses survives a round trip through to_string(); every
// row of the key table, read by its typed accessor for each of its port
// types, rejects bad values with OptionError only; finish() and the "did
// you mean" suggestion accept any key; a device setting (a path, an option
// string, rfc2217://HOST:PORT) is read or refused with OptionError.
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    wiretape::device_options(text);
  } catch (const wiretape::OptionError&) {
  }
  wiretape::Options parsed;
  try {
    parsed = wiretape::Options::parse(text);
  } catch (const wiretape::OptionError&) {
    return 0;
  }
  const wiretape::Options again = wiretape::Options::parse(parsed.to_string());
  if (again.entries().size() != parsed.entries().size()) std::abort();
  for (std::size_t i = 0; i < parsed.entries().size(); ++i) {
    if (again.entries()[i].key != parsed.entries()[i].key ||
        again.entries()[i].value != parsed.entries()[i].value) {
      std::abort();
    }
  }
  auto attempt = [](auto&& take) {
    try {
      take();
    } catch (const wiretape::OptionError&) {
    }
  };
  for (auto type : wiretape::port_types()) {
    wiretape::Options options = parsed;
    options.set_port_type(type);
    attempt([&] { options.resolve_aliases(); });
    for (const wiretape::OptionKey& key : wiretape::option_keys()) {
      if (!key.applies_to(type) || !key.alias_of.empty()) continue;
      const bool has_value = key.required || !key.default_value.empty() || options.has(key.name);
      if (key.prefix) {
        attempt([&] { options.take_prefixed(key.name); });
        continue;
      }
      if (!has_value) continue;
      switch (key.type) {
        case wiretape::OptionType::boolean: attempt([&] { options.take_bool(key.name); }); break;
        case wiretape::OptionType::integer: attempt([&] { options.take_int(key.name); }); break;
        case wiretape::OptionType::number: attempt([&] { options.take_double(key.name); }); break;
        case wiretape::OptionType::seconds: attempt([&] { options.take_timeout(key.name); }); break;
        case wiretape::OptionType::choice: attempt([&] { options.take_choice(key.name); }); break;
        case wiretape::OptionType::text:
        case wiretape::OptionType::path: attempt([&] { options.take_string(key.name); }); break;
      }
    }
    for (const auto& entry : options.entries()) wiretape::suggest_key(entry.key, type);
    attempt([&] { options.finish(type); });
  }
  return 0;
}
