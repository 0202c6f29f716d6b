#include "replay/profile.hpp"

#include <mutex>
#include <stdexcept>
#include <utility>

#include "replay/profiles/builtin.hpp"
#include "replay/profiles/declared.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

namespace {

struct RegistryEntry {
  std::string_view name;
  std::shared_ptr<const Profile> (*make)();
};

// In the order listings show them: `scip` first (DESIGN.md section 13).
constexpr RegistryEntry registry[] = {
    {"scip", &make_scip_profile},
    {"lines", &make_default_lines_profile},
    {"nmea", &make_nmea_profile},
    {"slcan", &make_slcan_profile},
    {"modbus-rtu", &make_modbus_rtu_profile},
    {"modbus-tcp", &make_modbus_tcp_profile},
    {"mavlink", &make_mavlink_profile},
};

}  // namespace

std::string_view to_string(StreamDirection direction) {
  return direction == StreamDirection::tx ? "tx" : "rx";
}

}  // namespace wiretape::detail

namespace wiretape {

namespace {

struct Registered {
  std::string name;
  ProfileFactory make;
};

std::mutex& registered_mutex() {
  static std::mutex mutex;
  return mutex;
}

std::vector<Registered>& registered() {
  static std::vector<Registered> profiles;
  return profiles;
}

bool is_builtin(std::string_view name) {
  for (const detail::RegistryEntry& entry : detail::registry) {
    if (entry.name == name) return true;
  }
  return false;
}

}  // namespace

void register_profile(const std::string& name, ProfileFactory make) {
  if (name.empty()) throw std::invalid_argument("register_profile: the name is empty");
  if (is_builtin(name)) {
    throw std::invalid_argument("register_profile: '" + name +
                                "' is a built-in profile; choose another name");
  }
  if (!make) throw std::invalid_argument("register_profile: no factory for '" + name + "'");
  std::lock_guard<std::mutex> lock(registered_mutex());
  for (Registered& entry : registered()) {
    if (entry.name == name) {
      entry.make = std::move(make);
      return;
    }
  }
  registered().push_back({name, std::move(make)});
}

std::vector<std::string> profile_names() {
  std::vector<std::string> names;
  for (const detail::RegistryEntry& entry : detail::registry) names.emplace_back(entry.name);
  std::lock_guard<std::mutex> lock(registered_mutex());
  for (const Registered& entry : registered()) names.push_back(entry.name);
  return names;
}

std::shared_ptr<const Profile> find_profile(std::string_view name) {
  for (const detail::RegistryEntry& entry : detail::registry) {
    if (entry.name == name) return entry.make();
  }
  ProfileFactory make;
  {
    std::lock_guard<std::mutex> lock(registered_mutex());
    for (const Registered& entry : registered()) {
      if (entry.name == name) make = entry.make;
    }
  }
  if (make) {
    std::shared_ptr<const Profile> profile = make();
    if (profile) return profile;
  }
  std::string known;
  for (const std::string& each : profile_names()) {
    if (!known.empty()) known += ", ";
    known += each;
  }
  throw OptionError("profile", "option 'profile': unknown profile '" + std::string(name) +
                                   "': the profiles are " + known);
}

}  // namespace wiretape

namespace wiretape::detail {

std::optional<std::size_t> first_key_difference(const Profile& profile,
                                                std::string_view expected,
                                                std::string_view actual) {
  const std::string key = profile.match_key(actual);
  if (key == profile.match_key(expected)) return std::nullopt;
  const std::size_t limit = std::min(expected.size(), actual.size());
  for (std::size_t i = 0; i < limit; ++i) {
    if (expected[i] == actual[i]) continue;
    std::string probe(actual);
    probe[i] = expected[i];
    if (profile.match_key(probe) != key) return i;
  }
  return limit;
}

std::string differing_field_text(const Profile& profile, std::string_view expected,
                                 std::string_view actual) {
  const std::optional<std::size_t> at = first_key_difference(profile, expected, actual);
  if (!at) return {};
  const std::string field = profile.field_name(StreamDirection::tx, expected, *at);
  return field.empty() ? std::string() : ": its field '" + field + "' differs";
}

// --- TimedFramer ----------------------------------------------------------------

void TimedFramer::feed(std::uint64_t t_ns, std::string_view bytes,
                       std::vector<TimedFrame>& out) {
  const bool tail_began_earlier = framer_->pending() > 0;
  scratch_.clear();
  framer_->feed_at(t_ns, bytes, scratch_);
  for (std::size_t i = 0; i < scratch_.size(); ++i) {
    const bool began_earlier = i == 0 && tail_began_earlier;
    out.push_back({std::move(scratch_[i]), began_earlier ? tail_t_ns_ : t_ns});
  }
  if (framer_->pending() > 0 && !(scratch_.empty() && tail_began_earlier)) tail_t_ns_ = t_ns;
}

std::optional<TimedFramer::TimedFrame> TimedFramer::finish() {
  std::optional<Frame> tail = framer_->finish();
  if (!tail) return std::nullopt;
  return TimedFrame{std::move(*tail), tail_t_ns_};
}

// --- SessionDecoder -----------------------------------------------------------

SessionDecoder::SessionDecoder(std::shared_ptr<const Profile> profile)
    : profile_(std::move(profile)),
      tx_(profile_->make_framer(StreamDirection::tx)),
      rx_(profile_->make_framer(StreamDirection::rx)) {}

void SessionDecoder::feed(const Record& record, std::deque<DecodedItem>& out) {
  feed(record.t_ns, record.kind, record.data, out);
}

void SessionDecoder::feed(std::uint64_t t_ns, RecordKind kind, std::string_view data,
                          std::deque<DecodedItem>& out) {
  if (kind != RecordKind::tx && kind != RecordKind::rx) {
    DecodedItem item;
    item.t_ns = t_ns;
    item.kind = kind;
    item.bytes.assign(data.data(), data.size());
    out.push_back(std::move(item));
    return;
  }
  const StreamDirection direction =
      kind == RecordKind::tx ? StreamDirection::tx : StreamDirection::rx;
  TimedFramer& stream = direction == StreamDirection::tx ? tx_ : rx_;
  // A framer that cuts by silence: the other direction speaking ends its
  // frame (a device answers a whole request).
  TimedFramer& other = direction == StreamDirection::tx ? rx_ : tx_;
  if (other.framer().quiet_gap() && other.framer().pending() > 0) {
    if (std::optional<TimedFramer::TimedFrame> tail = other.finish()) {
      emit(direction == StreamDirection::tx ? StreamDirection::rx : StreamDirection::tx,
           tail->t_ns, std::move(tail->frame), out);
    }
  }
  frames_.clear();
  stream.feed(t_ns, data, frames_);
  for (TimedFramer::TimedFrame& frame : frames_) {
    emit(direction, frame.t_ns, std::move(frame.frame), out);
  }
}

void SessionDecoder::finish(std::deque<DecodedItem>& out) {
  for (StreamDirection direction : {StreamDirection::rx, StreamDirection::tx}) {
    TimedFramer& stream = direction == StreamDirection::tx ? tx_ : rx_;
    if (std::optional<TimedFramer::TimedFrame> tail = stream.finish()) {
      emit(direction, tail->t_ns, std::move(tail->frame), out);
    }
  }
}

void SessionDecoder::emit(StreamDirection direction, std::uint64_t t_ns, Frame frame,
                          std::deque<DecodedItem>& out) const {
  DecodedItem item;
  item.t_ns = t_ns;
  item.kind = direction == StreamDirection::tx ? RecordKind::tx : RecordKind::rx;
  item.description = profile_->describe(direction, frame.bytes);
  if (frame.end == FrameEnd::broken) {
    item.description = "BROKEN (" + frame.problem + "): " + item.description;
  }
  item.bytes = std::move(frame.bytes);
  item.is_frame = true;
  out.push_back(std::move(item));
}

std::shared_ptr<const Profile> take_profile(Options& options) {
  std::shared_ptr<const Profile> profile;
  if (const auto name = options.peek("profile")) {
    if (options.has("framing")) {
      throw OptionError("framing",
                        "options 'profile' and 'framing' both say how to frame the "
                        "session: give a built-in profile or a declared one, not both");
    }
    profile = find_profile(*name);
  }
  options.take_string("profile");
  if (auto declared = take_declared_profile(options)) profile = std::move(declared);
  return profile;
}

ProfileSpec profile_from_spec(std::string_view spec) {
  const auto first = spec.find_first_not_of(" \t\r\n");
  if (first == std::string_view::npos) {
    std::string names;
    for (const std::string& name : profile_names()) names += (names.empty() ? "" : ", ") + name;
    throw OptionError("profile", "the profile is empty; give a profile's name (" + names +
                                     ") or a declared profile (framing=...)");
  }
  const std::string_view text =
      spec.substr(first, spec.find_last_not_of(" \t\r\n") - first + 1);
  Options options;
  if (text.find('=') == std::string_view::npos) {
    options.set("profile", std::string(text));
  } else {
    options = Options::parse(text);
  }
  for (const Options::Entry& entry : options.entries()) {
    if (entry.key != "profile" && entry.key != "framing" && entry.key != "ignore" &&
        entry.key != "echo" && entry.key != "checksum") {
      throw OptionError(entry.key, "option '" + entry.key +
                                       "' is not a profile's key: a profile is a name "
                                       "(profile=NAME) or declared by framing=, ignore=, "
                                       "echo=, checksum=");
    }
  }
  ProfileSpec read;
  read.options = options.to_string();
  options.set_port_type("replay");
  read.profile = take_profile(options);
  return read;
}

}  // namespace wiretape::detail
