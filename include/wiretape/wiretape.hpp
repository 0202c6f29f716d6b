// Everything of wiretape's public C++ API (the test helpers of
// wiretape/testing.hpp are included on their own, by tests).
#pragma once

#include "wiretape/attach.hpp"
#include "wiretape/bridge.hpp"
#include "wiretape/device_identity.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/fuzzing.hpp"
#include "wiretape/options.hpp"
#include "wiretape/port.hpp"
#include "wiretape/profile.hpp"
#include "wiretape/recorder.hpp"
#include "wiretape/session.hpp"
#include "wiretape/timeout.hpp"
#include "wiretape/version.hpp"
