// Protocol profiles (DESIGN.md section 13): what wiretape knows of a
// protocol. A profile cuts each direction's byte stream into frames, says
// which bytes of a request frame are compared when a replay matches it (its
// match key: fields that vary from run to run left out), fixes fields of a
// served response from the client's actual request, and names frames for
// `wiretape show`, `diff` and mismatch reports.
//
// `profile=NAME` finds a built-in profile or one registered with
// register_profile(). A profile of one's own implements Profile (and a
// Framer, or reuses BufferingFramer's buffering):
//
//   class MyProfile : public wiretape::Profile { ... };
//   wiretape::register_profile("mine", [] { return std::make_shared<MyProfile>(); });
//   auto port = wiretape::open_port("type=replay,file=s.wtape,match=request,profile=mine");
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace wiretape {

// The two byte streams of a session.
enum class StreamDirection {
  tx,  // host -> device: requests
  rx,  // device -> host: responses and unprompted data
};

// Why a frame ended.
enum class FrameEnd {
  delimited,   // by the protocol's own end of frame
  size_limit,  // at the framer's size limit: the input is not this protocol
  stream_end,  // the stream ended inside it (Framer::finish)
  broken,      // a bad length, a bad checksum, or bytes that begin no frame
};

struct Frame {
  std::string bytes;
  FrameEnd end = FrameEnd::delimited;
  // For a broken frame: what is wrong with it ("bad CRC 0x1234, computed
  // 0x4321"); empty otherwise.
  std::string problem;
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
  // For a framer that cuts frames by silence: how long without a byte ends
  // the frame being gathered. nullopt (the default): frames end by content.
  virtual std::optional<std::chrono::nanoseconds> quiet_gap() const { return std::nullopt; }
  // feed() of bytes that arrived at `t_ns` (a recording's record time, or
  // the time of a client's write). A framer that cuts by silence first ends
  // the frame being gathered if they came quiet_gap() or more after the
  // bytes before them; others ignore the time.
  virtual void feed_at(std::uint64_t t_ns, std::string_view bytes, std::vector<Frame>& frames) {
    (void)t_ns;
    feed(bytes, frames);
  }
};

// A frame never grows past this many bytes: hostile input (a stream with no
// delimiter, binary garbage) is cut into frames of this size, each marked
// FrameEnd::size_limit, so memory stays bounded.
inline constexpr std::size_t max_frame_bytes = 1 << 20;

// What every framer that cuts byte by byte shares: the kept bytes, cutting
// them into a frame, and the tail when the stream ends. A framer appends each
// byte to buffer_ and calls cut() where a frame ends.
class BufferingFramer : public Framer {
 public:
  std::optional<Frame> finish() override {
    if (buffer_.empty()) return std::nullopt;
    Frame frame{std::move(buffer_), tail_end(), {}};
    buffer_.clear();
    forget_frame();
    return frame;
  }
  std::size_t pending() const override { return buffer_.size(); }

 protected:
  void cut(FrameEnd end, std::vector<Frame>& frames, std::string problem = {}) {
    frames.push_back(Frame{std::move(buffer_), end, std::move(problem)});
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
  // The bytes of a request (tx) frame that are compared when matching:
  // fields that vary from run to run (sequence numbers, transaction ids,
  // checksums over them) left out.
  virtual std::string match_key(std::string_view request) const = 0;
  // A served response frame with the fields that follow the client's
  // request taken from `actual_request` (the client's frame) rather than
  // `recorded_request` (the frame it matched), checksums recomputed.
  // The default serves it unchanged.
  virtual std::string fix_response(std::string_view recorded_request,
                                   std::string_view actual_request,
                                   std::string_view response) const {
    (void)recorded_request;
    (void)actual_request;
    return std::string(response);
  }
  // Whether fix_response() may change anything (replay skips it if not).
  virtual bool fixes_responses() const { return false; }
  // `frame`, a whole frame of `direction`, with every checksum it carries
  // recomputed over its bytes as they are now. `wiretape edit --redact`
  // calls it for each frame whose bytes it scrubbed, so that the driver
  // that made a recording still accepts the scrubbed one (DESIGN.md
  // section 23). A frame that is not this protocol's, and a protocol
  // without checksums (the default), come back unchanged; the size never
  // changes.
  virtual std::string recompute_checksums(StreamDirection direction,
                                          std::string_view frame) const {
    (void)direction;
    return std::string(frame);
  }
  // A frame's short name (a command code) and its one-line description.
  virtual std::string frame_name(StreamDirection direction, std::string_view frame) const = 0;
  virtual std::string describe(StreamDirection direction, std::string_view frame) const = 0;
  // The name of the field holding byte `offset` of a request frame, for
  // mismatch reports ("unit id", "function code"); empty if unnamed.
  virtual std::string field_name(StreamDirection direction, std::string_view frame,
                                 std::size_t offset) const {
    (void)direction;
    (void)frame;
    (void)offset;
    return {};
  }
};

using ProfileFactory = std::function<std::shared_ptr<const Profile>()>;

// Makes `profile=name` find the profile `make` returns, in this process.
// Registering a name again replaces the earlier registration; a built-in
// name is refused (std::invalid_argument), as is an empty one.
void register_profile(const std::string& name, ProfileFactory make);

// The built-in profiles' names, in registry order (`scip` first), then the
// registered ones in the order they were registered.
std::vector<std::string> profile_names();

// The profile called `name`. Throws OptionError (key "profile") naming
// `name` and listing the known profiles.
std::shared_ptr<const Profile> find_profile(std::string_view name);

}  // namespace wiretape
