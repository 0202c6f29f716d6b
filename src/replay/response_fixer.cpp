#include "replay/response_fixer.hpp"

#include <algorithm>
#include <utility>

namespace wiretape::detail {

namespace {

// Requests kept while no response answers them: a client that writes and is
// never answered (the recording has no rx there) must not grow the list.
constexpr std::size_t kMaxUnansweredRequests = 64;

}  // namespace

ResponseFixer::ResponseFixer(std::shared_ptr<const Profile> profile)
    : profile_(std::move(profile)), framer_(profile_->make_framer(StreamDirection::rx)) {}

void ResponseFixer::request(std::uint64_t position, std::string_view recorded,
                            std::string_view actual) {
  requests_.push_back({position, std::string(recorded), std::string(actual), false});
  while (requests_.size() > kMaxUnansweredRequests) requests_.pop_front();
}

void ResponseFixer::push(RxItem&& item, std::uint64_t after) {
  if (item.kind != RecordKind::rx) {
    end_response();
    held_.push_back({std::move(item), stream_end_, after});
    ready_ = held_.size();
    return;
  }
  if (item.view) {
    item.data.assign(item.view.bytes);
    item.view = PayloadView{};
  }
  const std::uint64_t offset = stream_end_;
  stream_end_ += item.data.size();
  held_.push_back({std::move(item), offset, after});
  frames_.clear();
  framer_->feed_at(held_.back().item.t_ns, held_.back().item.data, frames_);
  for (const Frame& frame : frames_) fix_frame(frame, frame_start_);
  mark_ready();
}

void ResponseFixer::end_response() {
  if (std::optional<Frame> tail = framer_->finish()) fix_frame(*tail, frame_start_);
  ready_ = held_.size();
}

RxItem ResponseFixer::take() {
  RxItem item = std::move(held_.front().item);
  held_.pop_front();
  --ready_;
  return item;
}

std::uint64_t ResponseFixer::held_rx_bytes() const {
  std::uint64_t bytes = 0;
  for (std::size_t i = ready_; i < held_.size(); ++i) bytes += held_[i].item.data.size();
  return bytes;
}

void ResponseFixer::mark_ready() {
  while (ready_ < held_.size() &&
         held_[ready_].offset + held_[ready_].item.data.size() <= frame_start_) {
    ++ready_;
  }
}

const ResponseFixer::Request* ResponseFixer::answered_by(std::string_view bytes,
                                                         std::uint64_t after) {
  std::size_t candidates = 0;
  while (candidates < requests_.size() && requests_[candidates].position <= after) {
    ++candidates;
  }
  if (candidates == 0) return nullptr;  // released before its request (timing=session)
  // Frames go to the requests not yet answered, oldest first (pipelined
  // requests); once all are answered, further frames answer the latest.
  // Among several unanswered, the one the recorded frame was the answer to
  // (fixing it from its own recorded request changes nothing) wins, so that a
  // request the device ignored is skipped.
  std::size_t chosen = candidates - 1;
  std::size_t unanswered = 0;
  for (std::size_t i = 0; i < candidates; ++i) {
    if (requests_[i].answered) continue;
    if (unanswered++ == 0) chosen = i;
  }
  if (unanswered > 1) {
    for (std::size_t i = 0; i < candidates; ++i) {
      const Request& request = requests_[i];
      if (request.answered) continue;
      if (profile_->fix_response(request.recorded, request.recorded, bytes) == bytes) {
        chosen = i;
        break;
      }
    }
  }
  requests_.erase(requests_.begin(),
                  requests_.begin() + static_cast<std::ptrdiff_t>(chosen));
  requests_.front().answered = true;
  return &requests_.front();
}

void ResponseFixer::fix_frame(const Frame& frame, std::uint64_t start) {
  const std::string& bytes = frame.bytes;
  const std::uint64_t end = start + bytes.size();
  frame_start_ = end;
  // A fix applies to whole frames only. A frame the response ends inside
  // (FrameEnd::stream_end) is all the device sent of it, and one the profile
  // finds broken is not its protocol's: both are served as recorded, as a
  // fix (a checksum recomputed over part of a frame) would invent bytes.
  if (frame.end != FrameEnd::delimited) return;
  auto first = std::find_if(held_.begin(), held_.end(), [&](const Held& held) {
    return held.item.kind == RecordKind::rx && held.offset + held.item.data.size() > start;
  });
  if (first == held_.end()) return;
  const Request* request = answered_by(bytes, first->after);
  if (request == nullptr) return;
  const std::string fixed = profile_->fix_response(request->recorded, request->actual, bytes);
  if (fixed == bytes) return;
  // Written back over the records that hold the frame, each keeping its
  // share; a fix that changes the frame's size changes its last record's.
  std::size_t used = 0;
  for (auto it = first; it != held_.end(); ++it) {
    std::string& data = it->item.data;
    const std::uint64_t held_end = it->offset + data.size();
    const std::size_t from = static_cast<std::size_t>(std::max(start, it->offset) - it->offset);
    const std::size_t to = static_cast<std::size_t>(std::min(end, held_end) - it->offset);
    const bool last = held_end >= end;
    const std::size_t take = last ? fixed.size() - used : std::min(to - from, fixed.size() - used);
    data.replace(from, to - from, fixed, used, take);
    used += take;
    if (last) break;
  }
  if (fixed.size() != bytes.size()) {
    for (auto it = first; it != held_.end(); ++it) {
      if (it != first) it->offset = std::prev(it)->offset + std::prev(it)->item.data.size();
    }
    stream_end_ = held_.back().offset + held_.back().item.data.size();
    frame_start_ = start + fixed.size();
  }
}

}  // namespace wiretape::detail
