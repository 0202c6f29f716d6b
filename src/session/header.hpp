// The header of a .wtape file: its metadata JSON, written and parsed (the
// fixed bytes around it are in session/format.hpp).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "wiretape/session.hpp"

namespace wiretape::detail {

// The member names of the header JSON (docs/session-format.md, "Metadata"),
// spelled here once.
namespace header_field {
inline constexpr char port_options[] = "port_options";
inline constexpr char port_type[] = "port_type";
inline constexpr char start_utc[] = "start_utc";
inline constexpr char wiretape_version[] = "wiretape_version";
inline constexpr char host[] = "host";
inline constexpr char capture[] = "capture";
inline constexpr char metadata[] = "metadata";
// Format 1.1: provenance and addresses.
inline constexpr char source[] = "source";  // {"format":..,"files":[..],more strings}
inline constexpr char source_format[] = "format";
inline constexpr char source_files[] = "files";
inline constexpr char device_address[] = "device_address";
inline constexpr char edits[] = "edits";
// Format 1.2: the serial device's identity, an object of strings.
inline constexpr char device_identity[] = "device_identity";
// Format 1.2: the ports of a session of several ports, an array of objects
// with the port members above plus these.
inline constexpr char channels[] = "channels";
inline constexpr char channel_id[] = "id";
inline constexpr char channel_name[] = "name";
// A recording made by attaching to a running program (DESIGN §26): an
// object of these members.
inline constexpr char attached[] = "attached";
inline constexpr char attached_pid[] = "pid";
inline constexpr char attached_command[] = "command";
inline constexpr char attached_utc[] = "utc";
inline constexpr char attached_descriptors[] = "descriptors";
inline constexpr char attached_device[] = "device";
inline constexpr char attached_warnings[] = "warnings";
}  // namespace header_field

// The most channels a session has: ids are u16, and a header lists them all.
inline constexpr std::size_t max_channels = 1024;
inline constexpr std::size_t max_channel_name = 64;

// The members of a DeviceIdentity, by the name the header JSON and Python
// give them (docs/session-format.md, "device_identity"), spelled here once.
struct DeviceIdentityMember {
  const char* name;
  std::string DeviceIdentity::*value;
};
inline constexpr DeviceIdentityMember device_identity_members[] = {
    {"kernel_name", &DeviceIdentity::kernel_name},
    {"subsystem", &DeviceIdentity::subsystem},
    {"vendor_id", &DeviceIdentity::vendor_id},
    {"product_id", &DeviceIdentity::product_id},
    {"serial_number", &DeviceIdentity::serial_number},
    {"manufacturer", &DeviceIdentity::manufacturer},
    {"product", &DeviceIdentity::product},
    {"interface", &DeviceIdentity::interface},
    {"location", &DeviceIdentity::location},
    {"by_id", &DeviceIdentity::by_id},
};

// `identity` without its serial number, as `edit --redact` leaves it
// (DESIGN §20): the serial number cleared, and its part of the by-id name
// (as udev spells it there) replaced by "redacted"; a by-id name that holds
// the serial number in another spelling becomes /dev/serial/by-id/redacted.
void clear_device_serial(DeviceIdentity& identity);

// The years a header's start_utc may name: the session's start in ns since
// the epoch then fits a signed 64-bit count, and start + t_ns (at most
// max_record_t_ns) fits the unsigned 64-bit clocks of pcapng and MCAP.
inline constexpr int min_start_year = 1970;
inline constexpr int max_start_year = 2261;

// The header JSON of a session file (SessionHeader::to_json). Throws
// OptionError naming the field when a string is not valid UTF-8 or start_utc
// is not a time the reader accepts (start_utc_problem), so that nothing is
// written that cannot be read.
std::string header_json(const SessionHeader& header);
// Why `start_utc` is not what the header allows (empty, or ISO 8601 UTC
// YYYY-MM-DDTHH:MM:SS[.fraction]Z within min_start_year..max_start_year),
// or std::nullopt when it is.
std::optional<std::string> start_utc_problem(std::string_view start_utc);
// `start_utc` as ns since the epoch (a leap second's :60 is the next
// minute's :00); std::nullopt when it is empty (not known). Throws
// OptionError naming start_utc with start_utc_problem's reason when it is not
// what the header allows.
std::optional<std::int64_t> start_utc_epoch_ns(std::string_view start_utc);
// `epoch_ns` as the header writes it, 2026-11-23T10:00:00.123456789Z (nine
// digits of fraction); std::nullopt when it falls outside min_start_year..
// max_start_year (no header can hold it).
std::optional<std::string> format_start_utc(std::int64_t epoch_ns);
// Parses the header JSON into `header` (metadata_json included); throws
// SessionError(offset) naming `path` when it is not valid.
void parse_header_json(const std::string& json, const std::string& path,
                       std::uint64_t offset, SessionHeader& header);
// Now, as 2026-11-23T10:00:00.123456Z.
std::string utc_now_iso8601();
// The header's spelling of `capture`: "client" or "wire".
const char* capture_name(Capture capture);
// The capture spelled `name`, or std::nullopt when it is neither.
std::optional<Capture> capture_from_name(std::string_view name);
// This machine's host name ("" when it has none).
std::string host_name();

}  // namespace wiretape::detail
