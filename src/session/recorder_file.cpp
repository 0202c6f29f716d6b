// The file a Recorder writes (RecorderFile: writer, one clock, names) and
// its channels (DESIGN §19). The Recorder itself, which opens ports, is
// above the port folders, in src/open/recorder.cpp.
#include "session/recorder_file.hpp"

#include <algorithm>

namespace wiretape {

namespace detail {

namespace {

std::int64_t steady_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

bool RecorderFile::start_clock() {
  std::int64_t unset = 0;
  // A steady clock of exactly 0 is taken as 1 ns: 0 means "not started".
  const std::int64_t now = std::max<std::int64_t>(steady_now_ns(), 1);
  return epoch_ns.compare_exchange_strong(unset, now);
}

std::uint64_t RecorderFile::now_ns() const {
  const std::int64_t epoch = epoch_ns.load();
  if (epoch == 0) return 0;
  const std::int64_t elapsed = steady_now_ns() - epoch;
  return elapsed > 0 ? static_cast<std::uint64_t>(elapsed) : 0;
}

std::uint16_t RecorderFile::add_channel(Channel channel) {
  std::lock_guard<std::mutex> lock(header_mutex);
  return writer.add_channel(std::move(channel));
}

void RecorderFile::close() {
  closed.store(true);
  writer.close();
}

RecordingChannel single_channel_file(const std::string& path, const SessionHeader& header,
                                     FlushPolicy flush) {
  auto file = std::make_shared<RecorderFile>(path, header, flush, 0);
  file->start_clock();
  return RecordingChannelAccess::make(std::move(file), 0, "");
}

}  // namespace detail

// --- RecordingChannel -----------------------------------------------------------------

RecordingChannel::RecordingChannel(std::shared_ptr<detail::RecorderFile> file, std::uint16_t id,
                                   std::string name)
    : file_(std::move(file)), id_(id), name_(std::move(name)) {}

void RecordingChannel::write(RecordKind kind, std::uint64_t t_ns, std::string_view data) {
  file_->writer.write(kind, t_ns, data, id_);
}

void RecordingChannel::write_now(RecordKind kind, std::string_view data) {
  std::lock_guard<std::mutex> lock(file_->stamp_mutex);
  file_->writer.write(kind, file_->now_ns(), data, id_);
}

std::uint64_t RecordingChannel::now_ns() const { return file_->now_ns(); }
const std::string& RecordingChannel::path() const { return file_->writer.path(); }
std::uint64_t RecordingChannel::records_written() const {
  return file_->writer.records_written();
}
std::optional<PortError> RecordingChannel::failure() const { return file_->writer.failure(); }
bool RecordingChannel::file_closed() const { return file_->closed.load(); }

}  // namespace wiretape
