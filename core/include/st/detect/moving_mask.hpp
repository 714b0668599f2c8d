#pragma once
// The moving mask under its detect-stage name: the type lives in common (st/common/moving_mask.hpp), below
// the background statistics that use it too.
#include "st/common/moving_mask.hpp"

namespace st::detect {

using MovingMask = st::MovingMask;

}  // namespace st::detect
