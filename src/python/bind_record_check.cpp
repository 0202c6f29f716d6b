// The reader's walk over every record of a session, with what it skips, for
// `wiretape verify`: records per channel, the records of channels the header
// does not list (by offset) and where reading stopped. verify reads no byte
// of the layout itself.
#include <cstdint>
#include <map>
#include <optional>
#include <string>

#include <nanobind/nanobind.h>
#include <nanobind/stl/map.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/pair.h>

#include "python/bindings.hpp"
#include "python/text_caster.hpp"
#include "session/reader.hpp"
#include "session/session_index.hpp"
#include "wiretape/session.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace wiretape::python {

namespace {

struct RecordCheck {
  SessionHeader header;
  std::uint64_t records = 0;  // the good records of listed channels
  std::map<std::uint16_t, std::uint64_t> channel_records;  // listed or not
  std::uint64_t unlisted_records = 0;
  std::optional<detail::UnlistedRecord> first_unlisted;
  std::optional<SessionError> damage;
  std::optional<SessionError> unfinished;  // the file is still being written
  detail::IndexStatus index;
};

RecordCheck check_records(const std::string& path) {
  RecordCheck check;
  auto on_unlisted = [&check](const detail::UnlistedRecord& record) {
    ++check.unlisted_records;
    ++check.channel_records[record.channel];
    if (!check.first_unlisted) check.first_unlisted = record;
  };
  detail::IndexCheck index;
  // Pipes and FIFOs are read as every command reads them (DESIGN §6).
  auto source = detail::open_session_source(path, check.header, detail::Streams::read,
                                            std::nullopt, on_unlisted, index.sink());
  Record record;
  while (source->next(record)) {
    ++check.records;
    ++check.channel_records[record.channel];
  }
  check.damage = source->damage();
  check.unfinished = source->unfinished();
  if (detail::is_stream(path)) {
    check.index = {detail::IndexState::unchecked, "a pipe or FIFO is read once"};
  } else if (check.unfinished) {
    check.index = {detail::IndexState::unchecked, "the file is still being written"};
  } else {
    check.index = index.status(path, check.header.channels.size(), check.damage.has_value());
  }
  return check;
}

}  // namespace

void bind_record_check(nb::module_& m) {
  nb::class_<RecordCheck>(m, "RecordCheck",
                          "What check_session_records() found: every record the reader "
                          "reached, with those of channels the header does not list.")
      .def_ro("header", &RecordCheck::header)
      .def_ro("records", &RecordCheck::records,
              "the good records of the channels the header lists")
      .def_ro("channel_records", &RecordCheck::channel_records,
              "records per channel id, those of unlisted channels included")
      .def_ro("unlisted_records", &RecordCheck::unlisted_records,
              "records naming a channel the header does not list (the reader skips them)")
      .def_prop_ro(
          "first_unlisted_offset",
          [](const RecordCheck& c) -> std::optional<std::uint64_t> {
            if (!c.first_unlisted) return std::nullopt;
            return c.first_unlisted->offset;
          },
          "where the first such record begins, or None")
      .def_prop_ro(
          "first_unlisted_channel",
          [](const RecordCheck& c) -> std::optional<std::uint16_t> {
            if (!c.first_unlisted) return std::nullopt;
            return c.first_unlisted->channel;
          },
          "the channel the first such record names, or None")
      .def_prop_ro(
          "index_state",
          [](const RecordCheck& c) { return std::string(detail::to_string(c.index.state)); },
          "the per-channel index: 'not needed' (one channel), 'current', 'absent', 'stale' "
          "or 'unchecked' (a damaged file, a stream)")
      .def_prop_ro(
          "index_detail", [](const RecordCheck& c) { return c.index.detail; },
          "why the index is absent, stale or unchecked; where it is when current")
      .def_prop_ro(
          "damage",
          [](const RecordCheck& c) -> nb::object {
            if (!c.damage) return nb::none();
            // The class bind_errors() registered, looked up when needed.
            nb::object cls = nb::module_::import_("wiretape._core").attr("SessionError");
            nb::object error = cls(std::string(c.damage->what()), c.damage->offset());
            error.attr("message") = std::string(c.damage->what());
            return error;
          },
          nb::for_getter(nb::sig("def damage(self, /) -> SessionError | None")),
          "None, or a SessionError (not raised) with .offset and .message: where "
          "reading stopped and why")
      .def_prop_ro(
          "unfinished",
          [](const RecordCheck& c) -> std::optional<std::string> {
            if (!c.unfinished) return std::nullopt;
            return std::string(c.unfinished->what());
          },
          "None, or why reading stopped at the end of a file still being written (not "
          "damage)")
      .def_prop_ro(
          "unfinished_offset",
          [](const RecordCheck& c) -> std::optional<std::uint64_t> {
            if (!c.unfinished) return std::nullopt;
            return c.unfinished->offset();
          },
          "where the unfinished chunk or record begins, or None");

  m.def(
      "check_session_records",
      [](const std::string& path) {
        nb::gil_scoped_release release;
        return check_records(path);
      },
      "path"_a,
      "Reads every record of the session at PATH as SessionReader does (CRC, length, "
      "content), counting them per channel and noting the records of channels the header "
      "does not list, which a reader skips. Raises PortError when PATH cannot be opened, "
      "SessionError when it is not a session; damage later on is RecordCheck.damage.");

  m.def(
      "repair_session_index",
      [](const std::string& path) {
        nb::gil_scoped_release release;
        const detail::IndexStatus status = detail::repair_session_index(path);
        return std::make_pair(std::string(detail::to_string(status.state)), status.detail);
      },
      "path"_a,
      "`wiretape verify --repair`: appends the per-channel index to the session at PATH, "
      "of several channels, when it has none or a stale one. Returns (state, detail): "
      "('current', 'appended at byte N'), or the state found when nothing was to be done. "
      "Raises SessionError when the file is damaged, PortError when it cannot be written.");
}

}  // namespace wiretape::python
