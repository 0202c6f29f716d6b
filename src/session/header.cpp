#include "session/header.hpp"

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <ctime>
#include <optional>
#include <string_view>

#include "util/hex.hpp"
#include "util/json.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"
#include "wiretape/version.hpp"

namespace wiretape::detail {

std::string utc_now_iso8601() {
  const auto now = std::chrono::system_clock::now();
  const auto since_epoch = now.time_since_epoch();
  const auto seconds = std::chrono::duration_cast<std::chrono::seconds>(since_epoch);
  const auto micros =
      std::chrono::duration_cast<std::chrono::microseconds>(since_epoch - seconds);
  const std::time_t t = static_cast<std::time_t>(seconds.count());
  std::tm parts{};
  gmtime_r(&t, &parts);
  char text[64];
  std::snprintf(text, sizeof text, "%04d-%02d-%02dT%02d:%02d:%02d.%06lldZ",
                parts.tm_year + 1900, parts.tm_mon + 1, parts.tm_mday,
                parts.tm_hour, parts.tm_min, parts.tm_sec,
                static_cast<long long>(micros.count()));
  return text;
}

std::string host_name() {
  char name[256] = {};
  if (gethostname(name, sizeof name - 1) != 0) return "";
  return name;
}

namespace {

// A header string as it may appear in an error message: in quotes and
// escaped as payload bytes are, so that a hostile file cannot send control
// sequences to a terminal through it.
std::string quoted(std::string_view text) {
  return "\"" + escape_bytes(text, text.size()) + "\"";
}

bool digits_at(std::string_view text, std::size_t at, std::size_t count) {
  if (text.size() < at + count) return false;
  for (std::size_t i = at; i < at + count; ++i) {
    if (text[i] < '0' || text[i] > '9') return false;
  }
  return true;
}

int number_at(std::string_view text, std::size_t at, std::size_t count) {
  int value = 0;
  for (std::size_t i = at; i < at + count; ++i) value = value * 10 + (text[i] - '0');
  return value;
}

// Throws OptionError naming `field` when `value` is not valid UTF-8, which
// the header's JSON must be.
void require_utf8(const std::string& field, std::string_view value) {
  if (const auto bad = json::invalid_utf8_offset(value)) {
    throw OptionError(field, "the session header's " + field +
                                 " is not valid UTF-8 (byte " + std::to_string(*bad) +
                                 " of " + quoted(value) + ")");
  }
}

}  // namespace

std::optional<std::string> start_utc_problem(std::string_view text) {
  if (text.empty()) return std::nullopt;  // not known (imported sessions)
  // YYYY-MM-DDTHH:MM:SS, then an optional fraction, then Z.
  const bool shaped = digits_at(text, 0, 4) && text.size() > 19 && text[4] == '-' &&
                      digits_at(text, 5, 2) && text[7] == '-' && digits_at(text, 8, 2) &&
                      text[10] == 'T' && digits_at(text, 11, 2) && text[13] == ':' &&
                      digits_at(text, 14, 2) && text[16] == ':' && digits_at(text, 17, 2);
  std::size_t end = 19;
  if (shaped && text[end] == '.') {
    const std::size_t fraction = ++end;
    while (end < text.size() && text[end] >= '0' && text[end] <= '9') ++end;
    if (end == fraction || end - fraction > 9) end = 0;
  }
  if (!shaped || end == 0 || end + 1 != text.size() || text[end] != 'Z') {
    return "start_utc " + quoted(text) +
           " is not an ISO 8601 UTC time such as 2026-11-23T10:00:00.123456Z";
  }
  const int year = number_at(text, 0, 4);
  const int month = number_at(text, 5, 2);
  const int day = number_at(text, 8, 2);
  const int hour = number_at(text, 11, 2);
  const int minute = number_at(text, 14, 2);
  const int second = number_at(text, 17, 2);
  if (year < min_start_year || year > max_start_year) {
    return "start_utc " + quoted(text) + " is outside the years " +
           std::to_string(min_start_year) + " to " + std::to_string(max_start_year);
  }
  if (month < 1 || month > 12 || day < 1 || day > 31 || hour > 23 || minute > 59 ||
      second > 60) {
    return "start_utc " + quoted(text) + " is not a valid date and time";
  }
  return std::nullopt;
}

namespace {

// Days from 1970-01-01 to year-month-day of the proleptic Gregorian calendar
// (H. Hinnant's days_from_civil), and back.
std::int64_t days_from_civil(std::int64_t year, unsigned month, unsigned day) {
  year -= month <= 2;
  const std::int64_t era = (year >= 0 ? year : year - 399) / 400;
  const auto year_of_era = static_cast<unsigned>(year - era * 400);
  const unsigned day_of_year = (153 * (month + (month > 2 ? -3 : 9)) + 2) / 5 + day - 1;
  const unsigned day_of_era =
      year_of_era * 365 + year_of_era / 4 - year_of_era / 100 + day_of_year;
  return era * 146097 + static_cast<std::int64_t>(day_of_era) - 719468;
}

void civil_from_days(std::int64_t days, int& year, unsigned& month, unsigned& day) {
  days += 719468;
  const std::int64_t era = (days >= 0 ? days : days - 146096) / 146097;
  const auto day_of_era = static_cast<unsigned>(days - era * 146097);
  const unsigned year_of_era =
      (day_of_era - day_of_era / 1460 + day_of_era / 36524 - day_of_era / 146096) / 365;
  const unsigned day_of_year =
      day_of_era - (365 * year_of_era + year_of_era / 4 - year_of_era / 100);
  const unsigned shifted_month = (5 * day_of_year + 2) / 153;
  day = day_of_year - (153 * shifted_month + 2) / 5 + 1;
  month = shifted_month < 10 ? shifted_month + 3 : shifted_month - 9;
  year = static_cast<int>(static_cast<std::int64_t>(year_of_era) + era * 400 + (month <= 2));
}

constexpr std::int64_t ns_per_second = 1'000'000'000;

}  // namespace

std::optional<std::int64_t> start_utc_epoch_ns(std::string_view text) {
  if (text.empty()) return std::nullopt;
  if (const auto problem = start_utc_problem(text)) {
    throw OptionError(header_field::start_utc, *problem);
  }
  const std::int64_t days = days_from_civil(number_at(text, 0, 4),
                                            static_cast<unsigned>(number_at(text, 5, 2)),
                                            static_cast<unsigned>(number_at(text, 8, 2)));
  const std::int64_t seconds = days * 86400 + number_at(text, 11, 2) * 3600 +
                               number_at(text, 14, 2) * 60 + number_at(text, 17, 2);
  std::int64_t fraction = 0;
  std::size_t digits = 0;
  for (std::size_t at = 20; text[19] == '.' && at + 1 < text.size(); ++at, ++digits) {
    fraction = fraction * 10 + (text[at] - '0');
  }
  for (; digits < 9; ++digits) fraction *= 10;
  return seconds * ns_per_second + fraction;
}

std::optional<std::string> format_start_utc(std::int64_t epoch_ns) {
  if (epoch_ns < 0) return std::nullopt;  // before 1970, the first year allowed
  const std::int64_t seconds = epoch_ns / ns_per_second;
  const std::int64_t days = seconds / 86400;
  const std::int64_t in_day = seconds % 86400;
  int year = 0;
  unsigned month = 0;
  unsigned day = 0;
  civil_from_days(days, year, month, day);
  if (year < min_start_year || year > max_start_year) return std::nullopt;
  char text[48];
  std::snprintf(text, sizeof text, "%04d-%02u-%02uT%02d:%02d:%02d.%09lldZ", year, month, day,
                static_cast<int>(in_day / 3600), static_cast<int>(in_day / 60 % 60),
                static_cast<int>(in_day % 60),
                static_cast<long long>(epoch_ns % ns_per_second));
  return std::string(text);
}

const char* capture_name(Capture capture) {
  return capture == Capture::wire ? "wire" : "client";
}

std::optional<Capture> capture_from_name(std::string_view name) {
  if (name == capture_name(Capture::client)) return Capture::client;
  if (name == capture_name(Capture::wire)) return Capture::wire;
  return std::nullopt;
}

namespace {

// A header written by wiretape itself names no source member.
bool recorded_by_wiretape(const SessionHeader& header) {
  return header.source_format.empty() || header.source_format == "wiretape";
}

}  // namespace

namespace {

void require_good_channels(const std::vector<Channel>& channels) {
  namespace field = header_field;
  if (channels.size() > max_channels) {
    throw OptionError(field::channels, "a session holds at most " +
                                           std::to_string(max_channels) + " channels, not " +
                                           std::to_string(channels.size()));
  }
  for (std::size_t i = 0; i < channels.size(); ++i) {
    const Channel& channel = channels[i];
    if (channel.id != i) {
      throw OptionError(field::channels, "channel " + quoted(channel.name) + " has id " +
                                             std::to_string(channel.id) +
                                             "; channel ids are 0..n-1 in order, so it must be " +
                                             std::to_string(i));
    }
    if (const auto problem = channel_name_problem(channel.name)) {
      throw OptionError(field::channels, "channel " + std::to_string(i) + ": " + *problem);
    }
    for (std::size_t j = 0; j < i; ++j) {
      if (channels[j].name == channel.name) {
        throw OptionError(field::channels, "two channels are named " + quoted(channel.name) +
                                               " (ids " + std::to_string(j) + " and " +
                                               std::to_string(i) + ")");
      }
    }
  }
}

// The members a port has in the header, written for the top level and for
// each channel in the same order.
void add_port_members(json::ObjectWriter& object, const std::string& port_options,
                      const std::string& port_type) {
  object.add(header_field::port_options, port_options).add(header_field::port_type, port_type);
}

std::string device_identity_json(const DeviceIdentity& identity) {
  json::ObjectWriter object;
  for (const auto& member : device_identity_members) {
    const std::string& value = identity.*member.value;
    if (!value.empty()) object.add(member.name, value);
  }
  return object.str();
}

void require_utf8_identity(const std::string& field, const DeviceIdentity& identity) {
  for (const auto& member : device_identity_members) {
    require_utf8(field + "." + member.name, identity.*member.value);
  }
}

std::string channels_json(const std::vector<Channel>& channels) {
  namespace field = header_field;
  std::string out = "[";
  for (const Channel& channel : channels) {
    const std::string where = std::string(field::channels) + "[" + std::to_string(channel.id) + "]";
    require_utf8(where + "." + field::port_options, channel.port_options);
    require_utf8(where + "." + field::port_type, channel.port_type);
    require_utf8(where + "." + field::device_address, channel.device_address);
    if (channel.device_identity) {
      require_utf8_identity(where + "." + field::device_identity, *channel.device_identity);
    }
    json::ObjectWriter object;
    object.add(field::channel_id, static_cast<unsigned>(channel.id))
        .add(field::channel_name, channel.name);
    add_port_members(object, channel.port_options, channel.port_type);
    object.add(field::capture, capture_name(channel.capture));
    if (!channel.device_address.empty()) {
      object.add(field::device_address, channel.device_address);
    }
    if (channel.device_identity) {
      object.add_raw(field::device_identity, device_identity_json(*channel.device_identity));
    }
    if (out.size() > 1) out += ",";
    out += object.str();
  }
  return out + "]";
}

std::string string_array(const std::vector<std::string>& items) {
  std::string out = "[";
  for (const auto& item : items) {
    if (out.size() > 1) out += ",";
    json::append_string(out, item);
  }
  return out + "]";
}

std::string attached_json(const AttachedProgram& attached) {
  namespace field = header_field;
  require_utf8(std::string(field::attached) + "." + field::attached_command, attached.command);
  require_utf8(std::string(field::attached) + "." + field::attached_device, attached.device);
  for (const auto& warning : attached.warnings) {
    require_utf8(std::string(field::attached) + "." + field::attached_warnings, warning);
  }
  if (const auto problem = start_utc_problem(attached.utc)) {
    throw OptionError(field::attached, "the session header's attached." + *problem);
  }
  std::string descriptors = "[";
  for (const int fd : attached.descriptors) {
    if (descriptors.size() > 1) descriptors += ",";
    descriptors += std::to_string(fd);
  }
  json::ObjectWriter object;
  object.add(field::attached_pid, attached.pid)
      .add(field::attached_command, attached.command)
      .add(field::attached_utc, attached.utc)
      .add_raw(field::attached_descriptors, descriptors + "]")
      .add(field::attached_device, attached.device)
      .add_raw(field::attached_warnings, string_array(attached.warnings));
  return object.str();
}

std::optional<AttachedProgram> read_attached(const json::Value& root) {
  namespace field = header_field;
  const json::Value* member = root.find(field::attached);
  if (member == nullptr || !member->is_object()) return std::nullopt;
  AttachedProgram attached;
  if (const json::Value* pid = member->find(field::attached_pid);
      pid != nullptr && pid->type == json::Value::Type::number) {
    attached.pid = static_cast<std::int64_t>(pid->number);
  }
  attached.command = member->string_member(field::attached_command).value_or("");
  attached.utc = member->string_member(field::attached_utc).value_or("");
  attached.device = member->string_member(field::attached_device).value_or("");
  if (const json::Value* fds = member->find(field::attached_descriptors)) {
    for (const json::Value& item : fds->items) {
      if (item.type == json::Value::Type::number) attached.descriptors.push_back(static_cast<int>(item.number));
    }
  }
  if (const json::Value* warnings = member->find(field::attached_warnings)) {
    for (const json::Value& item : warnings->items) {
      if (item.is_string()) attached.warnings.push_back(item.text);
    }
  }
  return attached;
}

}  // namespace

std::string header_json(const SessionHeader& given) {
  namespace field = header_field;
  require_good_channels(given.channels);
  // With channels, the port members are channel 0's (what a 1.1 reader reads).
  SessionHeader with_channel_zero;
  if (!given.channels.empty()) {
    with_channel_zero = given;
    const Channel& first = given.channels.front();
    with_channel_zero.port_options = first.port_options;
    with_channel_zero.port_type = first.port_type;
    with_channel_zero.capture = first.capture;
    with_channel_zero.device_address = first.device_address;
    with_channel_zero.device_identity = first.device_identity;
  }
  const SessionHeader& header = given.channels.empty() ? given : with_channel_zero;
  // What is written here must read back: the reader refuses a header that
  // is not UTF-8 or has a start time out of range.
  require_utf8(field::port_options, header.port_options);
  require_utf8(field::port_type, header.port_type);
  require_utf8(field::host, header.host);
  require_utf8(field::wiretape_version, header.wiretape_version);
  for (const auto& [key, value] : header.user_metadata) {
    require_utf8("meta_" + key, key);
    require_utf8("meta_" + key, value);
  }
  require_utf8(field::source_format, header.source_format);
  for (const auto& name : header.source_files) require_utf8(field::source_files, name);
  for (const auto& [key, value] : header.source_details) {
    if (key == field::source_format || key == field::source_files) {
      throw OptionError(field::source, "the session header's source detail \"" + key +
                                           "\" would hide the source's own " + key);
    }
    require_utf8(field::source, key);
    require_utf8(field::source, value);
  }
  require_utf8(field::device_address, header.device_address);
  for (const auto& edit : header.edits) require_utf8(field::edits, edit);
  if (header.device_identity) {
    require_utf8_identity(field::device_identity, *header.device_identity);
  }
  if (const auto problem = start_utc_problem(header.start_utc)) {
    throw OptionError(field::start_utc, "the session header's " + *problem);
  }
  json::ObjectWriter object;
  add_port_members(object, header.port_options, header.port_type);
  object.add(field::start_utc, header.start_utc)
      .add(field::wiretape_version, header.wiretape_version)
      .add(field::host, header.host)
      .add(field::capture, capture_name(header.capture))
      .add(field::metadata, header.user_metadata);
  // Format 1.1 members, written only when they say something, so that a
  // recording's header stays as short as before.
  if (!recorded_by_wiretape(header)) {
    std::string files = "[";
    for (const auto& name : header.source_files) {
      if (files.size() > 1) files += ",";
      json::append_string(files, name);
    }
    files += "]";
    json::ObjectWriter source;
    source.add(field::source_format, header.source_format).add_raw(field::source_files, files);
    for (const auto& [key, value] : header.source_details) source.add(key, value);
    object.add_raw(field::source, source.str());
  }
  if (!header.device_address.empty()) {
    object.add(field::device_address, header.device_address);
  }
  if (!header.edits.empty()) {
    std::string edits = "[";
    for (const auto& edit : header.edits) {
      if (edits.size() > 1) edits += ",";
      json::append_string(edits, edit);
    }
    object.add_raw(field::edits, edits + "]");
  }
  // Format 1.2. Members not known are left out, so that the header says
  // only what the machine knew.
  if (header.device_identity) {
    object.add_raw(field::device_identity, device_identity_json(*header.device_identity));
  }
  if (!header.channels.empty()) object.add_raw(field::channels, channels_json(header.channels));
  if (header.attached) object.add_raw(field::attached, attached_json(*header.attached));
  return object.str();
}

namespace {

std::optional<DeviceIdentity> read_device_identity(const json::Value& port) {
  const json::Value* identity = port.find(header_field::device_identity);
  if (identity == nullptr || !identity->is_object()) return std::nullopt;
  DeviceIdentity read;
  for (const auto& member : device_identity_members) {
    read.*member.value = identity->string_member(member.name).value_or("");
  }
  return read;
}

// Unlike the other members, channels that cannot be read make the file
// unusable: every record would be attributed to a port it may not be of.
std::vector<Channel> read_channels(const json::Value& root, const std::string& path,
                                   std::uint64_t offset) {
  namespace field = header_field;
  std::vector<Channel> channels;
  const json::Value* list = root.find(field::channels);
  if (list == nullptr) return channels;
  const auto refuse = [&](const std::string& why) -> SessionError {
    return SessionError(path + ": the header at byte " + std::to_string(offset) +
                            " has unusable channels: " + why,
                        offset);
  };
  if (list->type != json::Value::Type::array) throw refuse("\"channels\" is not an array");
  if (list->items.empty()) throw refuse("\"channels\" is empty (a session has a channel)");
  if (list->items.size() > max_channels) {
    throw refuse(std::to_string(list->items.size()) + " channels, more than " +
                 std::to_string(max_channels));
  }
  for (const json::Value& item : list->items) {
    const std::string where = "channel " + std::to_string(channels.size());
    if (!item.is_object()) throw refuse(where + " is not an object");
    const json::Value* id = item.find(field::channel_id);
    if (id == nullptr || id->type != json::Value::Type::number ||
        id->number != static_cast<double>(channels.size())) {
      throw refuse(where + " has no id " + std::to_string(channels.size()) +
                   " (ids are 0..n-1 in order)");
    }
    Channel& channel = channels.emplace_back();
    channel.id = static_cast<std::uint16_t>(channels.size() - 1);
    const auto name = item.string_member(field::channel_name);
    if (!name) throw refuse(where + " has no name");
    if (const auto problem = channel_name_problem(*name)) throw refuse(where + ": " + *problem);
    for (std::size_t j = 0; j + 1 < channels.size(); ++j) {
      if (channels[j].name == *name) throw refuse("two channels are named " + quoted(*name));
    }
    channel.name = *name;
    channel.port_options = item.string_member(field::port_options).value_or("");
    channel.port_type = item.string_member(field::port_type).value_or("");
    const std::string capture =
        item.string_member(field::capture).value_or(capture_name(Capture::client));
    const auto known = capture_from_name(capture);
    if (!known) throw refuse(where + " has an unknown capture " + quoted(capture));
    channel.capture = *known;
    channel.device_address = item.string_member(field::device_address).value_or("");
    channel.device_identity = read_device_identity(item);
  }
  return channels;
}

}  // namespace

void parse_header_json(const std::string& text, const std::string& path,
                       std::uint64_t offset, SessionHeader& header) {
  json::Value root;
  try {
    root = json::parse(text);
  } catch (const json::ParseError& e) {
    throw SessionError(path + ": the header's metadata is not valid JSON (" +
                           e.what() + " of the metadata, file byte " +
                           std::to_string(offset + e.offset()) + ")",
                       offset + e.offset());
  }
  if (!root.is_object()) {
    throw SessionError(path + ": the header's metadata at byte " +
                           std::to_string(offset) + " is not a JSON object",
                       offset);
  }
  namespace field = header_field;
  // Without the spaces a recorder reserved for channels (header room).
  header.metadata_json = text.substr(0, text.find_last_not_of(' ') + 1);
  header.port_options = root.string_member(field::port_options).value_or("");
  header.port_type = root.string_member(field::port_type).value_or("");
  header.start_utc = root.string_member(field::start_utc).value_or("");
  header.wiretape_version = root.string_member(field::wiretape_version).value_or("");
  header.host = root.string_member(field::host).value_or("");
  const std::string capture =
      root.string_member(field::capture).value_or(capture_name(Capture::client));
  if (const auto known = capture_from_name(capture)) {
    header.capture = *known;
  } else {
    throw SessionError(path + ": unknown capture " + quoted(capture) +
                           " in the header at byte " + std::to_string(offset) +
                           " (expected client or wire)",
                       offset);
  }
  if (const auto problem = start_utc_problem(header.start_utc)) {
    throw SessionError(path + ": the header at byte " + std::to_string(offset) +
                           " has a " + *problem,
                       offset);
  }
  // Provenance: members of the wrong type are ignored, like unknown ones
  // (they can only come from a writer other than ours).
  header.source_format = "wiretape";
  header.source_files.clear();
  header.source_details.clear();
  if (const json::Value* source = root.find(field::source);
      source != nullptr && source->is_object()) {
    header.source_format = source->string_member(field::source_format).value_or("unknown");
    for (const auto& [key, value] : source->members) {
      if (key == field::source_format) continue;
      if (key == field::source_files) {
        for (const json::Value& item : value.items) {
          if (item.is_string()) header.source_files.push_back(item.text);
        }
      } else if (value.is_string()) {
        header.source_details[key] = value.text;
      }
    }
  }
  header.device_address = root.string_member(field::device_address).value_or("");
  header.edits.clear();
  if (const json::Value* edits = root.find(field::edits)) {
    for (const json::Value& item : edits->items) {
      if (item.is_string()) header.edits.push_back(item.text);
    }
  }
  // Like provenance: members of another type are ignored.
  header.device_identity = read_device_identity(root);
  header.channels = read_channels(root, path, offset);
  header.attached = read_attached(root);
  header.user_metadata.clear();
  if (const json::Value* metadata = root.find(field::metadata);
      metadata != nullptr && metadata->is_object()) {
    for (const auto& [key, value] : metadata->members) {
      header.user_metadata[key] =
          value.is_string() ? value.text : json::serialize(value);
    }
  }
}

namespace {

// A string as udev writes it into a by-id name: white space as `_`, and
// every byte but ASCII letters, digits, "#+-.:=@_" and UTF-8 as `_`.
std::string udev_name_part(std::string_view text) {
  std::string out;
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    const bool kept = (byte >= '0' && byte <= '9') || (byte >= 'a' && byte <= 'z') ||
                      (byte >= 'A' && byte <= 'Z') || byte >= 0x80 ||
                      std::string_view("#+-.:=@_").find(c) != std::string_view::npos;
    out += kept ? c : '_';
  }
  return out;
}

constexpr std::string_view redacted_text = "redacted";

}  // namespace

void clear_device_serial(DeviceIdentity& identity) {
  const std::string serial = std::move(identity.serial_number);
  identity.serial_number.clear();
  if (serial.empty() || identity.by_id.empty()) return;
  const std::size_t name_start = identity.by_id.rfind('/') + 1;  // npos + 1: all of it
  std::string name = identity.by_id.substr(name_start);
  // udev names a USB device usb-VENDOR_MODEL_SERIAL-ifNN: the serial is the
  // last place it appears.
  bool replaced = false;
  for (const std::string& spelling : {udev_name_part(serial), serial}) {
    if (const std::size_t at = name.rfind(spelling); !replaced && at != std::string::npos) {
      name.replace(at, spelling.size(), redacted_text);
      replaced = true;
    }
  }
  identity.by_id = identity.by_id.substr(0, name_start) +
                   (replaced ? name : std::string(redacted_text));
}

}  // namespace wiretape::detail

namespace wiretape {

SessionHeader SessionHeader::starting_now() {
  SessionHeader header;
  header.start_utc = detail::utc_now_iso8601();
  header.host = detail::host_name();
  return header;
}

std::string SessionHeader::to_json() const { return detail::header_json(*this); }

std::vector<Channel> SessionHeader::channel_list() const {
  if (!channels.empty()) return channels;
  Channel only;
  only.port_options = port_options;
  only.port_type = port_type;
  only.capture = capture;
  only.device_address = device_address;
  only.device_identity = device_identity;
  return {only};
}

std::optional<Channel> SessionHeader::find_channel(std::string_view name) const {
  for (const Channel& channel : channels) {
    if (channel.name == name) return channel;
  }
  return std::nullopt;
}

bool AttachedProgram::operator==(const AttachedProgram& other) const {
  return pid == other.pid && command == other.command && utc == other.utc &&
         descriptors == other.descriptors && device == other.device &&
         warnings == other.warnings;
}

bool Channel::operator==(const Channel& other) const {
  return id == other.id && name == other.name && port_options == other.port_options &&
         port_type == other.port_type && capture == other.capture &&
         device_address == other.device_address && device_identity == other.device_identity;
}

std::optional<std::string> channel_name_problem(std::string_view name) {
  const std::string shown = "\"" + detail::escape_bytes(name, name.size()) + "\"";
  if (name.empty()) return std::string("a channel name is empty");
  if (name.size() > detail::max_channel_name) {
    return "the channel name " + shown + " is longer than " +
           std::to_string(detail::max_channel_name) + " characters";
  }
  const auto letter = [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_';
  };
  const auto digit = [](char c) { return c >= '0' && c <= '9'; };
  if (!letter(name.front())) {
    return "the channel name " + shown + " does not start with a letter or '_'";
  }
  for (const char c : name) {
    if (!letter(c) && !digit(c) && c != '-') {
      return "the channel name " + shown +
             " holds a character other than letters, digits, '_' and '-'";
    }
  }
  for (const std::string_view type : port_types()) {
    if (find_option_key(name, type) != nullptr) {
      return "\"" + std::string(name) +
             "\" is an option key, so it cannot name a channel (NAME=... would read as "
             "an option)";
    }
  }
  return std::nullopt;
}

bool DeviceIdentity::operator==(const DeviceIdentity& other) const {
  for (const auto& member : detail::device_identity_members) {
    if (this->*member.value != other.*member.value) return false;
  }
  return true;
}

}  // namespace wiretape
