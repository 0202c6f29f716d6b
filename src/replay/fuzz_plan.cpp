#include "replay/fuzz_plan.hpp"

#include <array>
#include <cstdio>
#include <memory>
#include <optional>
#include <utility>

#include "wiretape/profile.hpp"

namespace wiretape::detail {
namespace {

constexpr std::array<std::uint8_t, 6> kBoundaryBytes = {0x00, 0x01, 0x7f, 0x80, 0xfe, 0xff};
// A delay step adds amount * this: up to 2.55 s, past any driver's timeout.
constexpr std::uint64_t kDelayStepMs = 10;
// A split's tail comes this much after its head, so that a reader across a
// pty or a socket sees two reads, not the one the kernel would merge them into.
constexpr std::uint64_t kSplitGapMs = 10;

std::string hex_byte(std::uint8_t value) {
  char text[8];
  std::snprintf(text, sizeof text, "0x%02x", value);
  return text;
}

// What the steps act on: rx records, or with a profile its rx frames, whose
// checksums are recomputed after a byte in them changes.
struct Units {
  const Profile* profile = nullptr;
  const char* noun() const { return profile ? "rx frame " : "rx record "; }
};

// Records one change: its line for `edits`, its kind beside it.
void say(MutatedRx& out, MutationKind kind, std::string edit) {
  out.edits.push_back(std::move(edit));
  out.kinds.push_back(kind);
}

// Sets one byte (the frame's checksums recomputed) and says so, by the
// profile's field name where it has one; nothing when the frame is unchanged.
void set_byte(MutatedRx& out, const Units& units, MutationKind kind, std::size_t index, std::size_t offset, std::uint8_t value) {
  auto& bytes = out.records[index].bytes;
  const std::string original = bytes;
  const auto before = static_cast<std::uint8_t>(bytes[offset]);
  bytes[offset] = static_cast<char>(value);
  std::string where = " byte " + std::to_string(offset);
  if (units.profile) {
    bytes = units.profile->recompute_checksums(StreamDirection::rx, bytes);
    const std::string field = units.profile->field_name(StreamDirection::rx, bytes, offset);
    if (!field.empty()) where = " field " + field;
  }
  if (bytes == original) return;
  say(out, kind, units.noun() + std::to_string(index) + where + ": " + hex_byte(before) + " → " +
                      hex_byte(value));
}

void apply_step(MutatedRx& out, const Units& units, const PlanStep& step) {
  auto& records = out.records;
  if (records.empty()) return;
  const std::size_t index = step.record % records.size();
  auto& record = records[index];
  const std::size_t size = record.bytes.size();
  const auto record_name = [&](std::size_t i) { return units.noun() + std::to_string(i); };
  const std::string name = record_name(index);
  switch (step.kind) {
    case MutationKind::flip:
      if (size == 0) return;
      set_byte(out, units, step.kind, index, step.offset % size,
               static_cast<std::uint8_t>(record.bytes[step.offset % size] ^ (1u << (step.amount % 8))));
      return;
    case MutationKind::boundary:
      if (size == 0) return;
      set_byte(out, units, step.kind, index, step.offset % size, kBoundaryBytes[step.amount % kBoundaryBytes.size()]);
      return;
    case MutationKind::truncate: {
      if (size == 0) return;
      const std::size_t keep = step.offset % size;
      record.bytes.resize(keep);
      say(out, step.kind, name + " truncated: " + std::to_string(size) + " → " + std::to_string(keep) + " bytes");
      return;
    }
    case MutationKind::extend: {
      const std::size_t count = step.offset % 16 + 1;
      record.bytes.append(count, static_cast<char>(step.amount));
      say(out, step.kind, name + " extended by " + std::to_string(count) + " bytes of " + hex_byte(step.amount));
      return;
    }
    case MutationKind::duplicate: {
      RxRecord copy = record;
      records.insert(records.begin() + static_cast<std::ptrdiff_t>(index) + 1, std::move(copy));
      say(out, step.kind, name + " duplicated");
      return;
    }
    case MutationKind::drop:
      records.erase(records.begin() + static_cast<std::ptrdiff_t>(index));
      say(out, step.kind, name + " dropped");
      return;
    case MutationKind::reorder: {
      if (records.size() < 2) return;
      const std::size_t next = (index + 1) % records.size();
      std::swap(records[index], records[next]);
      std::swap(records[index].place, records[next].place);  // the places keep their order
      say(out, step.kind, name + " swapped with " + record_name(next));
      return;
    }
    case MutationKind::split: {
      if (size < 2) return;
      const std::size_t at = step.offset % (size - 1) + 1;
      RxRecord tail{record.bytes.substr(at), kSplitGapMs, record.place};
      record.bytes.resize(at);
      records.insert(records.begin() + static_cast<std::ptrdiff_t>(index) + 1, std::move(tail));
      say(out, step.kind, name + " split across reads at byte " + std::to_string(at) + ", " +
                              std::to_string(kSplitGapMs) + " ms apart");
      return;
    }
    case MutationKind::delay: {
      const std::uint64_t ms = (static_cast<std::uint64_t>(step.amount) + 1) * kDelayStepMs;
      record.delay_ms += ms;
      say(out, step.kind, name + " delayed by " + std::to_string(ms) + " ms");
      return;
    }
  }
}

}  // namespace

const char* mutation_kind_name(MutationKind kind) {
  switch (kind) {
    case MutationKind::flip: return "flip";
    case MutationKind::boundary: return "boundary";
    case MutationKind::truncate: return "truncate";
    case MutationKind::extend: return "extend";
    case MutationKind::duplicate: return "duplicate";
    case MutationKind::drop: return "drop";
    case MutationKind::reorder: return "reorder";
    case MutationKind::split: return "split";
    case MutationKind::delay: return "delay";
  }
  return "?";
}

std::vector<PlanStep> decode_plan(std::string_view plan) {
  std::vector<PlanStep> steps;
  steps.reserve(plan.size() / kPlanStepBytes);
  for (std::size_t at = 0; at + kPlanStepBytes <= plan.size(); at += kPlanStepBytes) {
    const auto byte = [&](std::size_t i) { return static_cast<std::uint8_t>(plan[at + i]); };
    steps.push_back({static_cast<MutationKind>(byte(0) % kMutationKindCount), byte(1), byte(2), byte(3)});
  }
  return steps;
}

MutatedRx apply_plan(std::vector<RxRecord> records, std::string_view plan) {
  MutatedRx out{std::move(records), {}};
  for (const PlanStep& step : decode_plan(plan)) apply_step(out, Units{}, step);
  return out;
}

std::vector<RxRecord> rx_frames(const Profile& profile, const std::vector<RxRecord>& records,
                                std::vector<FrameEnd>* ends) {
  const std::unique_ptr<Framer> framer = profile.make_framer(StreamDirection::rx);
  std::vector<RxRecord> out;
  std::vector<Frame> frames;
  for (const RxRecord& record : records) {
    framer->feed(record.bytes, frames);
    for (Frame& frame : frames) {
      if (ends) ends->push_back(frame.end);
      out.push_back({std::move(frame.bytes), 0, record.place});
    }
    frames.clear();
  }
  if (std::optional<Frame> tail = framer->finish()) {
    if (ends) ends->push_back(tail->end);
    out.push_back({std::move(tail->bytes), 0, records.empty() ? 0 : records.back().place});
  }
  return out;
}

MutatedRx apply_plan(const Profile& profile, const std::vector<RxRecord>& records, std::string_view plan) {
  return apply_plan_to_frames(profile, rx_frames(profile, records), plan);
}

MutatedRx apply_plan_to_frames(const Profile& profile, std::vector<RxRecord> frames, std::string_view plan) {
  MutatedRx out{std::move(frames), {}};
  const Units units{&profile};
  for (const PlanStep& step : decode_plan(plan)) apply_step(out, units, step);
  return out;
}

}  // namespace wiretape::detail
