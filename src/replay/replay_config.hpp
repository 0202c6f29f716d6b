// The keys of type=replay (DESIGN.md section 7), parsed once into a value.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>

#include "replay/faults.hpp"
#include "wiretape/options.hpp"
#include "wiretape/profile.hpp"

namespace wiretape::detail {

enum class ReplayTiming { none, session, causal };
enum class ReplayCheck { off, data, timing };
enum class ReplayMatch { sequence, request };
enum class ReplayUnmatched { error, silent };
enum class ReplayRepeat { none, last, cycle };
enum class ReplayUnused { ignore, warn, error };
enum class ReplayAtEnd { silent, closed };

class ChannelHub;
class ChannelMember;

struct ReplayConfig {
  std::string file;
  // channel=NAME as given: which channel of a session of several ports
  // (DESIGN.md section 19); empty: not given.
  std::string channel;
  // The channel replayed (open_replay resolves `channel`): its records only.
  std::uint16_t channel_id = 0;
  // Whether the file has several channels: reports then name the channel.
  bool several_channels = false;
  // What the replays of this file's channels in this process share (one
  // clock, causal order across channels); nullptr for a file of one channel.
  std::shared_ptr<ChannelHub> hub;
  // timing=causal on a file of several channels: this replay's place in the
  // order across channels (match=sequence gates its rx on it); else nullptr.
  std::shared_ptr<ChannelMember> member;
  ReplayTiming timing = ReplayTiming::causal;
  double speed = 1.0;
  ReplayCheck check = ReplayCheck::data;
  std::chrono::nanoseconds tolerance = std::chrono::milliseconds(100);
  ReplayMatch match = ReplayMatch::sequence;
  ReplayUnmatched unmatched = ReplayUnmatched::error;
  ReplayRepeat repeat = ReplayRepeat::none;
  // match=request: how long the matcher waits, with no new byte, for a longer
  // request recorded earlier before it takes a shorter one that is complete
  // (DESIGN.md section 13).
  std::chrono::nanoseconds gap = std::chrono::milliseconds(50);
  // match=sequence: how long rx recorded after a client flush waits for the
  // client's own once it is otherwise due; the client may flush fewer times
  // (TIOCPKT merges flushes made back to back; probes vary) (DESIGN.md
  // section 12).
  std::chrono::nanoseconds flush_wait = std::chrono::milliseconds(200);
  // match=request with a recording of several client sessions: the
  // recorded session whose greeting this client session gets and whose
  // exchanges it matches first (1-based; 0: the recording has none).
  int client_session = 0;
  ReplayUnused unused = ReplayUnused::warn;
  ReplayAtEnd at_end = ReplayAtEnd::silent;
  // profile=NAME: exchanges are request frames matched by their keys, and
  // served responses are fixed (DESIGN.md section 13); none: raw bytes.
  std::shared_ptr<const Profile> profile;
  // Datagram sessions (recorded from udp) keep record boundaries.
  bool datagrams = false;
  // The number of the first exchange replayed: exchanges are numbered per
  // file (exchanges.hpp), so a virtual device's later client session goes on
  // from the exchanges of the sessions before it.
  std::uint64_t first_exchange = 0;
  // Fault injection (faults.hpp): faults= parsed, with seed= for its random
  // choices; empty without faults=.
  FaultPlan faults;
  // The line settings the recorded device opened with (its port options'
  // baud, databits, ...; a serial port's defaults where they say none): the
  // replay starts with them, so that a virtual device tells the client's
  // changes from them as the proxy that recorded them did.
  SerialSettings recorded_settings;
  // Nothing this replay does depends on when (timing=none, no faults,
  // match=sequence without check=timing, one channel, and no client flush
  // recorded, so no flush gate waits): every record is due at the open
  // time, so the port tells the engine that time instead of reading the
  // clock at each call. Set by whoever checked the recording
  // (untimed_replay()); false otherwise.
  bool untimed = false;
};

// Whether `config` over records holding client flushes or not
// (`recorded_flushes`) may be played untimed (ReplayConfig::untimed).
inline bool untimed_replay(const ReplayConfig& config, bool recorded_flushes) {
  return config.timing == ReplayTiming::none && config.faults.empty() &&
         config.match == ReplayMatch::sequence && config.check != ReplayCheck::timing &&
         !config.hub && !config.member && !recorded_flushes;
}

// Whether empty tx and rx records are datagrams that the replay serves and
// checks like any other (DESIGN.md section 23): in a datagram session
// matched in sequence without a profile, whose framers cannot frame an
// empty datagram. Elsewhere an empty record means nothing and is skipped.
inline bool replays_empty_datagrams(const ReplayConfig& config) {
  return config.datagrams && config.match == ReplayMatch::sequence && !config.profile;
}

// Consumes the replay keys of `options` (and flexiport's spellings:
// strictness, ignoretimes, jitter), then refuses any key left, so the keys
// that are not replay keys must have been taken before. Throws OptionError
// naming the key.
ReplayConfig take_replay_config(Options& options);

}  // namespace wiretape::detail
