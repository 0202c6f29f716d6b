// The built-in profiles, each in a file of its own; profile.cpp lists them
// in the registry.
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <string_view>

#include "replay/profile.hpp"

namespace wiretape::detail {

// The bytes as one line of text for descriptions: printable ASCII kept,
// LF, CR, tab and backslash as \n \r \t \\, other bytes as \xHH; past
// `limit` bytes the rest is counted ("... (+N bytes)"). The same text as
// `wiretape show` gives a record's payload.
std::string printable_text(std::string_view bytes, std::size_t limit);

// Hokuyo SCIP 2.0 laser scanners (scip.cpp).
std::shared_ptr<const Profile> make_scip_profile();

}  // namespace wiretape::detail
