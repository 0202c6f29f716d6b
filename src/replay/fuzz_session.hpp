// A fuzzing plan (fuzz_plan.hpp) applied to a recorded session (DESIGN.md
// section 27): the session's records of one channel with the device side
// mutated, for the replay engine to play (open_replay_session over them) or
// to be written as a plain .wtape session whose header's `edits` say what
// the plan changed. The public face is include/wiretape/fuzzing.hpp.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "replay/fuzz_plan.hpp"
#include "wiretape/profile.hpp"
#include "wiretape/session.hpp"

namespace wiretape::detail {

// One channel of a session, read once, that plans mutate again and again.
struct FuzzRecording {
  std::string path;
  SessionHeader header;
  Channel channel;
  std::vector<Record> records;  // the channel's, in recorded order
  std::shared_ptr<const Profile> profile;  // null: the plan acts on rx records
  std::vector<RxRecord> units;  // what a plan's steps index: rx records or frames
  // Delays up to this much in all are within the replay's tolerance
  // (tolerance=): a driver has no right to fail on them.
  std::uint64_t inert_delay_ms = 100;
};

// Reads channel `channel` (empty: the only one) of the session at `path`.
// Throws SessionError naming the file when it has no device bytes (nothing
// for a plan to change), and OptionError naming `profile` when the profile
// does not fit the recording (its rx framer finds no whole frame, or more
// broken frames than whole ones).
FuzzRecording read_fuzz_recording(const std::string& path, std::shared_ptr<const Profile> profile,
                                  const std::string& channel = "");

struct FuzzedRecords {
  std::vector<Record> records;
  std::vector<std::string> edits;
  // The plan changed nothing a driver may refuse (DESIGN.md section 27): it
  // only changed bytes the profile leaves out of matching (match_key), split
  // frames across reads, or delayed them within the tolerance.
  // A driver that fails on an inert plan has a finding even when it exits
  // cleanly with an error.
  bool inert = true;
};

// The recording's records with `plan` applied to its device side: each rx
// unit served at its place (the recorded rx it came from), the records after
// a delayed one later by the delay. The other records are as recorded.
FuzzedRecords fuzz_records(const FuzzRecording& recording, std::string_view plan);

// Writes the recording with `plan` applied as a plain .wtape session at
// `out`: the header as recorded (one channel), the plan's edits appended to
// its `edits`. Returns the plan's edits.
std::vector<std::string> write_fuzzed_session(const FuzzRecording& recording, std::string_view plan,
                                              const std::string& out);

}  // namespace wiretape::detail
