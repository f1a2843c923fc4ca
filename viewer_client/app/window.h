#pragma once
// The viewer's window (OpenCV highgui): the CPU-rendered live mesh with mouse orbit/zoom, a colour
// mode key and the status overlay. Only the executable links this; tests never open a window.
#include <memory>
#include <string>

#include <opencv2/core.hpp>

#include "vd/common/status.h"
#include "vd/viewer/receiver.h"
#include "vd/viewer/render.h"

namespace vd {

class MeshWindow {
 public:
  // Opens the window. Call only after CheckDisplay() passed: highgui aborts without a display.
  static StatusOr<std::unique_ptr<MeshWindow>> Open(const std::string& title, const RenderOptions& render,
                                                    ColorMode color_mode);
  ~MeshWindow();
  MeshWindow(const MeshWindow&) = delete;
  MeshWindow& operator=(const MeshWindow&) = delete;

  // Re-renders when the mesh, the view or the colouring changed, redraws the overlay, and handles
  // keys and mouse for up to wait_ms. Returns false when the user closed the window or quit.
  bool Update(const MeshReceiver& receiver, int wait_ms);

 private:
  MeshWindow(const std::string& title, const RenderOptions& render, ColorMode color_mode);
  static void OnMouse(int event, int x, int y, int flags, void* self);
  void HandleMouse(int event, int x, int y, int flags);
  void Render(const MeshReceiver& receiver);

  std::string title_;
  RenderOptions render_;
  ColorMode color_mode_;
  // What the last rendering used (kVertex when canonical colouring had no matching mesh).
  ColorMode used_mode_ = ColorMode::kShade;
  ViewParams view_;
  // The mesh image without overlay, re-rendered only when something it shows changed.
  cv::Mat mesh_image_;
  int64_t rendered_version_ = -1;
  bool view_dirty_ = true;
  // Mouse drag state.
  int last_x_ = 0;
  int last_y_ = 0;
  bool closed_ = false;
};

}  // namespace vd
