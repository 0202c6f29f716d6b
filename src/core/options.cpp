#include "wiretape/options.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <stdexcept>

#include "util/hex.hpp"
#include "wiretape/errors.hpp"

namespace wiretape {

namespace {

bool is_separator(char c) {
  return c == ',' || c == ' ' || c == '\t' || c == '\n' || c == '\r';
}

std::string lower(std::string_view text) {
  std::string out(text);
  std::transform(out.begin(), out.end(), out.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& item : items) {
    if (!out.empty()) out += ", ";
    out += item;
  }
  return out;
}

// Printable rendering of user text inside an error message.
std::string shown(std::string_view text) {
  std::string out = "'";
  for (unsigned char c : text) {
    if (c >= 0x20 && c < 0x7f) {
      out += static_cast<char>(c);
    } else {
      detail::append_hex_escape(out, c);
    }
  }
  return out + "'";
}

// What a key's row says is valid, for the messages of bad values.
std::string integer_range(const OptionKey& row) {
  return "a whole number from " + std::to_string(row.min_integer) + " to " +
         std::to_string(row.max_integer);
}

std::string number_range(const OptionKey& row) {
  auto shown_number = [](double value) {
    std::string text = std::to_string(value);
    text.erase(text.find_last_not_of('0') + 1);
    if (!text.empty() && text.back() == '.') text.pop_back();
    return text;
  };
  return "a number from " + shown_number(row.min_number) + " to " +
         shown_number(row.max_number);
}

std::vector<std::string> names_of(const std::vector<std::string_view>& views) {
  return {views.begin(), views.end()};
}

// A NUL byte cuts a value short where it reaches the OS as a C string (a
// path, a device): refused everywhere a value enters an Options.
void reject_nul(std::string_view key, std::string_view value) {
  const auto nul = value.find('\0');
  if (nul == std::string_view::npos) return;
  throw OptionError(std::string(key), "option '" + std::string(key) +
                                          "': its value holds a NUL byte (at byte " +
                                          std::to_string(nul) +
                                          " of the value), which would cut it short");
}

}  // namespace

Options Options::parse(std::string_view text) {
  Options options;
  std::size_t i = 0;
  const std::size_t n = text.size();
  // "type=serial,,device=X" is a slip of the keyboard, not a style: an empty
  // member is refused where it is (spaces beside a comma are no member). A
  // comma at the end is not one: "file=x," + more keys, more often empty.
  bool member_since_comma = false;
  std::size_t last_comma = std::string_view::npos;
  while (i < n) {
    if (is_separator(text[i])) {
      if (text[i] == ',') {
        if (!member_since_comma) {
          throw OptionError("", "option string: an empty option at position " +
                                    std::to_string(i) +
                                    (last_comma == std::string_view::npos
                                         ? " (nothing before the first comma)"
                                         : " (nothing between the commas at positions " +
                                               std::to_string(last_comma) + " and " +
                                               std::to_string(i) + ")"));
        }
        member_since_comma = false;
        last_comma = i;
      }
      ++i;
      continue;
    }
    member_since_comma = true;
    const std::size_t key_start = i;
    while (i < n && !is_separator(text[i]) && text[i] != '=') {
      if (text[i] == '"') {
        throw OptionError("", "option string: unexpected '\"' in a key at "
                              "position " + std::to_string(i));
      }
      if (text[i] == '\0') {
        throw OptionError("", "option string: a NUL byte in a key at position " +
                                  std::to_string(i));
      }
      ++i;
    }
    std::string key(text.substr(key_start, i - key_start));
    if (key.empty()) {
      throw OptionError("", "option string: '=' with no key before it at "
                            "position " + std::to_string(key_start));
    }
    std::string value = "1";
    if (i < n && text[i] == '=') {
      ++i;
      value.clear();
      if (i < n && text[i] == '"') {
        const std::size_t quote_start = i;
        ++i;
        bool closed = false;
        while (i < n) {
          if (text[i] == '\\' && i + 1 < n &&
              (text[i + 1] == '"' || text[i + 1] == '\\')) {
            value += text[i + 1];
            i += 2;
          } else if (text[i] == '"') {
            closed = true;
            ++i;
            break;
          } else {
            value += text[i++];
          }
        }
        if (!closed) {
          throw OptionError(key, "option string: the quoted value of '" + key +
                                     "' opened at position " +
                                     std::to_string(quote_start) +
                                     " is never closed");
        }
        if (i < n && !is_separator(text[i])) {
          throw OptionError(key, "option string: text after the closing quote "
                                 "of '" + key + "' at position " +
                                 std::to_string(i) +
                                 "; separate options with commas");
        }
      } else {
        while (i < n && !is_separator(text[i])) {
          if (text[i] == '"') {
            throw OptionError(key, "option string: a '\"' inside the value of '" +
                                       key + "' at position " + std::to_string(i) +
                                       "; quote the whole value instead");
          }
          value += text[i++];
        }
      }
    }
    if (options.find(key)) {
      throw OptionError(key, "option '" + key + "' is given twice");
    }
    reject_nul(key, value);
    options.add(std::move(key), std::move(value));
  }
  return options;
}

void Options::add(std::string key, std::string value) {
  index_.emplace(key, entries_.size());
  entries_.push_back({std::move(key), std::move(value)});
}

void Options::reindex() {
  index_.clear();
  for (std::size_t i = 0; i < entries_.size(); ++i) index_.emplace(entries_[i].key, i);
}

const Options::Entry* Options::find(std::string_view key) const {
  const auto found = index_.find(std::string(key));
  return found == index_.end() ? nullptr : &entries_[found->second];
}

bool Options::has(std::string_view key) const { return find(key) != nullptr; }

std::optional<std::string> Options::peek(std::string_view key) const {
  if (const Entry* entry = find(key)) return entry->value;
  return std::nullopt;
}

void Options::set(std::string_view key, std::string value) {
  reject_nul(key, value);
  if (const auto found = index_.find(std::string(key)); found != index_.end()) {
    entries_[found->second].value = std::move(value);
    return;
  }
  add(std::string(key), std::move(value));
}

void Options::erase(std::string_view key) {
  const auto found = index_.find(std::string(key));
  if (found == index_.end()) return;
  entries_.erase(entries_.begin() + static_cast<std::ptrdiff_t>(found->second));
  reindex();
}

void Options::alias(std::string_view alias, std::string_view canonical) {
  const Entry* old_name = find(alias);
  if (!old_name) return;
  if (has(canonical)) {
    throw OptionError(std::string(alias),
                      "options '" + std::string(alias) + "' and '" +
                          std::string(canonical) +
                          "' mean the same thing; give only one");
  }
  std::string value = old_name->value;
  erase(alias);
  set(canonical, std::move(value));
}

void Options::set_port_type(std::string_view port_type) { port_type_ = std::string(port_type); }

void Options::resolve_aliases() {
  for (const OptionKey& key : option_keys()) {
    if (!key.alias_of.empty() && key.applies_to(port_type_)) alias(key.name, key.alias_of);
  }
}

const OptionKey& Options::row(std::string_view key, OptionType type) const {
  const OptionKey* found = nullptr;
  for (const OptionKey& candidate : option_keys()) {
    if (candidate.name != key) continue;
    if (candidate.applies_to(port_type_)) {
      found = &candidate;
      break;
    }
    if (port_type_.empty() && !found) found = &candidate;
  }
  // Paths are text to whoever reads them as text.
  const bool fits = found && (found->type == type || (type == OptionType::text &&
                                                       found->type == OptionType::path));
  if (!fits) {
    throw std::logic_error("option key '" + std::string(key) + "' is read as " +
                           wiretape::to_string(type) + " but the key table " +
                           (found ? std::string("says ") + wiretape::to_string(found->type)
                                  : std::string("has no such key")) +
                           " for type=" + port_type_);
  }
  return *found;
}

std::optional<std::string> Options::take(std::string_view key) {
  const Entry* entry = find(key);
  if (!entry) return std::nullopt;
  consumed_.emplace(key);
  return entry->value;
}

namespace {

// The message of an unknown key a typo away from `near`, a key of `type`.
std::string typo_message(const std::string& unknown, std::string_view type,
                         const std::string& near) {
  return "unknown option " + shown(unknown) + " for type=" + std::string(type) +
         "; did you mean '" + near + "'?";
}

// The value of `row`: given, or the row's default. Nothing when neither; a
// required key missing is an OptionError, which names the typo of it
// (devcie=) among the keys given when there is one: that is the mistake.
std::optional<std::string> value_or_default(std::optional<std::string> given,
                                            const OptionKey& row,
                                            std::string_view port_type,
                                            const std::vector<Options::Entry>& entries) {
  if (row.required && (!given || given->empty())) {
    const std::string key(row.name);
    if (!given) {
      for (const auto& entry : entries) {
        if (find_option_key(entry.key, port_type)) continue;
        if (nearest_name(entry.key, {key})) {
          throw OptionError(entry.key, typo_message(entry.key, port_type, key));
        }
      }
    }
    throw OptionError(key, "missing option '" + key + "'" +
                               (port_type.empty() ? std::string()
                                                  : " for type=" + std::string(port_type)) +
                               " (" + key + "=...: " + std::string(row.help) +
                               (row.type == OptionType::integer ? ", " + integer_range(row)
                                                                : std::string()) +
                               ")");
  }
  if (given) return given;
  if (!row.default_value.empty()) return std::string(row.default_value);
  return std::nullopt;
}

std::string no_default(const OptionKey& row) {
  return "option key '" + std::string(row.name) +
         "' has no default in the key table: check that it is given first";
}

}  // namespace

std::string Options::take_string(std::string_view key) {
  const OptionKey& key_row = row(key, OptionType::text);
  return value_or_default(take(key), key_row, port_type_, entries_).value_or("");
}

std::string Options::take_required(std::string_view key) {
  const OptionKey& key_row = row(key, OptionType::text);
  if (!key_row.required) {
    throw std::logic_error("option key '" + std::string(key) +
                           "' is not required in the key table");
  }
  return *value_or_default(take(key), key_row, port_type_, entries_);
}

bool Options::take_bool(std::string_view key) {
  const OptionKey& key_row = row(key, OptionType::boolean);
  const auto value = value_or_default(take(key), key_row, port_type_, entries_);
  if (!value) throw std::logic_error(no_default(key_row));
  if (const auto parsed = parse_bool(*value)) return *parsed;
  throw OptionError(std::string(key),
                    "option '" + std::string(key) + "': " + shown(*value) +
                        " is not a boolean; use true/false, yes/no, on/off or "
                        "1/0");
}

std::int64_t Options::take_int(std::string_view key) {
  const OptionKey& key_row = row(key, OptionType::integer);
  const auto value = value_or_default(take(key), key_row, port_type_, entries_);
  if (!value) throw std::logic_error(no_default(key_row));
  errno = 0;
  char* end = nullptr;
  const long long parsed = std::strtoll(value->c_str(), &end, 10);
  if (value->empty() || *end != '\0' || errno == ERANGE || parsed < key_row.min_integer ||
      parsed > key_row.max_integer) {
    throw OptionError(std::string(key), "option '" + std::string(key) + "': " +
                                            shown(*value) + " is not " +
                                            integer_range(key_row));
  }
  return parsed;
}

double Options::take_double(std::string_view key) {
  const OptionKey& key_row = row(key, OptionType::number);
  const auto value = value_or_default(take(key), key_row, port_type_, entries_);
  if (!value) throw std::logic_error(no_default(key_row));
  char* end = nullptr;
  const double parsed = std::strtod(value->c_str(), &end);
  if (value->empty() || *end != '\0' || !std::isfinite(parsed) ||
      parsed < key_row.min_number || parsed > key_row.max_number) {
    throw OptionError(std::string(key), "option '" + std::string(key) + "': " +
                                            shown(*value) + " is not " +
                                            number_range(key_row));
  }
  return parsed;
}

std::string Options::take_choice(std::string_view key) {
  const OptionKey& key_row = row(key, OptionType::choice);
  const auto value = value_or_default(take(key), key_row, port_type_, entries_);
  if (!value) throw std::logic_error(no_default(key_row));
  const std::string v = lower(*value);
  for (auto choice : key_row.choices) {
    if (v == choice) return v;
  }
  throw OptionError(std::string(key), "option '" + std::string(key) + "': " +
                                          shown(*value) + " is not one of " +
                                          join(names_of(key_row.choices)));
}

Timeout Options::take_timeout(std::string_view key) {
  const OptionKey& key_row = row(key, OptionType::seconds);
  const auto value = value_or_default(take(key), key_row, port_type_, entries_);
  if (!value) throw std::logic_error(no_default(key_row));
  const std::string v = lower(*value);
  if (v == "none" || v == "-1" || v == "forever") return forever;
  char* end = nullptr;
  const double seconds = std::strtod(v.c_str(), &end);
  if (v.empty() || *end != '\0' || !std::isfinite(seconds) ||
      seconds < key_row.min_number || seconds > key_row.max_number) {
    throw OptionError(std::string(key),
                      "option '" + std::string(key) + "': " + shown(*value) +
                          " is not a timeout; give seconds (e.g. 0.5), 0 to "
                          "poll, or -1/none to block");
  }
  return std::chrono::nanoseconds(static_cast<std::int64_t>(seconds * 1e9));
}

std::map<std::string, std::string> Options::take_prefixed(
    std::string_view prefix) {
  std::map<std::string, std::string> out;
  for (const auto& entry : entries_) {
    if (entry.key.size() > prefix.size() &&
        std::string_view(entry.key).substr(0, prefix.size()) == prefix) {
      consumed_.insert(entry.key);
      out[entry.key.substr(prefix.size())] = entry.value;
    }
  }
  return out;
}

void Options::finish(std::string_view type) const {
  for (const auto& entry : entries_) {
    if (consumed_.count(entry.key)) continue;
    std::vector<std::string> valid;
    for (const OptionKey& key : option_keys()) {
      if (!key.applies_to(type)) continue;
      std::string name = std::string(key.name) + (key.prefix ? "KEY" : "");
      if (std::find(valid.begin(), valid.end(), name) == valid.end()) valid.push_back(name);
    }
    const bool elsewhere =
        std::any_of(option_keys().begin(), option_keys().end(), [&](const OptionKey& key) {
          return key.prefix ? entry.key.size() > key.name.size() &&
                                  std::string_view(entry.key).substr(0, key.name.size()) ==
                                      key.name
                            : entry.key == key.name;
        });
    if (elsewhere) {
      throw OptionError(entry.key, "option '" + entry.key + "' does not apply to type=" +
                                       std::string(type) + "; valid keys for type=" +
                                       std::string(type) + ": " + join(valid));
    }
    // A typo gets the key it was meant to be, not a list of 30 to read through.
    if (const auto near = suggest_key(entry.key, type)) {
      throw OptionError(entry.key, typo_message(entry.key, type, *near));
    }
    throw OptionError(entry.key, "unknown option " + shown(entry.key) + "; valid keys for type=" +
                                     std::string(type) + ": " + join(valid));
  }
}

std::vector<Options::Entry> parse_options(std::string_view text) {
  return Options::parse(text).entries();
}

std::optional<bool> parse_bool(std::string_view text) {
  const std::string v = lower(text);
  if (v == "1" || v == "true" || v == "yes" || v == "on") return true;
  if (v == "0" || v == "false" || v == "no" || v == "off") return false;
  return std::nullopt;
}

std::optional<Parity> parse_parity(std::string_view text) {
  const std::string v = lower(text);
  for (Parity parity : {Parity::none, Parity::even, Parity::odd, Parity::mark, Parity::space}) {
    if (v == to_string(parity)) return parity;
  }
  return std::nullopt;
}

std::optional<FlowControl> parse_flow_control(std::string_view text) {
  const std::string v = lower(text);
  for (FlowControl flow : {FlowControl::none, FlowControl::rtscts, FlowControl::xonxoff}) {
    if (v == to_string(flow)) return flow;
  }
  return std::nullopt;
}

std::string quote_option_value(std::string_view value) {
  const bool plain =
      !value.empty() &&
      std::none_of(value.begin(), value.end(), [](char c) {
        return is_separator(c) || c == '"' || c == '=' || c == '\\';
      });
  if (plain) return std::string(value);
  std::string out = "\"";
  for (char c : value) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

std::string format_option_value(std::string_view key, const OptionValue& value) {
  if (const auto* text = std::get_if<std::string>(&value)) return *text;
  if (const auto* flag = std::get_if<bool>(&value)) return *flag ? "true" : "false";
  if (const auto* whole = std::get_if<std::int64_t>(&value)) return std::to_string(*whole);
  const double number = std::get<double>(value);
  if (!std::isfinite(number)) {
    throw OptionError(std::string(key), "option '" + std::string(key) +
                                            "': a value must be a finite number, not " +
                                            (std::isnan(number) ? "nan" : "infinity"));
  }
  // Whole numbers within 2^53 are exact as int64: "2", not "2" + ".0".
  if (number == std::floor(number) && std::fabs(number) < 9007199254740992.0) {
    return std::to_string(static_cast<std::int64_t>(number));
  }
  std::array<char, 32> digits{};
  const auto written = std::to_chars(digits.data(), digits.data() + digits.size(), number);
  return std::string(digits.data(), written.ptr);
}

std::string option_string(const std::vector<std::pair<std::string, OptionValue>>& pairs) {
  std::string out;
  std::set<std::string_view> seen;
  for (const auto& [key, value] : pairs) {
    const auto bad = std::find_if(key.begin(), key.end(), [](char c) {
      return is_separator(c) || c == '=' || c == '"' || c == '\0';
    });
    if (key.empty() || bad != key.end()) {
      throw OptionError(key, "option string: " + shown(key) +
                                 " is not a key (a key is not empty and holds no comma, "
                                 "white space, '=', '\"' or NUL byte)");
    }
    if (!seen.insert(key).second) {
      throw OptionError(key, "option '" + key + "' is given twice");
    }
    const std::string text = format_option_value(key, value);
    reject_nul(key, text);
    if (!out.empty()) out += ',';
    out += key + "=" + quote_option_value(text);
  }
  return out;
}

namespace {

// rfc2217://HOST:PORT (pyserial's form; [ADDRESS]:PORT for IPv6) as
// type=rfc2217,host=HOST,port=PORT.
std::string rfc2217_device_options(std::string_view url, std::string_view address) {
  const auto problem = [&](const std::string& what) {
    return OptionError("device", "device '" + std::string(url) + "': " + what +
                                     "; give rfc2217://HOST:PORT (e.g. "
                                     "rfc2217://lab-pi:2000)");
  };
  std::string_view host;
  std::string_view port;
  if (!address.empty() && address.front() == '[') {
    const auto close = address.find(']');
    if (close == std::string_view::npos) throw problem("no ']' after the IPv6 address");
    host = address.substr(1, close - 1);
    if (address.substr(close + 1, 1) != ":") throw problem("no ':PORT' after the address");
    port = address.substr(close + 2);
  } else {
    const auto colon = address.rfind(':');
    if (colon == std::string_view::npos) throw problem("no ':PORT'");
    host = address.substr(0, colon);
    port = address.substr(colon + 1);
  }
  if (host.empty()) throw problem("no host");
  if (port.empty() || port.find_first_not_of("0123456789") != std::string_view::npos ||
      port.size() > 5) {
    throw problem("the port '" + std::string(port) + "' is not a number");
  }
  if (host.find_first_of("/?#,\"") != std::string_view::npos) {
    throw problem("the host '" + std::string(host) + "' is not a host name or address");
  }
  return option_string({{"type", std::string("rfc2217")},
                        {"host", std::string(host)},
                        {"port", static_cast<std::int64_t>(std::stoi(std::string(port)))}});
}

}  // namespace

std::string device_options(std::string_view device) {
  const auto first = device.find_first_not_of(" \t\r\n");
  if (first == std::string_view::npos) {
    throw OptionError("device", "the device setting is empty; give a device "
                                "path (/dev/ttyUSB0) or a port option string "
                                "(type=tcp,host=10.0.0.5,port=10940)");
  }
  const auto last = device.find_last_not_of(" \t\r\n");
  const std::string_view text = device.substr(first, last - first + 1);
  constexpr std::string_view rfc2217_scheme = "rfc2217://";
  if (text.substr(0, rfc2217_scheme.size()) == rfc2217_scheme) {
    return rfc2217_device_options(text, text.substr(rfc2217_scheme.size()));
  }
  if (text.find('=') != std::string_view::npos) return std::string(text);
  return "type=serial,device=" + quote_option_value(text);
}

std::string Options::to_string() const {
  std::string out;
  for (const auto& entry : entries_) {
    if (!out.empty()) out += ',';
    out += entry.key + "=" + quote_option_value(entry.value);
  }
  return out;
}

}  // namespace wiretape
