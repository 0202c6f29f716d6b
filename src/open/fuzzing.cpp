// include/wiretape/fuzzing.hpp: the recording read once (replay/fuzz_session),
// each plan's records played by the replay engine as a type=replay of the
// file would play them (the config is the file's, the records the plan's).
#include "wiretape/fuzzing.hpp"

#include <chrono>
#include <utility>

#include "open/port_types.hpp"
#include "replay/fuzz_session.hpp"
#include "replay/replay_config.hpp"
#include "replay/replay_port.hpp"
#include "wiretape/options.hpp"
#include "wiretape/profile.hpp"

namespace wiretape {

struct FuzzedReplay::Impl {
  detail::FuzzRecording recording;
  detail::ReplayConfig config;
};

namespace {

// What in-process fuzzing replays with unless told otherwise: no waiting,
// and a driver that reads past the end learns it at once, not at its timeout.
constexpr std::pair<const char*, const char*> kFuzzingDefaults[] = {
    {"timing", "none"}, {"at_end", "closed"}, {"unused", "ignore"}};

}  // namespace

FuzzedReplay::FuzzedReplay(const std::string& session, const std::string& profile,
                           const std::string& replay_options)
    : impl_(std::make_unique<Impl>()) {
  Options options = Options::parse(replay_options);
  if (options.peek("type") == std::optional<std::string>("replay")) options.erase("type");
  options.set("file", session);
  for (const auto& [key, value] : kFuzzingDefaults)
    if (!options.has(key)) options.set(key, value);
  impl_->config = detail::replay_file_config(options, detail::datagram_port_types());
  options.finish("replay");
  // The fuzzed replay plays its one channel alone: the others are not in
  // the records it is given.
  impl_->config.several_channels = false;
  impl_->config.hub.reset();
  impl_->config.member.reset();
  std::shared_ptr<const Profile> found = profile.empty() ? nullptr : find_profile(profile);
  impl_->recording = detail::read_fuzz_recording(session, std::move(found), impl_->config.channel);
  bool recorded_flushes = false;
  for (const Record& record : impl_->recording.records)
    if (record.kind == RecordKind::flush_input || record.kind == RecordKind::flush_output) recorded_flushes = true;
  // The defaults play untimed: each run's reads then read no clock.
  impl_->config.untimed = detail::untimed_replay(impl_->config, recorded_flushes);
  impl_->recording.inert_delay_ms =
      static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::milliseconds>(impl_->config.tolerance).count());
}

FuzzedReplay::~FuzzedReplay() = default;
FuzzedReplay::FuzzedReplay(FuzzedReplay&&) noexcept = default;
FuzzedReplay& FuzzedReplay::operator=(FuzzedReplay&&) noexcept = default;

std::unique_ptr<Port> FuzzedReplay::open(std::string_view plan) const {
  detail::FuzzedRecords fuzzed = detail::fuzz_records(impl_->recording, plan);
  std::unique_ptr<Port> port =
      detail::open_replay_session(impl_->config, detail::vector_source_factory(std::move(fuzzed.records)));
  return port;
}

std::vector<std::string> FuzzedReplay::edits(std::string_view plan) const {
  return detail::fuzz_records(impl_->recording, plan).edits;
}

std::vector<std::string> FuzzedReplay::write(const std::string& path, std::string_view plan) const {
  return detail::write_fuzzed_session(impl_->recording, plan, path);
}

bool FuzzedReplay::inert(std::string_view plan) const {
  return detail::fuzz_records(impl_->recording, plan).inert;
}

std::size_t FuzzedReplay::units() const { return impl_->recording.units.size(); }

}  // namespace wiretape
