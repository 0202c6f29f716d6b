#include "replay/faults.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "wiretape/errors.hpp"

namespace wiretape::detail {

const char* const kFaultGrammar =
    "faults=KIND@WHERE[;KIND@WHERE...] with KIND one of drop[:N], corrupt[:N], "
    "garbage[:N], truncate[:N], duplicate, delay:MS, stall:MS, trickle[:MS], "
    "silence, disconnect, reconnect:MS and WHERE one of exchange:N, rx:N, "
    "t:SECONDS, every:K, p:P (0..1, with seed=), optionally followed by "
    "@channel:NAME (that channel's replay only)";

namespace {

// Bounds that keep a plan cheap to parse and to apply.
constexpr std::size_t kMaxFaults = 256;
constexpr std::uint64_t kMaxAmount = 1'000'000'000;  // bytes, flips or ms
// Bit flips and inserted bytes are made one by one: bounded so that a typo
// cannot make a replay allocate or loop for minutes.
constexpr std::uint64_t kMaxBytesMade = 1 << 20;

std::string_view trim(std::string_view text) {
  const auto space = [](char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; };
  while (!text.empty() && space(text.front())) text.remove_prefix(1);
  while (!text.empty() && space(text.back())) text.remove_suffix(1);
  return text;
}

[[noreturn]] void bad_item(std::string_view item, const std::string& problem) {
  throw OptionError("faults", "option 'faults': '" + std::string(item) + "': " + problem +
                                  "; expected " + kFaultGrammar);
}

std::optional<std::uint64_t> parse_unsigned(std::string_view text) {
  if (text.empty() || text.size() > 19) return std::nullopt;
  std::uint64_t value = 0;
  for (char c : text) {
    if (c < '0' || c > '9') return std::nullopt;
    value = value * 10 + static_cast<std::uint64_t>(c - '0');
  }
  return value;
}

std::optional<double> parse_number(std::string_view text) {
  if (text.empty() || text.size() > 32) return std::nullopt;
  bool dot = false;
  for (char c : text) {
    if (c == '.' && !dot) {
      dot = true;
    } else if (c < '0' || c > '9') {
      return std::nullopt;
    }
  }
  if (text == ".") return std::nullopt;
  return std::strtod(std::string(text).c_str(), nullptr);
}

std::string format_number(double value) {
  char text[64];
  std::snprintf(text, sizeof text, "%g", value);
  return text;
}

// KIND into spec.kind, spec.amount and spec.kind_text; `item` for errors.
void parse_kind(std::string_view kind_text, std::string_view item, FaultSpec& spec) {
  const std::size_t colon = kind_text.find(':');
  const std::string_view kind_name = kind_text.substr(0, colon);
  const FaultKindInfo* known = nullptr;
  for (const FaultKindInfo& candidate : kFaultKinds) {
    if (kind_name == candidate.name) known = &candidate;
  }
  if (known == nullptr) bad_item(item, "unknown fault kind '" + std::string(kind_name) + "'");
  spec.kind = known->kind;
  if (colon != std::string_view::npos) {
    if (known->amount == FaultAmount::none) {
      bad_item(item, std::string("'") + known->name + "' takes no ':N'");
    }
    const auto amount = parse_unsigned(kind_text.substr(colon + 1));
    if (!amount || *amount > kMaxAmount) {
      bad_item(item, std::string("'") + known->name + ":' needs a whole number from 0 to " +
                         std::to_string(kMaxAmount));
    }
    if (*amount == 0 && (spec.kind == FaultKind::corrupt || spec.kind == FaultKind::garbage ||
                         spec.kind == FaultKind::drop)) {
      bad_item(item, std::string("'") + known->name + ":0' would do nothing; give 1 or more");
    }
    if (*amount > kMaxBytesMade &&
        (spec.kind == FaultKind::corrupt || spec.kind == FaultKind::garbage)) {
      bad_item(item, std::string("'") + known->name + ":' takes at most " +
                         std::to_string(kMaxBytesMade));
    }
    spec.amount = *amount;
  } else if (known->amount == FaultAmount::required) {
    bad_item(item, std::string("'") + known->name + "' needs ':MS' (milliseconds)");
  }
  spec.kind_text = known->name;
  if (spec.amount) spec.kind_text += ":" + std::to_string(*spec.amount);
}

// WHERE into spec.where, its number or value and spec.where_text.
void parse_where(std::string_view where_text, std::string_view item, FaultSpec& spec) {
  const std::size_t where_colon = where_text.find(':');
  if (where_colon == std::string_view::npos) bad_item(item, "WHERE needs NAME:VALUE");
  const std::string_view where_name = where_text.substr(0, where_colon);
  const std::string_view value = where_text.substr(where_colon + 1);
  const FaultPlaceInfo* place = nullptr;
  for (const FaultPlaceInfo& candidate : kFaultPlaces) {
    if (where_name == candidate.name) place = &candidate;
  }
  if (place == nullptr) bad_item(item, "unknown WHERE '" + std::string(where_name) + "'");
  spec.where = place->where;
  if (place->counted) {
    const auto number = parse_unsigned(value);
    if (!number || *number > std::numeric_limits<std::int64_t>::max()) {
      bad_item(item, "'" + std::string(where_name) + ":' needs a whole number");
    }
    if (spec.where == FaultWhereKind::every && *number == 0) {
      bad_item(item, "'every:0' never fires; give 1 or more");
    }
    spec.where_number = *number;
    spec.where_text = std::string(where_name) + ":" + std::to_string(*number);
    return;
  }
  const bool time = spec.where == FaultWhereKind::time;
  const auto number = parse_number(value);
  if (!number || !std::isfinite(*number) || *number > 1e9 || (!time && *number > 1.0)) {
    bad_item(item, time ? "'t:' needs session seconds (a number, 0 or more)"
                        : "'p:' needs a probability from 0 to 1");
  }
  spec.where_value = *number;
  spec.where_text = std::string(where_name) + ":" + format_number(*number);
}

FaultSpec parse_item(std::string_view item) {
  const std::size_t at = item.find('@');
  if (at == std::string_view::npos) bad_item(item, "no '@WHERE'");
  FaultSpec spec;
  spec.text = std::string(item);
  parse_kind(trim(item.substr(0, at)), item, spec);
  std::string_view where = trim(item.substr(at + 1));
  // WHERE@channel:NAME: the fault belongs to one channel of the session.
  if (const std::size_t channel_at = where.find('@'); channel_at != std::string_view::npos) {
    const std::string_view channel = trim(where.substr(channel_at + 1));
    constexpr std::string_view prefix = "channel:";
    if (channel.substr(0, prefix.size()) != prefix) {
      bad_item(item, "after WHERE only '@channel:NAME' may follow");
    }
    spec.channel = std::string(trim(channel.substr(prefix.size())));
    if (spec.channel.empty()) bad_item(item, "'@channel:' needs the channel's name");
    where = trim(where.substr(0, channel_at));
  }
  parse_where(where, item, spec);
  if (!spec.channel.empty()) spec.where_text += "@channel:" + spec.channel;
  return spec;
}

}  // namespace

const FaultKindInfo& fault_kind_info(FaultKind kind) {
  for (const FaultKindInfo& info : kFaultKinds) {
    if (info.kind == kind) return info;
  }
  return kFaultKinds[0];  // every enumerator has a row
}

std::string campaign_kind_text(const FaultKindInfo& info) {
  if (info.amount != FaultAmount::required) return info.name;
  return std::string(info.name) + ":" + std::to_string(info.campaign_amount);
}

const FaultPlaceInfo& fault_place_info(FaultWhereKind where) {
  for (const FaultPlaceInfo& info : kFaultPlaces) {
    if (info.where == where) return info;
  }
  return kFaultPlaces[0];  // every enumerator has a row
}

std::string normal_fault_kind(std::string_view kind) {
  const std::string_view trimmed = trim(kind);
  if (trimmed.find_first_of("@;") != std::string_view::npos) {
    bad_item(trimmed, "a KIND alone has no '@' or ';'");
  }
  FaultSpec spec;
  parse_kind(trimmed, trimmed, spec);
  return spec.kind_text;
}

FaultPlan faults_for_channel(const FaultPlan& plan, const std::string& channel,
                             const std::vector<std::string>& names,
                             const std::string& file) {
  FaultPlan chosen;
  chosen.seed = plan.seed;
  for (const FaultSpec& spec : plan.faults) {
    if (!spec.channel.empty() &&
        std::find(names.begin(), names.end(), spec.channel) == names.end()) {
      std::string known;
      for (const std::string& name : names) {
        if (name.empty()) continue;
        known += (known.empty() ? "" : ", ") + name;
      }
      throw OptionError("faults", "option 'faults': '" + spec.text + "' names channel '" +
                                      spec.channel + "', which " + file + " does not have (" +
                                      (known.empty() ? "it has no named channels"
                                                     : "its channels: " + known) +
                                      ")");
    }
    if (spec.channel.empty() || spec.channel == channel) chosen.faults.push_back(spec);
  }
  return chosen;
}

void FaultPlan::check_against(const SessionPlaces& session) const {
  const auto refuse = [](const FaultSpec& spec, const std::string& problem) {
    throw OptionError("faults", spec.text + ": " + problem);
  };
  // A fault without @channel: applies to every channel: past the end only
  // when past every channel's.
  SessionShape every;
  for (const SessionShape& shape : session.shapes) {
    every.exchange_end = std::max(every.exchange_end, shape.exchange_end);
    every.rx_bytes = std::max(every.rx_bytes, shape.rx_bytes);
    every.last_rx_t_ns = std::max(every.last_rx_t_ns, shape.last_rx_t_ns);
  }
  for (const FaultSpec& spec : faults) {
    const SessionShape* shape = &every;
    std::string whose = session.channels.empty() ? "the session" : "every channel";
    if (!spec.channel.empty()) {
      const auto found =
          std::find(session.channels.begin(), session.channels.end(), spec.channel);
      if (found == session.channels.end()) {
        std::string known;
        for (const std::string& name : session.channels) {
          known += (known.empty() ? "" : ", ") + name;
        }
        refuse(spec, "the session has no channel '" + spec.channel + "' (its channels: " +
                         (known.empty() ? "none: the session has one port (leave @channel out)"
                                        : known) +
                         ")");
      }
      const auto at = static_cast<std::size_t>(found - session.channels.begin());
      if (at < session.shapes.size()) shape = &session.shapes[at];
      whose = "channel " + spec.channel;
    }
    switch (spec.where) {
      case FaultWhereKind::exchange:
        if (spec.where_number >= shape->exchange_end) {
          refuse(spec, whose + " has " + std::to_string(shape->exchange_end) +
                           " exchanges with rx (0.." +
                           std::to_string(static_cast<std::int64_t>(shape->exchange_end) - 1) +
                           "); exchange " + std::to_string(spec.where_number) +
                           " is past its end");
        }
        break;
      case FaultWhereKind::rx:
        if (spec.where_number >= shape->rx_bytes) {
          refuse(spec, whose + " has " + std::to_string(shape->rx_bytes) + " rx bytes; rx byte " +
                           std::to_string(spec.where_number) + " is past its end");
        }
        break;
      case FaultWhereKind::time:
        // The fault stage's own test: it fires at an rx recorded at or after S.
        if (static_cast<double>(shape->last_rx_t_ns) < spec.where_value * 1e9) {
          char seconds[64];
          std::snprintf(seconds, sizeof seconds, "%.3f",
                        static_cast<double>(shape->last_rx_t_ns) / 1e9);
          refuse(spec, whose + " lasts " + seconds + " s; t:" + format_number(spec.where_value) +
                           " is past its end");
        }
        break;
      default:
        break;
    }
  }
}

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

FaultPlan parse_faults(std::string_view text, std::uint64_t seed) {
  FaultPlan plan;
  plan.seed = seed;
  std::size_t start = 0;
  while (start <= text.size()) {
    std::size_t end = text.find(';', start);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view item = trim(text.substr(start, end - start));
    if (!item.empty()) {
      if (plan.faults.size() == kMaxFaults) {
        throw OptionError("faults", "option 'faults': more than " + std::to_string(kMaxFaults) +
                                        " faults in one plan");
      }
      plan.faults.push_back(parse_item(item));
    }
    start = end + 1;
  }
  return plan;
}

}  // namespace wiretape::detail
