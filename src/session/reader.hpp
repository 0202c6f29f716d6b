// The session reader's private side: the record source behind
// wiretape::SessionReader, for the replay engine, which reads large payloads
// as views (RecordSource::next(record, view)) instead of copies.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "posix/file_checks.hpp"
#include "session/record_source.hpp"
#include "wiretape/session.hpp"

namespace wiretape::detail {

// The records of a .wtape file or a flexiport log pair ("name.log"), and its
// header into `header`. Throws PortError when a file cannot be opened or is
// not a regular file (a pipe or FIFO is read as a stream with Streams::read;
// flexiport logs are always regular files), SessionError when it is not a
// usable session; damage later on ends the records and is reported by
// damage(). `channel`: only that channel's records; std::nullopt: every
// channel's (records of a channel the header does not list are skipped).
// `on_unlisted` is told of each record (a good CRC, any kind) whose channel
// the header does not list, which is skipped: `wiretape verify` names them.
struct UnlistedRecord {
  std::uint64_t offset = 0;  // where its record header begins
  std::uint16_t channel = 0;
};
using UnlistedRecordSink = std::function<void(const UnlistedRecord&)>;
// `on_place` is told where each record with a good CRC lies (any kind, any
// channel, before the channel filter): what the index of the file is made
// of, for verify and `verify --repair`. Once a chunk's records were all
// read, it is told of the whole chunk once per channel the chunk holds,
// with `records` its records of that channel (0 for every record itself).
struct RecordPlace {
  std::uint64_t offset = 0;  // its record header (a chunk's first part's)
  std::uint64_t end = 0;     // past its CRC (a chunk's last part's)
  std::uint16_t channel = 0;
  std::uint8_t kind_code = 0;
  std::uint64_t records = 0;
};
using RecordPlaceSink = std::function<void(const RecordPlace&)>;
std::unique_ptr<RecordSource> open_session_source(
    const std::string& path, SessionHeader& header, Streams streams = Streams::refused,
    std::optional<std::uint16_t> channel = std::nullopt, UnlistedRecordSink on_unlisted = {},
    RecordPlaceSink on_place = {});

// Why a record whose CRC is good still cannot be handed to the commands that
// read it, or std::nullopt. What verify accepts, every consumer (Python's
// json module included) must be able to take: t_ns within max_record_t_ns,
// event payloads empty or JSON objects of valid UTF-8 within the JSON
// parser's nesting limit (unknown members are fine: readers ignore them).
// The reader stops at such a record; the writer refuses to write one.
std::optional<std::string> record_content_problem(RecordKind kind, std::uint64_t t_ns,
                                                  std::string_view payload);

}  // namespace wiretape::detail
