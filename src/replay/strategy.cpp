#include "replay/strategy.hpp"

#include <algorithm>
#include <cstdio>
#include <sstream>

#include "session/record_kinds.hpp"
#include "util/hex.hpp"
#include "util/json.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

void ReleasedRx::push(RxItem&& item) {
  bytes_ += item.payload().size();
  items_.push_back(std::move(item));
}

ModemInputs ReleasedRx::device_lines(ReplayTime now) {
  while (!lines_.empty() && lines_.front().due <= now) {
    device_lines_ = lines_.front().inputs;
    lines_.pop_front();
  }
  return device_lines_;
}

void ReleasedRx::pop_front() {
  bytes_ -= items_.front().payload().size();
  recycle_payload(std::move(items_.front().data));
  items_.pop_front();
}

std::string ReleasedRx::spare_payload() {
  if (spare_payloads_.empty()) return {};
  std::string buffer = std::move(spare_payloads_.back());
  spare_payloads_.pop_back();
  spare_bytes_ -= buffer.capacity();
  return buffer;
}

void ReleasedRx::recycle_payload(std::string&& buffer) {
  // Bounded like the look-ahead, so memory stays independent of the session.
  if (!recycle_ || buffer.capacity() == 0 ||
      spare_payloads_.size() >= kLookaheadRecords ||
      spare_bytes_ + buffer.capacity() > kLookaheadBytes) {
    return;
  }
  buffer.clear();
  spare_bytes_ += buffer.capacity();
  spare_payloads_.push_back(std::move(buffer));
}

void MismatchReport::accepted(std::string_view bytes) {
  if (bytes.size() >= kReplayContext) {
    history_.assign(bytes.substr(bytes.size() - kReplayContext));
    return;
  }
  history_.append(bytes);
  if (history_.size() > kReplayContext) {
    history_.erase(0, history_.size() - kReplayContext);
  }
}

// The lines every report begins with: what, where, and the bytes before.
std::string MismatchReport::heading(const std::string& title, std::uint64_t offset,
                                    std::uint64_t session_t_ns,
                                    const std::string& exchange_text) const {
  return "replay mismatch in " + file_ + ": " +
         (channel_.empty() ? "" : "channel " + channel_ + ": ") + title + "\n" +
         "  at tx byte offset " + std::to_string(offset) + ", session time " +
         session_seconds(session_t_ns) + " s, exchange " + exchange_text + "\n" +
         "  before:   " + hex_ascii(history_) + "\n";
}

void MismatchReport::raise(const std::string& title, std::uint64_t offset,
                           std::string_view expected, std::string_view actual,
                           std::uint64_t session_t_ns, std::int64_t exchange,
                           const std::string& extra, bool expected_is_datagram) const {
  raise_with(title, offset, expected, actual, session_t_ns, exchange,
             exchange >= 0 ? std::to_string(exchange) : std::string("-"), extra,
             expected_is_datagram);
}

void MismatchReport::raise_past_the_end(std::uint64_t offset, std::string_view actual,
                                        std::uint64_t session_t_ns, std::uint64_t first,
                                        std::int64_t last, std::string_view whose) const {
  const std::uint64_t held =
      last >= static_cast<std::int64_t>(first) ? static_cast<std::uint64_t>(last) + 1 - first : 0;
  const std::uint64_t next = first + held;
  std::string count = std::to_string(held) + " recorded exchange" + (held == 1 ? "" : "s");
  count += whose;
  if (held == 1) count += " (" + std::to_string(first) + ")";
  if (held > 1) count += " (" + std::to_string(first) + ".." + std::to_string(next - 1) + ")";
  raise_with("the client wrote more than the recording holds", offset, {}, actual,
             session_t_ns, static_cast<std::int64_t>(next),
             std::to_string(next) + ", past the " + count, {}, false);
}

void MismatchReport::raise_with(const std::string& title, std::uint64_t offset,
                                std::string_view expected, std::string_view actual,
                                std::uint64_t session_t_ns, std::int64_t exchange,
                                const std::string& exchange_text, const std::string& extra,
                                bool expected_is_datagram) const {
  std::ostringstream report;
  report << heading(title, offset, session_t_ns, exchange_text);
  report << "  expected: "
         << (expected.empty() && expected_is_datagram
                 ? std::string("(an empty datagram)")
             : expected.empty() && match_ == ReplayMatch::sequence
                 ? std::string("(nothing: the recorded writes end here)")
                 : hex_ascii(expected))
         << "\n"
         << "  actual:   " << hex_ascii(actual) << "\n"
         << extra;
  throw ReplayMismatch(report.str(), offset, session_t_ns, exchange);
}

void MismatchReport::raise_event(const std::string& title, std::uint64_t offset,
                                 std::uint64_t session_t_ns, std::int64_t exchange,
                                 const std::string& event_lines,
                                 std::string_view writes_next) const {
  std::ostringstream report;
  report << heading(title, offset, session_t_ns,
                    exchange >= 0 ? std::to_string(exchange) : std::string("-"));
  report << event_lines << "  recorded writes that follow: "
         << (writes_next.empty() ? std::string("(none: the recorded writes end here)")
                                 : hex_ascii(writes_next))
         << "\n";
  throw ReplayMismatch(report.str(), offset, session_t_ns, exchange);
}

std::string session_seconds(std::uint64_t ns) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6f", static_cast<double>(ns) / 1e9);
  return text;
}

std::size_t common_prefix(std::string_view a, std::string_view b) {
  const std::size_t limit = std::min(a.size(), b.size());
  std::size_t i = 0;
  while (i < limit && a[i] == b[i]) ++i;
  return i;
}

void Wildcards::add(std::size_t offset, std::size_t length) {
  if (length > 0) ranges_.emplace_back(offset, length);
}

void Wildcards::add_event(std::string_view payload) {
  json::Value event;
  try {
    event = json::parse(payload.empty() ? std::string_view("{}") : payload);
  } catch (const json::ParseError&) {
    return;
  }
  const json::Value* offset = event.find(event_field::offset);
  const json::Value* length = event.find(event_field::length);
  if (offset == nullptr || length == nullptr || offset->number < 0 || length->number < 0) {
    return;
  }
  add(static_cast<std::size_t>(offset->number),
      static_cast<std::size_t>(length->number));
}

bool Wildcards::covers(std::size_t position) const {
  for (const auto& [offset, length] : ranges_) {
    if (position >= offset && position - offset < length) return true;
  }
  return false;
}

void Wildcards::append_shifted(const Wildcards& other, std::size_t shift) {
  for (const auto& [offset, length] : other.ranges_) add(offset + shift, length);
}

std::size_t common_prefix(std::string_view recorded, std::string_view written,
                          const Wildcards& wildcards, std::size_t at) {
  if (wildcards.empty()) return common_prefix(recorded, written);
  const std::size_t limit = std::min(recorded.size(), written.size());
  std::size_t i = 0;
  while (i < limit && (recorded[i] == written[i] || wildcards.covers(at + i))) ++i;
  return i;
}

bool session_goes_on(RecordSource& source) {
  Record record;
  while (source.next(record)) {
    if ((record.kind == RecordKind::rx || record.kind == RecordKind::tx) &&
        !record.data.empty()) {
      return true;
    }
    if (record.kind == RecordKind::device_lost) return true;
  }
  return false;
}

}  // namespace wiretape::detail
