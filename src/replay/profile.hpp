// Protocol profiles (DESIGN.md section 13): what wiretape knows of a
// protocol. A profile cuts each direction's byte stream into frames, says
// which bytes of a request frame are compared when matching, and names
// frames for show, diff and mismatch reports.
//
// Only framing and names are used yet; match keys will drive request
// matching in a later step, and response fixes (section 13, item 3) are not
// built: they will be one more virtual of Profile, taking the served
// response and the client's actual request.
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

#include "wiretape/session.hpp"

namespace wiretape::detail {

// The two byte streams of a session.
enum class StreamDirection {
  tx,  // host -> device: requests
  rx,  // device -> host: responses and unprompted data
};

std::string_view to_string(StreamDirection direction);

// Why a frame ended.
enum class FrameEnd {
  delimited,   // by the protocol's own end of frame
  size_limit,  // at the framer's size limit: the input is not this protocol
  stream_end,  // the stream ended inside it (Framer::finish)
};

struct Frame {
  std::string bytes;
  FrameEnd end = FrameEnd::delimited;
};

// Cuts one direction's byte stream into frames, incrementally: however the
// stream is split into feed() calls, the same frames come out. Frames are
// consecutive and cover every byte fed (no byte is dropped or repeated).
class Framer {
 public:
  virtual ~Framer() = default;
  // The next bytes of the stream: appends the frames they complete to
  // `frames`, in order, and keeps the incomplete tail.
  virtual void feed(std::string_view bytes, std::vector<Frame>& frames) = 0;
  // The stream has ended: the kept tail as a last frame (FrameEnd::stream_end),
  // if there is one. The framer is then as new.
  virtual std::optional<Frame> finish() = 0;
  // How many bytes are kept for the next frame.
  virtual std::size_t pending() const = 0;
};

// A frame never grows past this many bytes: hostile input (a stream with no
// delimiter, binary garbage) is cut into frames of this size, each marked
// FrameEnd::size_limit, so memory stays bounded. Real frames are far smaller
// (a SCIP ME scan of 1081 steps is about 7 KiB).
inline constexpr std::size_t max_frame_bytes = 1 << 20;

// What every framer that cuts byte by byte shares: the kept bytes, cutting
// them into a frame, and the tail when the stream ends. A framer appends each
// byte to buffer_ and calls cut() where a frame ends.
class BufferingFramer : public Framer {
 public:
  std::optional<Frame> finish() override {
    if (buffer_.empty()) return std::nullopt;
    Frame frame{std::move(buffer_), tail_end()};
    buffer_.clear();
    forget_frame();
    return frame;
  }
  std::size_t pending() const override { return buffer_.size(); }

 protected:
  void cut(FrameEnd end, std::vector<Frame>& frames) {
    frames.push_back(Frame{std::move(buffer_), end});
    buffer_.clear();
    forget_frame();
  }
  // What the kept bytes are when the stream ends: cut short, unless the
  // framer knows them complete.
  virtual FrameEnd tail_end() const { return FrameEnd::stream_end; }
  // Drops what the framer noted about the frame being gathered.
  virtual void forget_frame() {}

  std::string buffer_;
};

class Profile {
 public:
  virtual ~Profile() = default;
  virtual std::string_view name() const = 0;
  // One line for listings: what protocol this is.
  virtual std::string_view summary() const = 0;
  // A new framer for one direction's stream.
  virtual std::unique_ptr<Framer> make_framer(StreamDirection direction) const = 0;
  // The bytes of a request (tx) frame that are compared when matching.
  virtual std::string match_key(std::string_view request) const = 0;
  // A frame's short name (a command code) and its one-line description.
  virtual std::string frame_name(StreamDirection direction, std::string_view frame) const = 0;
  virtual std::string describe(StreamDirection direction, std::string_view frame) const = 0;
};

// The built-in profiles' names, in registry order (`scip` first).
std::vector<std::string> profile_names();

// The built-in profile called `name`. Throws OptionError (key "profile")
// naming `name` and listing the known profiles.
std::shared_ptr<const Profile> find_profile(std::string_view name);

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
  struct Stream {
    std::unique_ptr<Framer> framer;
    std::uint64_t tail_t_ns = 0;  // when the kept tail's first byte came
  };
  void emit(StreamDirection direction, std::uint64_t t_ns, Frame frame,
            std::deque<DecodedItem>& out) const;

  std::shared_ptr<const Profile> profile_;
  Stream tx_;
  Stream rx_;
  std::vector<Frame> frames_;  // reused between records
};

}  // namespace wiretape::detail
