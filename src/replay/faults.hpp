// Fault injection on replay (DESIGN.md sections 14 and 17): the kinds of
// fault, and `faults=` parsed once into a plan that the replay config holds
// (replay_config.hpp) and Python reads through the bindings. The stage that
// applies a plan to the rx a replay releases is fault_stage.hpp.
//
// Every random choice comes from the plan's seed through a generator of our
// own (splitmix64), so a plan does the same on every platform.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/fault_hook.hpp"  // FaultEvent
#include "session/record_source.hpp"
#include "wiretape/profile.hpp"

namespace wiretape::detail {

enum class FaultKind {
  drop,        // the exchange's rx lost (drop:N: N bytes of it, N datagrams)
  corrupt,     // N bit flips (default 1)
  garbage,     // N random bytes inserted (default 8)
  truncate,    // the response stops after N bytes (default: half of it)
  duplicate,   // the response's first record sent twice
  delay,       // the response comes MS later
  stall,       // a gap of MS inside the response
  trickle,     // one byte at a time (MS apart, default 1)
  silence,     // the device stops answering, for good
  disconnect,  // the device is lost: PortClosed from here on
  reconnect,   // the device is lost for MS, then answers again
};

// Whether a kind takes `:N` (or `:MS`).
enum class FaultAmount { none, optional, required };

struct FaultKindInfo {
  const char* name;
  FaultKind kind;
  FaultAmount amount;
  // What a campaign gives a kind whose amount is required (docs/faults.md
  // says why), in ms; 0 for the others, which a campaign injects bare.
  std::uint64_t campaign_amount;
};

// Every kind, in the order a campaign injects them: the one table the
// parser, the campaigns (python/wiretape/faults.py) and the docs go by.
inline constexpr FaultKindInfo kFaultKinds[] = {
    {"drop", FaultKind::drop, FaultAmount::optional, 0},
    {"corrupt", FaultKind::corrupt, FaultAmount::optional, 0},
    {"garbage", FaultKind::garbage, FaultAmount::optional, 0},
    {"truncate", FaultKind::truncate, FaultAmount::optional, 0},
    {"duplicate", FaultKind::duplicate, FaultAmount::none, 0},
    {"delay", FaultKind::delay, FaultAmount::required, 500},
    {"stall", FaultKind::stall, FaultAmount::required, 500},
    {"trickle", FaultKind::trickle, FaultAmount::optional, 0},
    {"silence", FaultKind::silence, FaultAmount::none, 0},
    {"disconnect", FaultKind::disconnect, FaultAmount::none, 0},
    {"reconnect", FaultKind::reconnect, FaultAmount::required, 500},
};

const FaultKindInfo& fault_kind_info(FaultKind kind);
// The KIND a campaign injects for `info` (delay -> delay:500, drop -> drop).
std::string campaign_kind_text(const FaultKindInfo& info);

enum class FaultWhereKind { exchange, rx, time, every, probability };

struct FaultPlaceInfo {
  const char* name;  // as WHERE spells it: NAME:VALUE
  FaultWhereKind where;
  bool counted;  // VALUE is a whole number (where_number), else a number (where_value)
};

// Every WHERE: the one table the parser and the bindings go by.
inline constexpr FaultPlaceInfo kFaultPlaces[] = {
    {"exchange", FaultWhereKind::exchange, true},
    {"rx", FaultWhereKind::rx, true},
    {"t", FaultWhereKind::time, false},
    {"every", FaultWhereKind::every, true},
    {"p", FaultWhereKind::probability, false},
};

const FaultPlaceInfo& fault_place_info(FaultWhereKind where);

struct FaultSpec {
  FaultKind kind = FaultKind::drop;
  std::optional<std::uint64_t> amount;  // the :N or :MS, when given
  FaultWhereKind where = FaultWhereKind::exchange;
  std::uint64_t where_number = 0;  // exchange:N, rx:N, every:K
  double where_value = 0;          // t:SECONDS, p:P
  std::string kind_text;           // normalised (corrupt:4), for reports
  std::string where_text;          // normalised (exchange:3, p:0.25; exchange:3@channel:gps)
  // `@channel:NAME`: only the replay of that channel injects it; empty: every
  // replay it is given to.
  std::string channel;
  std::string text;                // the item as written (trimmed), for errors
};

// Where faults can fire in what a replay of one channel serves, as the
// fault stage (fault_stage.hpp) counts places: measured by the one
// segmentation (exchanges.hpp, served_shape).
struct SessionShape {
  std::uint64_t first_exchange = 0;  // the number of the first exchange served
  std::uint64_t exchange_end = 0;    // one past the last exchange with rx
  std::uint64_t rx_bytes = 0;        // rx bytes served
  // The session time of the last rx record served (0: none). `t:S` fires at
  // the first rx recorded at or after S on the session's clock, so S past
  // it never fires.
  std::uint64_t last_rx_t_ns = 0;
};

// A session as fault places are checked against it.
struct SessionPlaces {
  std::vector<std::string> channels;  // a session of several ports' names; empty: one port
  std::vector<SessionShape> shapes;   // one per channel, in that order; one for one port
};

struct FaultPlan {
  std::vector<FaultSpec> faults;
  std::uint64_t seed = 0;
  bool empty() const { return faults.empty(); }
  // Throws OptionError naming `faults` for a fault naming a channel
  // `session` lacks, or placed past the end of what its replay serves
  // (exchange:N, rx:N, t:S; a fault without @channel: past every channel's
  // end), naming the item, the end and the channels.
  void check_against(const SessionPlaces& session) const;
};

// The grammar, for error messages and docs.
extern const char* const kFaultGrammar;

// Parses `faults=` (a `;`-separated list of KIND@WHERE). Throws OptionError
// naming the key `faults`, the item and the grammar.
FaultPlan parse_faults(std::string_view text, std::uint64_t seed);

// The faults of `plan` for the replay of channel `channel` of a session whose
// channels are `names` (their names; empty for a file of one unnamed
// channel): those without `@channel:` and those naming it. Throws
// OptionError naming `faults` for a fault naming a channel the file does not
// have.
FaultPlan faults_for_channel(const FaultPlan& plan, const std::string& channel,
                             const std::vector<std::string>& names,
                             const std::string& file);

// Parses one KIND (drop, corrupt:4, delay:500) into its normal spelling;
// throws OptionError naming the key `faults`, the kind and the grammar.
std::string normal_fault_kind(std::string_view kind);

// splitmix64: small, fast, and the same everywhere.
std::uint64_t splitmix64(std::uint64_t x);


}  // namespace wiretape::detail
