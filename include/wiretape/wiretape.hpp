// Everything of wiretape's public C++ API.
#pragma once

#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"
#include "wiretape/port.hpp"
#include "wiretape/timeout.hpp"
#include "wiretape/version.hpp"
