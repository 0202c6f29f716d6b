// The `lines` profile: text protocols whose frames end with a delimiter
// (default LF), in both directions. A frame is one line, delimiter included.
#include <utility>

#include "replay/profiles/builtin.hpp"
#include "util/hex.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

namespace {

// A frame's name is its line, escaped, up to this many bytes.
constexpr std::size_t name_bytes = 40;
// Descriptions show as much of a line as `wiretape show` shows of a record.
constexpr std::size_t description_bytes = 64;

bool ends_with(std::string_view text, std::string_view suffix) {
  return text.size() >= suffix.size() && text.substr(text.size() - suffix.size()) == suffix;
}

class DelimiterFramer final : public BufferingFramer {
 public:
  explicit DelimiterFramer(std::string delimiter) : delimiter_(std::move(delimiter)) {}

  void feed(std::string_view bytes, std::vector<Frame>& frames) override {
    for (char byte : bytes) {
      buffer_ += byte;
      if (byte == delimiter_.back() && ends_with(buffer_, delimiter_)) {
        cut(FrameEnd::delimited, frames);
      } else if (buffer_.size() >= max_frame_bytes) {
        // A delimiter straddling this cut is not seen: the input was not
        // lines of a sane length anyway.
        cut(FrameEnd::size_limit, frames);
      }
    }
  }

 private:
  std::string delimiter_;
};

class LinesProfile final : public Profile {
 public:
  explicit LinesProfile(std::string delimiter) : delimiter_(std::move(delimiter)) {}

  std::string_view name() const override { return "lines"; }

  std::string_view summary() const override {
    return "text lines ending with a delimiter (default LF), both directions";
  }

  std::unique_ptr<Framer> make_framer(StreamDirection) const override {
    return std::make_unique<DelimiterFramer>(delimiter_);
  }

  // The line without its delimiter.
  std::string match_key(std::string_view request) const override {
    return std::string(without_delimiter(request));
  }

  std::string frame_name(StreamDirection, std::string_view frame) const override {
    return escape_bytes(without_delimiter(frame), name_bytes);
  }

  std::string describe(StreamDirection, std::string_view frame) const override {
    return escape_bytes(frame, description_bytes);
  }

 private:
  std::string_view without_delimiter(std::string_view frame) const {
    if (ends_with(frame, delimiter_)) frame.remove_suffix(delimiter_.size());
    return frame;
  }

  std::string delimiter_;
};

}  // namespace

std::shared_ptr<const Profile> make_lines_profile(std::string delimiter) {
  if (delimiter.empty()) {
    throw OptionError("delimiter", "profile 'lines': the delimiter is empty; give at least one byte "
                                   "(the default is LF)");
  }
  return std::make_shared<LinesProfile>(std::move(delimiter));
}

std::shared_ptr<const Profile> make_default_lines_profile() { return make_lines_profile("\n"); }

}  // namespace wiretape::detail
