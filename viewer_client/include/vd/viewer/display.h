#pragma once
// Whether a window can be opened. OpenCV's highgui (Qt) aborts the whole process when it cannot
// reach a display, so the viewer checks first: $DISPLAY / $WAYLAND_DISPLAY must be set and the
// server behind it must accept a connection.
#include <string>

#include "vd/common/status.h"

namespace vd {

struct X11Display {
  // Empty (or "unix") for the local socket /tmp/.X11-unix/X<number>; else a TCP host.
  std::string host;
  // Display number; the TCP port is 6000 + number.
  int number = 0;
};

// Parses "[host]:number[.screen]" as found in $DISPLAY.
StatusOr<X11Display> ParseX11Display(const std::string& text);

// Ok when $DISPLAY names a reachable X server or $WAYLAND_DISPLAY a reachable compositor socket;
// otherwise FailedPrecondition saying what is missing (for the "falling back to headless" line).
Status CheckDisplay();

}  // namespace vd
