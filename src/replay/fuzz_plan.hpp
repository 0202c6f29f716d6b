// Fuzzing plans (DESIGN.md section 27), first step: the plan over rx records,
// for a recording replayed without a profile. A plan is a compact byte
// string a fuzzer (libFuzzer, atheris, AFL++) mutates; it decodes into a list
// of mutations of the device's side. Decoding never fails: any byte string
// is a plan, a trailing partial step is ignored, and an empty plan leaves
// the recording unchanged, so every input a fuzzer produces is a valid replay.
//
// A plan is read four bytes a step: [operation, record, offset, amount], each
// taken modulo what it indexes at the time the step applies (records drop
// and split as earlier steps apply), so a step never points outside.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace wiretape {
class Profile;
enum class FrameEnd;
}

namespace wiretape::detail {

enum class MutationKind {
  flip,       // one bit of one byte
  boundary,   // one byte set to a boundary value (0x00 0x01 0x7f 0x80 0xfe 0xff)
  truncate,   // the record ends early
  extend,     // bytes appended to the record
  duplicate,  // the record sent twice
  drop,       // the record never sent
  reorder,    // the record swapped with the next one
  split,      // the record arrives in two reads
  delay,      // the record comes later
};

inline constexpr std::size_t kPlanStepBytes = 4;
inline constexpr std::size_t kMutationKindCount = 9;

const char* mutation_kind_name(MutationKind kind);

struct PlanStep {
  MutationKind kind;
  std::uint8_t record;
  std::uint8_t offset;
  std::uint8_t amount;
};

// Every whole step of `plan`, in order.
std::vector<PlanStep> decode_plan(std::string_view plan);

// One rx record of the device side as a replay serves it.
struct RxRecord {
  std::string bytes;
  std::uint64_t delay_ms = 0;  // added before it is served
  // Where in the session it is served: the index of the recorded record it
  // came from (for a frame, the record its last byte was in). A reorder
  // swaps what two places serve, so this stays with the place; a duplicate
  // or a split's tail is served at the place of what it came from.
  std::size_t place = 0;
};

struct MutatedRx {
  std::vector<RxRecord> records;
  // One line per step that changed something, in words
  // ("rx record 1 byte 3: 0x04 → 0x2c"), for the session header's `edits`.
  std::vector<std::string> edits;
  std::vector<MutationKind> kinds;  // what made each edit, in step
};

// `records` with the plan's steps applied in order. A step with nothing to
// act on (no records left, a one-byte record to split) changes nothing and
// says nothing.
MutatedRx apply_plan(std::vector<RxRecord> records, std::string_view plan);

// The rx stream of `records` cut into frames by `profile`'s rx framer, one
// record a frame (an incomplete tail is a frame of its own). `ends`, when
// given, receives why each frame ended (whether the profile fits).
std::vector<RxRecord> rx_frames(const Profile& profile, const std::vector<RxRecord>& records,
                                std::vector<FrameEnd>* ends = nullptr);

// With a profile the steps act on its rx frames (rx_frames), "rx frame N"
// in the edits, a changed byte named by the profile's field where it has
// one; a frame whose byte changed has its checksums recomputed
// (Profile::recompute_checksums), so that it reaches the driver's parser.
MutatedRx apply_plan(const Profile& profile, const std::vector<RxRecord>& records, std::string_view plan);
// The same on frames already cut by rx_frames (a recording fuzzed many
// times is cut once).
MutatedRx apply_plan_to_frames(const Profile& profile, std::vector<RxRecord> frames, std::string_view plan);

}  // namespace wiretape::detail
