// Sessions of several ports: the Recorder (DESIGN §19), which opens each
// port through open_port and records it into a channel of its file. Its
// file and channels are src/session/recorder_file.cpp.
#include "wiretape/recorder.hpp"

#include "open/port_types.hpp"
#include "ports/ports.hpp"
#include "session/recorder_file.hpp"

namespace wiretape {

// --- Recorder ---------------------------------------------------------------------------

Recorder::Recorder(const std::string& path, const SessionHeader& header, FlushPolicy flush,
                   std::size_t header_room)
    : file_(std::make_shared<detail::RecorderFile>(path, header, flush, header_room)) {
  for (const Channel& channel : header.channels) file_->names.insert(channel.name);
}

Recorder::~Recorder() = default;
Recorder::Recorder(Recorder&&) noexcept = default;
Recorder& Recorder::operator=(Recorder&&) noexcept = default;

namespace {

// Takes `name` for a channel of `file`, or says why it cannot be one.
void reserve_name(detail::RecorderFile& file, const std::string& name) {
  if (const auto problem = channel_name_problem(name)) {
    throw OptionError("name", "option 'name': " + *problem);
  }
  std::lock_guard<std::mutex> lock(file.names_mutex);
  if (!file.names.insert(name).second) {
    throw OptionError("name", "option 'name': " + file.writer.path() +
                                  " already has a channel named \"" + name +
                                  "\"; each port of a recorder needs its own name");
  }
}

void release_name(detail::RecorderFile& file, const std::string& name) {
  std::lock_guard<std::mutex> lock(file.names_mutex);
  file.names.erase(name);
}

}  // namespace

std::unique_ptr<Port> Recorder::open_port(std::string_view options) {
  return open_port(Options::parse(options));
}

std::unique_ptr<Port> Recorder::open_port(Options options) {
  const std::optional<std::string> name = options.peek("name");
  options.erase("name");
  if (!name) {
    throw OptionError("name", "missing option 'name': a recorder's port records into a "
                              "channel of " + path() +
                              " named by name=NAME (e.g. \"name=gps,type=serial,"
                              "device=/dev/ttyUSB0\")");
  }
  if (options.has("log")) {
    throw OptionError("log", "option 'log' cannot be given to a recorder's port: it records "
                             "into " + path() + " (channel \"" + *name +
                             "\"); open it with wiretape::open_port to record it alone");
  }
  // flexiport's logging types record into their own file= (log= by another name).
  if (const auto type = options.peek("type")) {
    const detail::PortTypeAlias* alias = detail::find_port_type_alias(*type);
    if (alias != nullptr && alias->records_into_file) {
      throw OptionError("type", "type=" + *type + " records into its own file, and a "
                                "recorder's port records into " + path() + ": use type=" +
                                std::string(alias->type));
    }
  }
  reserve_name(*file_, *name);
  try {
    // The channel's options as the port was opened with them, without the
    // name, which the channel holds.
    const std::string given = options.to_string();
    std::unique_ptr<Port> port = wiretape::open_port(std::move(options));
    Channel channel;
    channel.name = *name;
    channel.port_options = given;
    channel.port_type = port->type();
    channel.capture = Capture::client;
    const std::uint16_t id = file_->add_channel(std::move(channel));
    const bool first = file_->start_clock();
    return detail::record_port_into(
        std::move(port), detail::RecordingChannelAccess::make(file_, id, *name),
        detail::RecordingTarget{/*owns_file=*/false, /*raise_errors=*/true, first});
  } catch (...) {
    release_name(*file_, *name);
    throw;
  }
}

RecordingChannel Recorder::add_channel(Channel channel) {
  const std::string name = channel.name;
  reserve_name(*file_, name);
  try {
    const std::uint16_t id = file_->add_channel(std::move(channel));
    file_->start_clock();
    return detail::RecordingChannelAccess::make(file_, id, name);
  } catch (...) {
    release_name(*file_, name);
    throw;
  }
}

void Recorder::close() { file_->close(); }
std::uint64_t Recorder::now_ns() const { return file_->now_ns(); }
const std::string& Recorder::path() const { return file_->writer.path(); }

SessionHeader Recorder::header() const {
  std::lock_guard<std::mutex> lock(file_->header_mutex);
  return file_->writer.header();
}

}  // namespace wiretape
