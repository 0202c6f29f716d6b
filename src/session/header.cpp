#include "session/header.hpp"

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <ctime>

#include "util/json.hpp"
#include "wiretape/errors.hpp"
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

namespace {

std::string host_name() {
  char name[256] = {};
  if (gethostname(name, sizeof name - 1) != 0) return "";
  return name;
}

}  // namespace

const char* capture_name(Capture capture) {
  return capture == Capture::wire ? "wire" : "client";
}

std::string header_json(const SessionWriterOptions& options) {
  namespace field = header_field;
  json::ObjectWriter object;
  object.add(field::port_options, options.port_options)
      .add(field::port_type, options.port_type)
      .add(field::start_utc,
           options.start_utc.empty() ? utc_now_iso8601() : options.start_utc)
      .add(field::wiretape_version, options.wiretape_version.empty()
                                        ? std::string(wiretape::version)
                                        : options.wiretape_version)
      .add(field::host, options.host.empty() ? host_name() : options.host)
      .add(field::capture, capture_name(options.capture))
      .add(field::metadata, options.metadata);
  return object.str();
}

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
  header.metadata_json = text;
  header.port_options = root.string_member(field::port_options).value_or("");
  header.port_type = root.string_member(field::port_type).value_or("");
  header.start_utc = root.string_member(field::start_utc).value_or("");
  header.wiretape_version = root.string_member(field::wiretape_version).value_or("");
  header.host = root.string_member(field::host).value_or("");
  const std::string capture =
      root.string_member(field::capture).value_or(capture_name(Capture::client));
  if (capture == capture_name(Capture::client)) {
    header.capture = Capture::client;
  } else if (capture == capture_name(Capture::wire)) {
    header.capture = Capture::wire;
  } else {
    throw SessionError(path + ": unknown capture \"" + capture +
                           "\" in the header at byte " + std::to_string(offset) +
                           " (expected client or wire)",
                       offset);
  }
  header.user_metadata.clear();
  if (const json::Value* metadata = root.find(field::metadata);
      metadata != nullptr && metadata->is_object()) {
    for (const auto& [key, value] : metadata->members) {
      header.user_metadata[key] =
          value.is_string() ? value.text : json::serialize(value);
    }
  }
}

}  // namespace wiretape::detail
