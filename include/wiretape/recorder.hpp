// Sessions of several ports (DESIGN §19): a Recorder writes one session
// file, and every port it opens (or channel it adds) records into its own
// channel of it, on the recorder's one clock.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

namespace wiretape {

namespace detail {
struct RecorderFile;
struct RecordingChannelAccess;
}  // namespace detail

// One channel of a recorder's file, for whoever records into it by hand
// (the proxy: a bridge records what crosses it). Copies share the channel;
// each keeps the file open. Thread-safe.
class RecordingChannel {
 public:
  // Appends a record of this channel. Throws PortError when the file cannot
  // be written or was closed (Recorder::close()).
  void write(RecordKind kind, std::uint64_t t_ns, std::string_view data);
  // Appends a record stamped with the recorder's clock as it enters the
  // file. The records of every channel written this way are in time order
  // across channels: two threads cannot stamp in one order and append in
  // the other. Throws as write().
  void write_now(RecordKind kind, std::string_view data);
  // The recorder's clock: ns since its first channel was opened.
  std::uint64_t now_ns() const;
  std::uint16_t id() const { return id_; }
  const std::string& name() const { return name_; }
  // The session file's path.
  const std::string& path() const;
  // Records of every channel in the file so far (SessionWriter::records_written).
  std::uint64_t records_written() const;
  // The file's first write failure, if any (SessionWriter::failure).
  std::optional<PortError> failure() const;
  // Whether the file was closed (Recorder::close()): later writes throw.
  bool file_closed() const;

 private:
  friend struct detail::RecordingChannelAccess;
  RecordingChannel(std::shared_ptr<detail::RecorderFile> file, std::uint16_t id,
                   std::string name);
  std::shared_ptr<detail::RecorderFile> file_;
  std::uint16_t id_ = 0;
  std::string name_;
};

// Records several ports into one session file (format 1.2, `channels`):
//
//   wiretape::Recorder recorder("run.wtape");
//   auto gps = recorder.open_port("name=gps,type=serial,device=/dev/ttyUSB0");
//   auto rtk = recorder.open_port("name=rtk,type=tcp,host=caster,port=2101");
//
// Time 0 is the first channel's open. The ports and channels keep the file
// open (shared ownership): it is closed when the recorder and the last of
// them are gone, or at close().
class Recorder {
 public:
  // Spare bytes of header kept for channels: enough for dozens of channels
  // with long option strings and device identities.
  static constexpr std::size_t default_header_room = 32 * 1024;

  // Creates the session file (SessionWriter's rules: PortError when it
  // cannot, OptionError naming the member of a header that cannot be
  // written). The header's port members are the first channel's, written
  // as channels are added.
  explicit Recorder(const std::string& path,
                    const SessionHeader& header = SessionHeader::starting_now(),
                    FlushPolicy flush = FlushPolicy{},
                    std::size_t header_room = default_header_room);
  ~Recorder();
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;
  Recorder(Recorder&&) noexcept;
  Recorder& operator=(Recorder&&) noexcept;

  // Opens the port the options describe and records it (capture=client)
  // into a new channel named by `name=NAME` (required; a channel name,
  // channel_name_problem; unique in the file). `log=` is refused: the port
  // records here. Throws OptionError naming the key, and what open_port()
  // throws; nothing is added to the file then.
  std::unique_ptr<Port> open_port(std::string_view options);
  std::unique_ptr<Port> open_port(Options options);
  // Adds a channel recorded by hand (the proxy). `channel.name` must be a
  // channel name not used yet; its id is assigned (the next one).
  RecordingChannel add_channel(Channel channel);
  // Flushes and closes the file; later records of its ports are dropped.
  // Throws PortError if the last data could not be written.
  void close();
  // The recorder's clock: ns since its first channel was opened (0 before).
  std::uint64_t now_ns() const;
  const std::string& path() const;
  // The header as written so far, channels included.
  SessionHeader header() const;

 private:
  std::shared_ptr<detail::RecorderFile> file_;
};

}  // namespace wiretape
