#include "vd/viewer/status_text.h"

#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <sstream>

#include <opencv2/imgproc.hpp>

namespace vd {
namespace {

std::string Fixed(double value, int decimals) {
  char text[64];
  std::snprintf(text, sizeof text, "%.*f", decimals, value);
  return text;
}

// The stage times of a status message, "name 1.2 name 3.4", bounded by the shortest array.
std::string StageTimes(const vdeform::server_status_t& status, size_t max_stages) {
  const size_t n = std::min({static_cast<size_t>(std::max(status.num_stages, 0)), status.stage_name.size(),
                             status.stage_ms_last.size(), max_stages});
  std::string out;
  for (size_t i = 0; i < n; ++i) {
    if (i) out += ' ';
    out += status.stage_name[i] + ' ' + Fixed(status.stage_ms_last[i], 1);
  }
  return out;
}

}  // namespace

std::string FormatBytes(int64_t bytes) {
  if (bytes < 1024) return std::to_string(bytes) + " B";
  if (bytes < 1024 * 1024) return Fixed(bytes / 1024.0, 1) + " KB";
  return Fixed(bytes / (1024.0 * 1024.0), 1) + " MB";
}

std::string StatusLine(const ReceiverStats& stats, const std::optional<vdeform::server_status_t>& status) {
  std::ostringstream os;
  os << "meshes " << stats.live_meshes;
  if (stats.canonical_meshes) os << " +" << stats.canonical_meshes << " canon";
  if (stats.tracked_meshes) os << " +" << stats.tracked_meshes << " tracked";
  if (stats.meshes_failed) os << " failed " << stats.meshes_failed;
  if (stats.last_live_seq >= 0)
    os << " seq " << stats.last_live_seq << " (" << stats.last_live_triangles << " tri)";
  os << " " << FormatBytes(stats.mesh_bytes);
  const int64_t refused = stats.meshes_refused.total() + stats.status_refused.total();
  if (refused) os << " refused " << refused << " (not signed by the server)";
  if (!status) {
    os << " | server: no status yet";
    return os.str();
  }
  os << " | " << ServerStateName(status->state) << " proc " << status->frames_processed << " drop "
     << status->frames_dropped;
  if (status->frames_rejected) os << " rej " << status->frames_rejected;
  os << " " << Fixed(status->fps, 1) << " fps";
  if (status->latency_ms_p50 > 0)
    os << " lat " << Fixed(status->latency_ms_p50, 0) << "/" << Fixed(status->latency_ms_p95, 0) << " ms";
  const std::string stages = StageTimes(*status, 16);
  if (!stages.empty()) os << " | ms: " << stages;
  return os.str();
}

std::vector<std::string> StatusOverlayLines(const ReceiverStats& stats,
                                            const std::optional<vdeform::server_status_t>& status,
                                            ColorMode requested, ColorMode used) {
  std::vector<std::string> lines;
  if (status) {
    std::string state = "server " + ServerStateName(status->state);
    if (!status->message.empty()) state += ": " + status->message.substr(0, 60);
    lines.push_back(state);
    lines.push_back("frames processed " + std::to_string(status->frames_processed) + "  dropped " +
                    std::to_string(status->frames_dropped) + "  rejected " + std::to_string(status->frames_rejected) +
                    "  " + Fixed(status->fps, 1) + " fps");
    if (status->latency_ms_p50 > 0)
      lines.push_back("latency p50 " + Fixed(status->latency_ms_p50, 0) + " ms  p95 " +
                      Fixed(status->latency_ms_p95, 0) + " ms");
    // Stage times, a few per line so each line fits a 640-pixel window.
    const size_t n = std::min({static_cast<size_t>(std::max(status->num_stages, 0)), status->stage_name.size(),
                               status->stage_ms_last.size()});
    std::string line;
    for (size_t i = 0; i < n; ++i) {
      const std::string item = status->stage_name[i] + " " + Fixed(status->stage_ms_last[i], 1) + " ms";
      if (!line.empty() && line.size() + item.size() > 56) {
        lines.push_back(line);
        line.clear();
      }
      line += (line.empty() ? "" : "  ") + item;
    }
    if (!line.empty()) lines.push_back(line);
  } else {
    lines.push_back("server: no status yet");
  }
  std::string mesh = "mesh ";
  mesh += stats.last_live_seq >= 0 ? "seq " + std::to_string(stats.last_live_seq) + "  " +
                                         std::to_string(stats.last_live_vertices) + " vertices  " +
                                         std::to_string(stats.last_live_triangles) + " triangles"
                                   : "none yet";
  if (stats.meshes_failed) mesh += "  failed " + std::to_string(stats.meshes_failed);
  lines.push_back(mesh);
  const int64_t refused = stats.meshes_refused.total() + stats.status_refused.total();
  if (refused) lines.push_back("refused " + std::to_string(refused) + " messages not signed by the server");
  std::string colour = std::string("colour ") + ColorModeName(requested);
  if (used != requested) {
    colour += std::string(" (showing ") + ColorModeName(used);
    if (requested == ColorMode::kCanonical) colour += ": no canonical mesh of this frame";
    colour += ")";
  }
  lines.push_back(colour);
  lines.push_back("c colour  r reset  q quit  drag rotate  wheel zoom");
  return lines;
}

void DrawOverlay(cv::Mat& image, const std::vector<std::string>& lines) {
  if (image.empty() || lines.empty()) return;
  const int font = cv::FONT_HERSHEY_SIMPLEX;
  const double scale = 0.45;
  const int line_height = 17;
  int width = 0;
  for (const auto& line : lines) {
    int baseline = 0;
    width = std::max(width, cv::getTextSize(line, font, scale, 1, &baseline).width);
  }
  const cv::Rect band = cv::Rect(0, 0, std::min(image.cols, width + 12),
                                 std::min(image.rows, static_cast<int>(lines.size()) * line_height + 8)) &
                        cv::Rect(0, 0, image.cols, image.rows);
  cv::Mat roi = image(band);
  cv::Mat dark(roi.size(), roi.type(), cv::Scalar::all(0));
  cv::addWeighted(roi, 0.45, dark, 0.55, 0.0, roi);
  for (size_t i = 0; i < lines.size(); ++i)
    cv::putText(image, lines[i], cv::Point(6, 17 + static_cast<int>(i) * line_height), font, scale,
                cv::Scalar(235, 235, 235), 1, cv::LINE_AA);
}

std::string SummaryText(const ReceiverStats& stats, const std::optional<vdeform::server_status_t>& status,
                        const std::vector<std::string>& written_paths, size_t max_paths) {
  std::ostringstream os;
  os << "vdeform-viewer summary\n";
  os << "  meshes received " << stats.mesh_messages << ": decoded " << stats.meshes_decoded << " (live "
     << stats.live_meshes << ", canonical " << stats.canonical_meshes << ", tracked " << stats.tracked_meshes
     << ", repeats " << stats.repeated_meshes
     << "), failed " << stats.meshes_failed << "\n";
  os << "  bytes " << stats.mesh_bytes << " (" << FormatBytes(stats.mesh_bytes) << ")\n";
  if (stats.last_live_seq >= 0)
    os << "  last live seq " << stats.last_live_seq << " (" << stats.last_live_vertices << " vertices, "
       << stats.last_live_triangles << " triangles)\n";
  else
    os << "  last live seq: none\n";
  os << "  status messages " << stats.status_messages << ", failed " << stats.status_failed << "\n";
  if (status) {
    os << "  last status: " << ServerStateName(status->state);
    if (!status->message.empty()) os << " \"" << status->message << "\"";
    os << ", received " << status->frames_received << ", processed " << status->frames_processed << ", dropped "
       << status->frames_dropped << ", rejected " << status->frames_rejected << ", last seq "
       << status->last_processed_seq << ", " << Fixed(status->fps, 1) << " fps\n";
  } else {
    os << "  last status: none\n";
  }
  if (stats.verifying)
    os << "  refused under --key-file: meshes " << stats.meshes_refused.ToString() << "; status "
       << stats.status_refused.ToString() << "\n";
  if (stats.internal_errors) os << "  handler errors " << stats.internal_errors << "\n";
  if (stats.write_failures) os << "  write failures " << stats.write_failures << "\n";
  os << "  files written " << written_paths.size() << (written_paths.empty() ? "\n" : ":\n");
  const size_t n = written_paths.size();
  const size_t keep = std::max<size_t>(max_paths / 2, 1);
  for (size_t i = 0; i < n; ++i) {
    if (n > 2 * keep && i == keep) {
      os << "    ... " << n - 2 * keep << " more\n";
      i = n - keep - 1;
      continue;
    }
    os << "    " << written_paths[i] << "\n";
  }
  return os.str();
}

namespace {

// Columns of the terminal on stdout (80 when unknown), so the \r-refreshed line never wraps.
size_t TerminalColumns() {
  winsize size{};
  if (ioctl(STDOUT_FILENO, TIOCGWINSZ, &size) == 0 && size.ws_col > 0) return size.ws_col;
  return 80;
}

}  // namespace

StatusPrinter::StatusPrinter(bool enabled) : enabled_(enabled), tty_(isatty(STDOUT_FILENO) != 0) {}

void StatusPrinter::Tick(const std::function<std::string()>& line_of) {
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  const auto period = tty_ ? std::chrono::milliseconds(250) : std::chrono::milliseconds(1000);
  if (now - last_ < period) return;
  last_ = now;
  std::string line = line_of();
  if (tty_) {
    const size_t columns = TerminalColumns();
    if (line.size() >= columns) line.resize(columns - 1);
    std::printf("\r%s\033[K", line.c_str());
    printed_on_line_ = true;
  } else {
    std::printf("%s\n", line.c_str());
  }
  std::fflush(stdout);
}

void StatusPrinter::Finish() {
  if (printed_on_line_) std::printf("\n");
  printed_on_line_ = false;
}

}  // namespace vd
