// Protocol profiles from Python: profile_names(), find_profile(name) and the
// Profile it returns (framing, match keys, names, and a whole session
// decoded for `wiretape show`).
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <nanobind/stl/optional.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/unique_ptr.h>
#include <nanobind/stl/vector.h>

#include "python/bindings.hpp"
#include "python/text_caster.hpp"
#include "replay/profile.hpp"
#include "replay/profiles/declared.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"
#include "wiretape/session.hpp"

namespace nb = nanobind;
using namespace nb::literals;

namespace wiretape::python {

namespace {

using detail::DecodedItem;
using detail::Profile;
using detail::SessionDecoder;
using detail::StreamDirection;

struct PyProfile {
  std::shared_ptr<const Profile> profile;
  std::string options;  // the replay keys that give it (detail::ProfileSpec::options)
};

StreamDirection direction_from_python(const std::string& direction) {
  if (direction == "tx") return StreamDirection::tx;
  if (direction == "rx") return StreamDirection::rx;
  throw nb::value_error(("direction must be 'tx' or 'rx', not '" + direction + "'").c_str());
}

std::string_view view_of(const nb::bytes& data) { return {data.c_str(), data.size()}; }

nb::bytes to_bytes(std::string_view data) { return nb::bytes(data.data(), data.size()); }

// A profile's text (a frame's name or description) as str. Built-in profiles
// escape the device bytes they show, so their text is UTF-8; a profile of
// one's own may not: its stray bytes come out as \xNN instead of the
// conversion error nanobind would raise for them.
nb::str to_text(std::string_view text) {
  PyObject* str = PyUnicode_DecodeUTF8(text.data(), static_cast<Py_ssize_t>(text.size()),
                                       "backslashreplace");
  if (str == nullptr) throw nb::python_error();
  return nb::steal<nb::str>(str);
}

// A record from an iterable: anything with t_ns, kind and data, as
// SessionReader's records and show's own record views have.
struct RecordFields {
  std::uint64_t t_ns = 0;
  nb::object kind;
  nb::bytes data;
};

RecordFields record_fields(nb::handle record) {
  for (const char* name : {"t_ns", "kind", "data"}) {
    if (!nb::hasattr(record, name)) {
      throw nb::type_error(("decode_session: a record needs t_ns, kind and data; " +
                            std::string(nb::repr(record).c_str()) + " has no " + name)
                               .c_str());
    }
  }
  nb::object t_ns = record.attr("t_ns");
  nb::object data = record.attr("data");
  std::uint64_t t = 0;
  if (!PyLong_Check(t_ns.ptr()) || !nb::try_cast<std::uint64_t>(t_ns, t)) {
    throw nb::type_error(("decode_session: a record's t_ns must be an integer 0..2**64-1, not " +
                          std::string(nb::repr(t_ns).c_str()))
                             .c_str());
  }
  if (!nb::isinstance<nb::bytes>(data)) {
    throw nb::type_error(("decode_session: a record's data must be bytes, not " +
                          std::string(nb::type_name(data.type()).c_str()))
                             .c_str());
  }
  return RecordFields{t, record.attr("kind"), nb::borrow<nb::bytes>(data)};
}

// (t_ns, kind, bytes, description): a frame, or an event with None.
nb::object item_tuple(const DecodedItem& item, nb::object kind) {
  nb::object description = item.is_frame ? nb::object(to_text(item.description)) : nb::none();
  return nb::make_tuple(item.t_ns, kind, to_bytes(item.bytes), description);
}

// Iterates a session decoded with a profile: from a session file read here,
// or from any iterable of records (objects with t_ns, kind and data, as
// SessionReader yields). Memory holds one record's frames at a time.
class DecodedSession {
 public:
  DecodedSession(std::shared_ptr<const Profile> profile, nb::handle source)
      : decoder_(std::move(profile)) {
    if (nb::isinstance<nb::str>(source) || nb::isinstance<nb::bytes>(source) ||
        nb::hasattr(source, "__fspath__")) {
      PyObject* fspath = PyOS_FSPath(source.ptr());
      if (fspath == nullptr) throw nb::python_error();
      nb::object path = nb::steal(fspath);
      const std::string p = nb::isinstance<nb::bytes>(path)
                                ? std::string(view_of(nb::borrow<nb::bytes>(path)))
                                : nb::cast<std::string>(path);
      nb::gil_scoped_release release;
      reader_ = std::make_unique<SessionReader>(p);
    } else {
      records_ = nb::iter(source);
    }
  }

  nb::object next() {
    while (ready_.empty() && !finished_) pull();
    if (ready_.empty()) throw nb::stop_iteration();
    nb::object item = std::move(ready_.front());
    ready_.pop_front();
    return item;
  }

  std::optional<SessionError> damage() const {
    if (reader_ && reader_->damage()) return *reader_->damage();
    return std::nullopt;
  }

 private:
  void pull() {
    decoded_.clear();
    if (reader_) {
      bool more = false;
      {
        nb::gil_scoped_release release;
        more = reader_->next(record_);
        if (more) {
          decoder_.feed(record_, decoded_);
        } else {
          decoder_.finish(decoded_);
        }
      }
      finished_ = !more;
      queue_decoded();
      return;
    }
    PyObject* next = PyIter_Next(records_.ptr());
    if (next == nullptr) {
      if (PyErr_Occurred()) throw nb::python_error();
      finished_ = true;
      decoder_.finish(decoded_);
      queue_decoded();
      return;
    }
    const RecordFields record = record_fields(nb::steal(next));
    const std::optional<RecordKind> known =
        nb::isinstance<nb::str>(record.kind)
            ? record_kind_from_string(nb::cast<std::string>(record.kind))
            : std::nullopt;
    if (known != RecordKind::tx && known != RecordKind::rx) {
      // Events keep the kind as given (kinds this version does not name too).
      DecodedItem event;
      event.t_ns = record.t_ns;
      event.bytes = std::string(view_of(record.data));
      ready_.push_back(item_tuple(event, record.kind));
      return;
    }
    decoder_.feed(record.t_ns, *known, view_of(record.data), decoded_);
    queue_decoded();
  }

  void queue_decoded() {
    for (const DecodedItem& item : decoded_) {
      const std::string_view kind = to_string(item.kind);
      ready_.push_back(item_tuple(item, nb::str(kind.data(), kind.size())));
    }
  }

  SessionDecoder decoder_;
  std::unique_ptr<SessionReader> reader_;
  nb::object records_;
  Record record_;
  std::deque<DecodedItem> decoded_;
  std::deque<nb::object> ready_;
  bool finished_ = false;
};

// One direction's framer, fed piece by piece (wiretape edit reseals the
// frames it scrubbed as the records come).
class PyFramer {
 public:
  // (bytes, how it ended)
  using FrameTuple = std::pair<nb::bytes, std::string>;

  explicit PyFramer(std::unique_ptr<detail::Framer> framer) : framer_(std::move(framer)) {}

  std::vector<FrameTuple> feed(nb::bytes data, std::uint64_t t_ns) {
    frames_.clear();
    framer_->feed_at(t_ns, view_of(data), frames_);
    std::vector<FrameTuple> out;
    out.reserve(frames_.size());
    for (const detail::Frame& frame : frames_) out.push_back(frame_tuple(frame));
    return out;
  }

  std::optional<FrameTuple> finish() {
    std::optional<detail::Frame> tail = framer_->finish();
    if (!tail) return std::nullopt;
    return frame_tuple(*tail);
  }

  std::size_t pending() const { return framer_->pending(); }

 private:
  static FrameTuple frame_tuple(const detail::Frame& frame) {
    return {to_bytes(frame.bytes), frame_end_name(frame.end)};
  }
  static std::string frame_end_name(detail::FrameEnd end) {
    switch (end) {
      case detail::FrameEnd::delimited: return "delimited";
      case detail::FrameEnd::size_limit: return "size_limit";
      case detail::FrameEnd::stream_end: return "stream_end";
      case detail::FrameEnd::broken: return "broken";
    }
    return "broken";
  }

  std::unique_ptr<detail::Framer> framer_;
  std::vector<detail::Frame> frames_;  // reused
};

}  // namespace

namespace {

// A Python callable held by a profile that may outlive the interpreter's
// threads: released under the GIL, and not at all once Python is gone.
class HeldCallable {
 public:
  explicit HeldCallable(nb::handle callable) : callable_(callable.ptr()) {
    Py_XINCREF(callable_);
  }
  ~HeldCallable() {
    if (callable_ == nullptr || !Py_IsInitialized()) return;
    nb::gil_scoped_acquire gil;
    Py_DECREF(callable_);
  }
  HeldCallable(const HeldCallable&) = delete;
  HeldCallable& operator=(const HeldCallable&) = delete;
  explicit operator bool() const { return callable_ != nullptr; }
  nb::handle get() const { return callable_; }

 private:
  PyObject* callable_;
};

std::string bytes_result(nb::handle result, const char* what) {
  if (!nb::isinstance<nb::bytes>(result)) {
    throw std::invalid_argument(std::string(what) + " must return bytes, not " +
                                nb::cast<std::string>(nb::str(result.type().attr("__name__"))));
  }
  const nb::bytes bytes = nb::borrow<nb::bytes>(result);
  return std::string(bytes.c_str(), bytes.size());
}

// A profile whose match key and response fix are Python callables, framing
// and names those of a base profile (DESIGN.md section 13). The replay calls
// it from whatever thread serves the client, so each call takes the GIL.
class CallableProfile final : public Profile {
 public:
  CallableProfile(std::string name, std::shared_ptr<const Profile> base, nb::handle match_key,
                  nb::handle fix_response)
      : name_(std::move(name)),
        base_(std::move(base)),
        match_key_(match_key.is_none() ? nb::handle() : match_key),
        fix_response_(fix_response.is_none() ? nb::handle() : fix_response) {}

  std::string_view name() const override { return name_; }
  std::string_view summary() const override { return base_->summary(); }
  std::unique_ptr<detail::Framer> make_framer(StreamDirection direction) const override {
    return base_->make_framer(direction);
  }
  std::string match_key(std::string_view request) const override {
    if (!match_key_) return base_->match_key(request);
    nb::gil_scoped_acquire gil;
    return bytes_result(match_key_.get()(nb::bytes(request.data(), request.size())),
                        "match_key");
  }
  bool fixes_responses() const override {
    return static_cast<bool>(fix_response_) || base_->fixes_responses();
  }
  std::string fix_response(std::string_view recorded, std::string_view actual,
                           std::string_view response) const override {
    if (!fix_response_) return base_->fix_response(recorded, actual, response);
    nb::gil_scoped_acquire gil;
    return bytes_result(fix_response_.get()(nb::bytes(recorded.data(), recorded.size()),
                                            nb::bytes(actual.data(), actual.size()),
                                            nb::bytes(response.data(), response.size())),
                        "fix_response");
  }
  std::string recompute_checksums(StreamDirection direction,
                                  std::string_view frame) const override {
    return base_->recompute_checksums(direction, frame);
  }
  std::string frame_name(StreamDirection direction, std::string_view frame) const override {
    return base_->frame_name(direction, frame);
  }
  std::string describe(StreamDirection direction, std::string_view frame) const override {
    return base_->describe(direction, frame);
  }
  std::string field_name(StreamDirection direction, std::string_view frame,
                         std::size_t offset) const override {
    return base_->field_name(direction, frame, offset);
  }

 private:
  std::string name_;
  std::shared_ptr<const Profile> base_;
  HeldCallable match_key_;
  HeldCallable fix_response_;
};

}  // namespace

void bind_profile(nb::module_& m) {
  nb::class_<PyProfile>(m, "Profile",
                        "What wiretape knows of a protocol: how each direction is cut into "
                        "frames, the bytes of a request compared when matching, and frame "
                        "names. Get one with profile_from_spec(text).")
      .def_prop_ro("name", [](const PyProfile& p) { return std::string(p.profile->name()); })
      .def_prop_ro("options", [](const PyProfile& p) { return p.options; },
                   "the replay keys that give this profile: 'profile=NAME', or a declared "
                   "profile's 'framing=...[,echo=...]' (for a replay's option string and "
                   "session_exchanges(options=))")
      .def_prop_ro("summary", [](const PyProfile& p) { return std::string(p.profile->summary()); })
      .def(
          "frames",
          [](const PyProfile& p, const std::string& direction, nb::bytes data) {
            auto framer = p.profile->make_framer(direction_from_python(direction));
            std::vector<detail::Frame> frames;
            framer->feed(view_of(data), frames);
            if (auto tail = framer->finish()) frames.push_back(std::move(*tail));
            nb::list out;
            for (const detail::Frame& frame : frames) out.append(to_bytes(frame.bytes));
            return out;
          },
          "direction"_a, "data"_a,
          "The frames of one direction's whole byte stream ('tx' or 'rx'); an "
          "incomplete tail is the last frame.")
      .def(
          "framer",
          [](const PyProfile& p, const std::string& direction) {
            return std::make_unique<PyFramer>(
                p.profile->make_framer(direction_from_python(direction)));
          },
          "direction"_a,
          "A new framer for one direction's stream ('tx' or 'rx'), fed piece by piece.")
      .def(
          "recompute_checksums",
          [](const PyProfile& p, const std::string& direction, nb::bytes frame) {
            return to_bytes(
                p.profile->recompute_checksums(direction_from_python(direction), view_of(frame)));
          },
          "direction"_a, "frame"_a,
          "The whole frame with every checksum it carries recomputed over its bytes as they "
          "are now (same size); unchanged for a protocol without checksums or a frame that "
          "is not this protocol's.")
      .def(
          "match_key",
          [](const PyProfile& p, nb::bytes request) {
            return to_bytes(p.profile->match_key(view_of(request)));
          },
          "request"_a, "The bytes of a request frame that are compared when matching.")
      .def(
          "frame_name",
          [](const PyProfile& p, const std::string& direction, nb::bytes frame) {
            return to_text(p.profile->frame_name(direction_from_python(direction), view_of(frame)));
          },
          "direction"_a, "frame"_a, "The frame's short name (for SCIP, the command code).")
      .def(
          "describe",
          [](const PyProfile& p, const std::string& direction, nb::bytes frame) {
            return to_text(p.profile->describe(direction_from_python(direction), view_of(frame)));
          },
          "direction"_a, "frame"_a, "The frame's one-line description, as show prints it.")
      .def(
          "decode_session",
          [](const PyProfile& p, nb::handle source) {
            return std::make_unique<DecodedSession>(p.profile, source);
          },
          "source"_a,
          "Decodes a session for show: `source` is a session file's path or an iterable "
          "of records. Yields (t_ns, kind, data, description): frames of 'tx' and 'rx' "
          "(re-assembled however the recording split them; t_ns is that of the frame's "
          "first byte) with their description, once complete; events as they come, with "
          "their payload and None. Frames incomplete at the end come last, rx before tx.")
      .def("__repr__",
           [](const PyProfile& p) { return "<Profile " + std::string(p.profile->name()) + ">"; });

  nb::class_<PyFramer>(m, "Framer",
                       "Cuts one direction's byte stream into frames, however it is split "
                       "into feed() calls. Get one with Profile.framer(direction).")
      .def("feed", &PyFramer::feed, "data"_a, "t_ns"_a = 0,
           "The next bytes of the stream, which arrived at t_ns (for framers that cut by "
           "silence): the frames they complete, as (bytes, end) with end one of "
           "'delimited', 'size_limit', 'stream_end', 'broken'.")
      .def("finish", &PyFramer::finish,
           "The stream has ended: the kept tail as a last (bytes, end), or None.")
      .def_prop_ro("pending", &PyFramer::pending, "How many bytes are kept for the next frame.");

  nb::class_<DecodedSession>(m, "DecodedSession",
                             "The items of a session decoded with a profile (an iterator).")
      .def("__iter__", [](nb::handle self) { return self; })
      .def("__next__", &DecodedSession::next)
      .def_prop_ro(
          "damage",
          [](const DecodedSession& self) -> nb::object {
            const auto damage = self.damage();
            if (!damage) return nb::none();
            nb::object cls = nb::module_::import_("wiretape._core").attr("SessionError");
            nb::object error = cls(std::string(damage->what()), damage->offset());
            error.attr("message") = std::string(damage->what());
            return error;
          },
          "None, or a SessionError (not raised) saying where reading a session file "
          "stopped");

  m.def("profile_names", &detail::profile_names,
        "The built-in protocol profiles' names, `scip` first, then registered ones.");
  m.def(
      "register_callable_profile",
      [](const std::string& name, const std::string& base, nb::object match_key,
         nb::object fix_response) {
        for (nb::handle callable : {match_key, fix_response}) {
          if (!callable.is_none() && !PyCallable_Check(callable.ptr())) {
            throw nb::type_error("match_key and fix_response must be callables or None");
          }
        }
        std::shared_ptr<const Profile> framing = detail::find_profile(base);
        auto profile = std::make_shared<const CallableProfile>(name, framing, match_key,
                                                               fix_response);
        register_profile(name, [profile] { return profile; });
      },
      "name"_a, "base"_a, "match_key"_a = nb::none(), "fix_response"_a = nb::none(),
      "Registers `name` for profile=: the framing and names of the profile `base`, "
      "the match key match_key(request: bytes) -> bytes and the response fix "
      "fix_response(recorded_request, actual_request, response) -> bytes, where given "
      "(None: the base profile's). The callables are called with the GIL from the "
      "thread that serves the client.");
  m.def(
      "declared_profile",
      [](const std::string& options) {
        Options parsed = Options::parse(options);
        const std::string keys = parsed.to_string();
        parsed.set_port_type("replay");
        std::shared_ptr<const Profile> profile = detail::take_declared_profile(parsed);
        if (!profile) {
          throw OptionError("framing", "a declared profile needs framing= (and may have "
                                       "ignore=, echo=, checksum=), not '" + options + "'");
        }
        for (const Options::Entry& entry : parsed.entries()) {
          if (entry.key != "framing" && entry.key != "ignore" && entry.key != "echo" &&
              entry.key != "checksum") {
            throw OptionError(entry.key, "option '" + entry.key +
                                             "' is not a declared profile's key (framing=, "
                                             "ignore=, echo=, checksum=)");
          }
        }
        return PyProfile{profile, keys};
      },
      "options"_a,
      "The profile declared by 'framing=...[,ignore=...][,echo=...][,checksum=...]' "
      "(docs/replay.md); OptionError naming the key for a bad spec or another key.");
  m.def(
      "find_profile",
      [](const std::string& name) {
        return PyProfile{detail::find_profile(name), "profile=" + quote_option_value(name)};
      },
      "name"_a, "The built-in profile called `name`; OptionError for an unknown name.");
  m.def(
      "profile_from_spec",
      [](std::string_view text) {
        detail::ProfileSpec read = detail::profile_from_spec(text);
        return PyProfile{std::move(read.profile), std::move(read.options)};
      },
      "text"_a,
      "The profile a --profile value stands for, by the replay's rule: text with no "
      "'=' is a name ('scip', as profile=scip), else the replay keys profile=, "
      "framing=, ignore=, echo=, checksum= ('framing=fixed:10,echo=0:2'). OptionError "
      "naming the key for an empty spec, another key, a bad spec or an unknown name.");
}

}  // namespace wiretape::python
