// The one place where wiretape's version is defined: CMake and pyproject.toml
// both read it from here.
#pragma once

#define WIRETAPE_VERSION_MAJOR 0
#define WIRETAPE_VERSION_MINOR 1
#define WIRETAPE_VERSION_PATCH 0
#define WIRETAPE_VERSION_STRING "0.1.0"

namespace wiretape {
inline constexpr const char* version = WIRETAPE_VERSION_STRING;
}  // namespace wiretape
