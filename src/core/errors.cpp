#include "wiretape/errors.hpp"

namespace wiretape {

std::string system_error_message(const std::string& context, int errno_value) {
  if (errno_value == 0) return context;
  // strerror() is not thread-safe; the category's message() is.
  const std::string text = std::generic_category().message(errno_value);
  if (context.find(text) != std::string::npos) return context;
  if (context.empty()) return text;
  return context + ": " + text;
}

}  // namespace wiretape
