// A profile's response fixes (Profile::fix_response) applied frame by frame
// (DESIGN.md section 17): the served rx is framed with the profile's rx
// framer, each response frame is fixed from the client's request it answers
// and written back at the frame's own offsets, so a frame split over several
// rx records, or several frames in one record, is fixed as the device would
// have sent it. Records keep their times and boundaries; a record is held
// back only until the frames its bytes belong to are complete, or the
// response ends; a frame that is not whole (the response ends inside it, or
// the profile finds it broken) is served as recorded.
// Both match strategies use it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "replay/profile.hpp"
#include "replay/strategy.hpp"

namespace wiretape::detail {

class ResponseFixer {
 public:
  // `profile` must fix responses (Profile::fixes_responses()).
  explicit ResponseFixer(std::shared_ptr<const Profile> profile);

  // The client wrote `actual`, which stands for the recorded request frame
  // `recorded`. `position` orders requests and responses: a response pushed
  // with `after` >= position may answer it (match=sequence: recorded tx
  // bytes up to the request's end; match=request: matches so far).
  void request(std::uint64_t position, std::string_view recorded, std::string_view actual);

  // The next released item of the response to the requests up to `after`.
  // A record that is not rx ends the response and passes through.
  void push(RxItem&& item, std::uint64_t after);
  // The response goes no further (the next request is due, the client must
  // act before more is released, or the session ended): everything held is
  // given out, a frame it ends inside as recorded (a fix applies to whole
  // frames only).
  void end_response();

  // Items ready to serve, in recorded order.
  bool ready() const { return ready_ > 0; }
  RxItem take();
  // Items held back (waiting for the rest of a frame).
  bool holding() const { return held_.size() > ready_; }
  std::uint64_t held_after() const { return held_.back().after; }
  // rx bytes and records held back, for the unused-data report.
  std::uint64_t held_rx_bytes() const;
  std::uint64_t held_rx_records() const { return held_.size() - ready_; }

 private:
  struct Held {
    RxItem item;
    std::uint64_t offset = 0;  // of its first byte in the rx stream
    std::uint64_t after = 0;
  };
  struct Request {
    std::uint64_t position = 0;
    std::string recorded;
    std::string actual;
    bool answered = false;
  };
  // Fixes `frame`, which begins at stream offset `start`, if it is whole.
  void fix_frame(const Frame& frame, std::uint64_t start);
  // The request the response frame `bytes`, pushed after `after`, answers.
  const Request* answered_by(std::string_view bytes, std::uint64_t after);
  void mark_ready();

  std::shared_ptr<const Profile> profile_;
  std::unique_ptr<Framer> framer_;
  std::vector<Frame> frames_;  // reused
  std::deque<Held> held_;
  std::size_t ready_ = 0;             // the first ready_ of held_
  std::uint64_t stream_end_ = 0;      // rx bytes pushed
  std::uint64_t frame_start_ = 0;     // of the frame being gathered
  std::deque<Request> requests_;
};

}  // namespace wiretape::detail
