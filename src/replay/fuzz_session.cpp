#include "replay/fuzz_session.hpp"

#include <cstddef>
#include <utility>

#include "replay/replay_config.hpp"
#include "replay/replay_port.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {
namespace {

constexpr std::uint64_t kNsPerMs = 1000000;

// Why `profile` does not fit `units` (the recording's rx records), or empty.
std::string profile_misfit(const Profile& profile, const std::vector<RxRecord>& records) {
  std::vector<FrameEnd> ends;
  rx_frames(profile, records, &ends);
  std::size_t whole = 0;
  std::size_t broken = 0;
  for (FrameEnd end : ends) {
    if (end == FrameEnd::delimited) ++whole;
    if (end == FrameEnd::broken || end == FrameEnd::size_limit) ++broken;
  }
  if (whole == 0)
    return "its rx framer finds no whole frame in the device's bytes (" + std::to_string(ends.size()) +
           " pieces, none ended as the protocol ends a frame)";
  if (broken > whole)
    return "its rx framer finds more broken frames (" + std::to_string(broken) + ") than whole ones (" +
           std::to_string(whole) + ") in the device's bytes";
  return {};
}

// Whether the frames a plan of flips, boundary values, splits and delays
// made differ from the recorded ones only in bytes `profile` leaves out of
// matching (Profile::match_key: a transaction id the replay takes from the
// request, a sequence number): a driver has no right to fail on those. The
// split frames are joined again, frame by frame, to compare.
bool only_unmatched_bytes_changed(const Profile& profile, const std::vector<RxRecord>& recorded,
                                  const std::vector<RxRecord>& mutated) {
  std::size_t next = 0;
  for (const RxRecord& frame : recorded) {
    std::string bytes;
    while (bytes.size() < frame.bytes.size() && next < mutated.size()) bytes += mutated[next++].bytes;
    if (bytes.size() != frame.bytes.size()) return false;
    if (bytes != frame.bytes && profile.match_key(bytes) != profile.match_key(frame.bytes)) return false;
  }
  return next == mutated.size();
}

}  // namespace

FuzzRecording read_fuzz_recording(const std::string& path, std::shared_ptr<const Profile> profile,
                                  const std::string& channel) {
  FuzzRecording recording;
  recording.path = path;
  recording.profile = std::move(profile);
  {
    SessionReader all(path);
    recording.header = all.header();
  }
  ReplayConfig chosen;
  chosen.file = path;
  chosen.channel = channel;
  recording.channel = choose_channel(chosen, recording.header);
  SessionReader reader(path, recording.channel.id);
  std::vector<RxRecord> rx;
  std::size_t rx_bytes = 0;
  for (Record record; reader.next(record);) {
    if (record.kind == RecordKind::rx) {
      rx.push_back({record.data, 0, recording.records.size()});
      rx_bytes += record.data.size();
    }
    recording.records.push_back(std::move(record));
  }
  if (rx_bytes == 0)
    throw SessionError(path + ": the session has no device bytes (no rx data" +
                       (recording.header.channel_list().size() > 1 ? " on channel " + recording.channel.name
                                                                   : std::string()) +
                       "): a fuzzing plan mutates what the device sent, and there is nothing to mutate",
                       0);
  if (recording.profile) {
    const std::string misfit = profile_misfit(*recording.profile, rx);
    if (!misfit.empty())
      throw OptionError("profile", "profile '" + std::string(recording.profile->name()) +
                                       "' does not fit " + path + ": " + misfit);
    recording.units = rx_frames(*recording.profile, rx);
  } else {
    recording.units = std::move(rx);
  }
  return recording;
}

FuzzedRecords fuzz_records(const FuzzRecording& recording, std::string_view plan) {
  // The units are already cut (frames, with a profile); the steps act on a
  // copy of them, as apply_plan does on records.
  MutatedRx mutated = recording.profile ? apply_plan_to_frames(*recording.profile, recording.units, plan)
                                        : apply_plan(recording.units, plan);
  FuzzedRecords out;
  out.edits = std::move(mutated.edits);
  std::uint64_t delayed_ms = 0;
  for (const RxRecord& unit : mutated.records) delayed_ms += unit.delay_ms;
  bool changed_bytes = false;
  for (MutationKind kind : mutated.kinds) {
    if (kind == MutationKind::flip || kind == MutationKind::boundary)
      changed_bytes = true;
    else if (kind != MutationKind::split && kind != MutationKind::delay)
      out.inert = false;
  }
  if (changed_bytes && out.inert)
    out.inert = recording.profile && only_unmatched_bytes_changed(*recording.profile, recording.units,
                                                                   mutated.records);
  if (delayed_ms > recording.inert_delay_ms) out.inert = false;
  out.records.reserve(recording.records.size() + mutated.records.size());
  std::size_t next_unit = 0;
  std::uint64_t shift_ns = 0;  // what the delays so far add to every later record
  auto& units = mutated.records;  // moved from: they are this call's own
  for (std::size_t place = 0; place < recording.records.size(); ++place) {
    const Record& recorded = recording.records[place];
    if (recorded.kind != RecordKind::rx) {
      out.records.push_back(recorded);
      out.records.back().t_ns += shift_ns;
      continue;
    }
    // Units keep the order of their places (fuzz_plan.hpp, RxRecord::place).
    for (; next_unit < units.size() && units[next_unit].place == place; ++next_unit) {
      shift_ns += units[next_unit].delay_ms * kNsPerMs;
      out.records.push_back(
          {recorded.t_ns + shift_ns, RecordKind::rx, std::move(units[next_unit].bytes), recorded.channel});
    }
  }
  return out;
}

std::vector<std::string> write_fuzzed_session(const FuzzRecording& recording, std::string_view plan,
                                              const std::string& out) {
  FuzzedRecords fuzzed = fuzz_records(recording, plan);
  SessionHeader header = recording.header;
  if (header.channel_list().size() > 1) header.channels = {recording.channel};
  header.edits.insert(header.edits.end(), fuzzed.edits.begin(), fuzzed.edits.end());
  SessionWriter writer(out, header);
  for (const Record& record : fuzzed.records) writer.write(record);
  writer.close();
  return std::move(fuzzed.edits);
}

}  // namespace wiretape::detail
