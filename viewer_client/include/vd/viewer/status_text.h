#pragma once
// Text the viewer shows: the terminal status line, the window's overlay and the exit summary.
#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <vdeform/server_status_t.hpp>

#include "vd/common/messages.h"
#include "vd/viewer/receiver.h"
#include "vd/viewer/render.h"

namespace vd {

// "812 B", "3.4 KB", "12.0 MB".
std::string FormatBytes(int64_t bytes);

// One line: meshes received, seq, bytes, and the server's state, counters, fps and stage times.
std::string StatusLine(const ReceiverStats& stats, const std::optional<vdeform::server_status_t>& status);

// The window's overlay, a few short lines: state, frames processed/dropped, fps, per-stage ms,
// mesh size and the colouring in use (`requested` and what `used` fell back to).
std::vector<std::string> StatusOverlayLines(const ReceiverStats& stats,
                                            const std::optional<vdeform::server_status_t>& status,
                                            ColorMode requested, ColorMode used);

// Draws `lines` top-left on a translucent band so they stay legible over any mesh.
void DrawOverlay(cv::Mat& image, const std::vector<std::string>& lines);

// The exit summary: meshes received/decoded/failed, bytes, last seq, last status, and the paths
// written (all of them up to `max_paths`, else the first and last few and a count).
std::string SummaryText(const ReceiverStats& stats, const std::optional<vdeform::server_status_t>& status,
                        const std::vector<std::string>& written_paths, size_t max_paths = 20);

// The status line on stdout of vdeform-viewer and vdeform-web: refreshed in place four times a
// second on a terminal (cut to its width so it never wraps), one line a second otherwise (logs,
// pipes).
class StatusPrinter {
 public:
  explicit StatusPrinter(bool enabled);
  // Prints line() when the period has passed (line is called only then).
  void Tick(const std::function<std::string()>& line);
  // Ends the in-place line so what follows starts on a fresh one.
  void Finish();

 private:
  bool enabled_;
  bool tty_;
  bool printed_on_line_ = false;
  std::chrono::steady_clock::time_point last_{};
};

}  // namespace vd
