// The file a Recorder writes, shared by the recorder, its ports and its
// channels; and the single-port recording of `log=FILE`, which is a file of
// one unnamed channel (no `channels` member) owned by its port.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <set>
#include <string>

#include "wiretape/recorder.hpp"
#include "wiretape/session.hpp"

namespace wiretape::detail {

struct RecorderFile {
  RecorderFile(const std::string& path, const SessionHeader& header, FlushPolicy flush,
               std::size_t header_room)
      : writer(path, header, flush, header_room) {}

  SessionWriter writer;
  // steady_clock time of the first channel's open, in ns since its epoch;
  // 0 until then.
  std::atomic<std::int64_t> epoch_ns{0};
  std::atomic<bool> closed{false};
  // Names taken, including those of ports still being opened.
  std::mutex names_mutex;
  std::set<std::string> names;

  // Held from stamping a record to appending it (write_now).
  std::mutex stamp_mutex;

  // Guards the writer's header: add_channel() and reading it.
  mutable std::mutex header_mutex;

  std::uint16_t add_channel(Channel channel);
  // Starts the clock if no channel did yet; true if this call started it.
  bool start_clock();
  std::uint64_t now_ns() const;
  void close();
};

struct RecordingChannelAccess {
  static RecordingChannel make(std::shared_ptr<RecorderFile> file, std::uint16_t id,
                               std::string name) {
    return RecordingChannel(std::move(file), id, std::move(name));
  }
  static RecorderFile& file(const RecordingChannel& channel) { return *channel.file_; }
};

// The file of a `log=` recording: one unnamed channel (id 0), the clock
// started now, the header exactly as long as its JSON.
RecordingChannel single_channel_file(const std::string& path, const SessionHeader& header,
                                     FlushPolicy flush);

}  // namespace wiretape::detail
