// Protocol profiles (DESIGN.md section 13): what wiretape knows of a
// protocol. A profile cuts each direction's byte stream into frames, says
// which bytes of a request frame are compared when matching, and names
// frames for show, diff and mismatch reports.
//
// The interface is public (wiretape/profile.hpp); this header adds what
// show and diff use: decoding a whole session.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "wiretape/options.hpp"
#include "wiretape/profile.hpp"
#include "wiretape/session.hpp"

namespace wiretape::detail {

using wiretape::BufferingFramer;
using wiretape::Frame;
using wiretape::FrameEnd;
using wiretape::Framer;
using wiretape::max_frame_bytes;
using wiretape::Profile;
using wiretape::StreamDirection;
using wiretape::find_profile;
using wiretape::profile_names;

std::string_view to_string(StreamDirection direction);

// Where `actual`, a request frame, first differs from `expected` in a byte
// that its match key holds (a byte the key leaves out, such as a
// transaction id, is no difference); nullopt when the keys are equal.
std::optional<std::size_t> first_key_difference(const Profile& profile,
                                                std::string_view expected,
                                                std::string_view actual);

// " (field 'address' differs)" for a mismatch report, or "".
std::string differing_field_text(const Profile& profile, std::string_view expected,
                                 std::string_view actual);

// A framer that also says when each frame began: the time of the record
// holding its first byte (only the first frame a record completes can have
// begun in an earlier record, as the framer's kept tail).
class TimedFramer {
 public:
  struct TimedFrame {
    Frame frame;
    std::uint64_t t_ns = 0;
  };
  explicit TimedFramer(std::unique_ptr<Framer> framer) : framer_(std::move(framer)) {}

  // Framer::feed_at(t_ns, bytes); appends the frames it completes to `out`.
  void feed(std::uint64_t t_ns, std::string_view bytes, std::vector<TimedFrame>& out);
  // Framer::finish(), with its time.
  std::optional<TimedFrame> finish();
  const Framer& framer() const { return *framer_; }

 private:
  std::unique_ptr<Framer> framer_;
  std::vector<Frame> scratch_;   // reused
  std::uint64_t tail_t_ns_ = 0;  // when the kept tail's first byte came
};

// One item of a decoded session: a frame of one direction, or an event
// record passed through where it came.
struct DecodedItem {
  std::uint64_t t_ns = 0;  // a frame's: the time of the record holding its first byte
  RecordKind kind = RecordKind::rx;
  std::string bytes;        // the frame, or the event's payload
  std::string description;  // a frame's description; empty for events
  bool is_frame = false;
};

// A session's records decoded with a profile, as `wiretape show` lists
// them: each direction is framed however the recording split it into
// records; a frame comes out once complete, an event as soon as it is read,
// so items come in the order they became known. Frames still incomplete at
// the end come out from finish(), rx before tx.
class SessionDecoder {
 public:
  explicit SessionDecoder(std::shared_ptr<const Profile> profile);

  // Appends to `out` what this record completes.
  void feed(const Record& record, std::deque<DecodedItem>& out);
  void feed(std::uint64_t t_ns, RecordKind kind, std::string_view data,
            std::deque<DecodedItem>& out);
  // The session has ended: appends the incomplete tails.
  void finish(std::deque<DecodedItem>& out);

 private:
  void emit(StreamDirection direction, std::uint64_t t_ns, Frame frame,
            std::deque<DecodedItem>& out) const;

  std::shared_ptr<const Profile> profile_;
  TimedFramer tx_;
  TimedFramer rx_;
  std::vector<TimedFramer::TimedFrame> frames_;  // reused between records
};

// The profile a replay's keys give, taking them: a built-in or registered one
// by profile=NAME, or one declared by framing= (with ignore=, echo=,
// checksum=); nullptr for neither. `options` reads the replay's rows
// (set_port_type("replay")). Both at once, a bad spec or an unknown name is an
// OptionError naming the key.
std::shared_ptr<const Profile> take_profile(Options& options);

// What a profile given by a person stands for (every --profile of the CLI).
struct ProfileSpec {
  std::shared_ptr<const Profile> profile;
  // The replay keys that give the same profile: `profile=NAME`, or the
  // declared profile's `framing=...[,ignore=...][,echo=...][,checksum=...]`.
  std::string options;
};

// `spec` read by the replay's own rule (take_profile): text with no `=` is a
// name, as profile=NAME (`scip`); else the replay keys profile=, framing=,
// ignore=, echo= and checksum= (`framing=fixed:10,echo=0:2`). Surrounding white
// space is ignored. OptionError naming the key for an empty spec, another
// key, or whatever take_profile refuses.
ProfileSpec profile_from_spec(std::string_view spec);

}  // namespace wiretape::detail
