// A session file opened for replay (type=replay): its records of one
// channel, the channel chosen, the client's tx of a channel for the causal
// order across channels. The replaying port itself is replay_port.cpp.
#include <algorithm>
#include <cstdio>

#include "replay/channel_hub.hpp"
#include "replay/faults.hpp"
#include "replay/replay_port.hpp"
#include "session/reader.hpp"
#include "session/record_kinds.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"
#include "wiretape/session.hpp"

namespace wiretape::detail {

namespace {

// A session file's records of one channel; damage ends them with one
// warning on stderr (shared by the sources of one replay).
class SessionRecordSource final : public RecordSource {
 public:
  SessionRecordSource(const std::string& path, std::uint16_t channel,
                      std::shared_ptr<bool> warned)
      : path_(path), source_(open_session_source(path, header_, Streams::refused, channel)),
        warned_(std::move(warned)) {}
  bool next(Record& record) override {
    if (source_->next(record)) return true;
    warn_of_damage();
    return false;
  }
  bool next(Record& record, PayloadView& view) override {
    // Views only where they pin this channel's bytes (the reader decides).
    if (source_->next(record, view)) return true;
    warn_of_damage();
    return false;
  }
  void rewind() override { source_->rewind(); }
  const std::optional<SessionError>& damage() const override {
    return source_->damage();
  }
  const std::optional<SessionError>& unfinished() const override {
    return source_->unfinished();
  }

 private:
  void warn_of_damage() {
    if (source_->damage() && !*warned_) {
      *warned_ = true;
      std::fprintf(stderr,
                   "wiretape: %s is damaged; replaying what comes before the "
                   "damage: %s\n",
                   path_.c_str(), source_->damage()->what());
    } else if (source_->unfinished() && !*warned_) {
      *warned_ = true;  // not damage: a recorder is still writing the file
      std::fprintf(stderr, "wiretape: warning: %s; replaying what was written\n",
                   source_->unfinished()->what());
    }
  }

  std::string path_;
  SessionHeader header_;
  std::unique_ptr<RecordSource> source_;
  std::shared_ptr<bool> warned_;
};

// The names of `channels`, for messages: "gps, rtk".
std::string channel_names(const std::vector<Channel>& channels) {
  std::string names;
  for (const Channel& channel : channels) {
    names += (names.empty() ? "" : ", ") + channel.name;
  }
  return names;
}

// The client's tx recorded on `channel` of the file at `path`, for the
// causal order across channels.
std::vector<ChannelHub::TxMark> recorded_tx(const std::string& path, std::uint16_t channel) {
  std::vector<ChannelHub::TxMark> marks;
  SessionHeader header;
  const std::unique_ptr<RecordSource> source =
      open_session_source(path, header, Streams::refused, channel);
  Record record;
  PayloadView view;
  std::uint64_t offset = 0;
  while (source->next(record, view)) {
    if (record.kind != RecordKind::tx) continue;
    const std::size_t size = view ? view.bytes.size() : record.data.size();
    if (size == 0) continue;  // an empty datagram moves no byte count
    offset += size;
    marks.push_back({offset, record.t_ns});
  }
  return marks;
}

}  // namespace

Channel choose_channel(const ReplayConfig& config, const SessionHeader& header) {
  const std::vector<Channel> channels = header.channel_list();
  const bool named = !header.channels.empty();
  if (config.channel.empty()) {
    if (channels.size() > 1) {
      throw OptionError("channel", "option 'channel' is required: " + config.file +
                                       " is a session of several ports (channels: " +
                                       channel_names(channels) +
                                       "); give channel=NAME");
    }
    return channels.front();
  }
  if (!named) {
    throw OptionError("channel", "option 'channel=" + config.channel + "': " + config.file +
                                     " has one channel and it is not named (none named); "
                                     "leave channel= out");
  }
  if (const std::optional<Channel> found = header.find_channel(config.channel)) return *found;
  std::vector<std::string> names;
  for (const Channel& channel : channels) names.push_back(channel.name);
  const std::optional<std::string> near = nearest_name(config.channel, names);
  throw OptionError("channel", "option 'channel': " + config.file + " has no channel '" +
                                   config.channel + "'" +
                                   (near ? "; did you mean '" + *near + "'?" : std::string()) +
                                   " (channels: " + channel_names(channels) + ")");
}

RecordSourceFactory session_source_factory(const std::string& path, std::uint16_t channel) {
  auto warned = std::make_shared<bool>(false);
  return [path, channel, warned] {
    return std::make_unique<SessionRecordSource>(path, channel, warned);
  };
}

bool recorded_as_datagrams(const Channel& channel, const DatagramPortTypes& datagram_types) {
  return std::find(datagram_types.begin(), datagram_types.end(), channel.port_type) !=
         datagram_types.end();
}

SerialSettings recorded_line_settings(const std::string& port_options) {
  SerialSettings settings;
  std::vector<Options::Entry> entries;
  try {
    entries = parse_options(port_options);
  } catch (const OptionError&) {
    return settings;
  }
  for (const Options::Entry& entry : entries) {
    const bool digits = !entry.value.empty() && entry.value.size() <= 9 &&
                        entry.value.find_first_not_of("0123456789") == std::string::npos;
    const unsigned long number = digits ? std::stoul(entry.value) : 0;
    if (entry.key == "baud" && number > 0) {
      settings.baud = static_cast<unsigned>(number);
    } else if (entry.key == "databits" && number >= 5 && number <= 8) {
      settings.data_bits = static_cast<int>(number);
    } else if (entry.key == "stopbits" && (number == 1 || number == 2)) {
      settings.stop_bits = static_cast<int>(number);
    } else if (entry.key == "parity") {
      settings.parity = parse_parity(entry.value).value_or(settings.parity);
    } else if (entry.key == "flow") {
      settings.flow = parse_flow_control(entry.value).value_or(settings.flow);
    }
  }
  return settings;
}

ReplayConfig replay_file_config(Options& options, const DatagramPortTypes& datagram_types) {
  ReplayConfig config = take_replay_config(options);
  // The file is opened here once, so that a missing or unreadable session
  // fails at open with the reason. Not as a SessionReader, which would wait
  // on a FIFO: a replay reads its session again and again, so a FIFO is
  // refused at once.
  {
    SessionHeader header;
    open_session_source(config.file, header, Streams::refused);
    const Channel channel = choose_channel(config, header);
    config.channel_id = channel.id;
    config.channel = channel.name;
    config.datagrams = recorded_as_datagrams(channel, datagram_types);
    config.recorded_settings = recorded_line_settings(channel.port_options);
    std::vector<std::string> names;
    for (const Channel& each : header.channel_list()) names.push_back(each.name);
    config.faults = faults_for_channel(config.faults, channel.name, names, config.file);
    config.several_channels = header.channel_list().size() > 1;
    if (config.several_channels) {
      config.hub = ChannelHub::of_file(config.file);
      if (config.timing == ReplayTiming::causal) {
        config.member = config.hub->join(channel.id, recorded_tx(config.file, channel.id));
      }
    }
  }
  return config;
}

std::unique_ptr<Port> open_replay(Options& options, const DatagramPortTypes& datagram_types) {
  ReplayConfig config = replay_file_config(options, datagram_types);
  RecordSourceFactory sources = session_source_factory(config.file, config.channel_id);
  return open_replay_session(std::move(config), std::move(sources));
}

}  // namespace wiretape::detail
