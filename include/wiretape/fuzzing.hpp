// Fuzzing a driver in process from its recording (DESIGN.md section 27).
//
// A recording is read once; each fuzzer input is a *plan* (docs/fuzzing.md):
// any byte string, decoded into mutations of what the device sent (with a
// profile: on its frames and fields, checksums recomputed). open(plan) gives
// a replay Port of the recording so mutated, for the driver to read from:
//
//   static const wiretape::FuzzedReplay replay("scan.wtape", "scip");
//   extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
//     auto port = replay.open(data, size);
//     try { MyDriver(*port).run(); } catch (const std::exception&) {}
//     return 0;
//   }
//
// Every plan is a valid replay, and a plan of length zero replays the
// recording unchanged. A finding is written with write(path, plan) as a plain
// .wtape session (the mutation in its header's `edits`) that `wiretape
// replay` plays to the driver with no fuzzer installed.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "wiretape/port.hpp"

namespace wiretape {

class FuzzedReplay {
 public:
  // `session`: the recording (.wtape or a flexiport log pair). `profile`: a
  // profile name as `profile=` takes it (built-in or registered), whose
  // frames the plans mutate; empty: plans act on rx records. `replay_options`:
  // replay keys (`channel=NAME`, `match=request`, ...) over the fuzzing
  // defaults `timing=none,at_end=closed,unused=ignore` (no waiting; a read
  // past the recording's end raises PortClosed at once). Throws OptionError
  // for bad options or a profile that does not fit the recording (its
  // framer finds no whole frame), SessionError for a session with no device
  // bytes (or a damaged one), PortError for one that cannot be opened.
  explicit FuzzedReplay(const std::string& session, const std::string& profile = "",
                        const std::string& replay_options = "");
  ~FuzzedReplay();
  FuzzedReplay(FuzzedReplay&&) noexcept;
  FuzzedReplay& operator=(FuzzedReplay&&) noexcept;

  // A replay of the recording mutated by `plan`. Thread-safe: each port is
  // its own.
  std::unique_ptr<Port> open(std::string_view plan) const;
  std::unique_ptr<Port> open(const std::uint8_t* plan, std::size_t size) const {
    return open(std::string_view(reinterpret_cast<const char*>(plan), size));
  }
  // What `plan` changes, one line a change ("rx frame 1 field len: 0x04 →
  // 0x2c"); empty for a plan that changes nothing.
  std::vector<std::string> edits(std::string_view plan) const;
  // Writes the recording mutated by `plan` as a plain .wtape session at
  // `path`, the edits appended to its header's `edits`; returns the edits.
  std::vector<std::string> write(const std::string& path, std::string_view plan) const;
  // Whether `plan` changes nothing a driver may refuse: it only changes
  // bytes the profile leaves out of matching, splits frames across reads or
  // delays them within the replay's tolerance (100 ms unless tolerance=
  // says otherwise). A driver failing on an inert
  // plan, even with a clean error, has a finding (DESIGN.md section 27).
  bool inert(std::string_view plan) const;
  // How many rx frames (with a profile) or rx records a plan's steps index.
  std::size_t units() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace wiretape
