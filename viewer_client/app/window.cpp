#include "window.h"

#include <algorithm>
#include <cmath>

#include <opencv2/highgui.hpp>
#include <opencv2/imgproc.hpp>

#include "vd/common/log.h"
#include "vd/viewer/status_text.h"

namespace vd {
namespace {

// Radians of orbit per pixel dragged: a drag across a 640-pixel window turns about 180 degrees.
constexpr float kRadiansPerPixel = 0.005f;
// Zoom factor per wheel notch and per pixel of right-drag.
constexpr float kZoomPerNotch = 1.1f;
constexpr float kZoomPerPixel = 1.01f;
// Beyond these the mesh is a dot or fills the window with one triangle.
constexpr float kMinZoom = 0.05f;
constexpr float kMaxZoom = 50.f;
// Pitch is kept short of the poles so the orbit does not flip over.
constexpr float kMaxPitch = 1.5f;

}  // namespace

StatusOr<std::unique_ptr<MeshWindow>> MeshWindow::Open(const std::string& title, const RenderOptions& render,
                                                       ColorMode color_mode) {
  VD_RETURN_IF_ERROR(render.Validate());
  std::unique_ptr<MeshWindow> window(new MeshWindow(title, render, color_mode));
  try {
    // GUI_NORMAL: without Qt's toolbar, whose own zoom would take the mouse wheel from us.
    cv::namedWindow(title, cv::WINDOW_AUTOSIZE | cv::WINDOW_GUI_NORMAL);
    cv::setMouseCallback(title, &MeshWindow::OnMouse, window.get());
  } catch (const cv::Exception& e) {
    return Unavailable(std::string("cannot open the viewer window: ") + e.what());
  }
  return window;
}

MeshWindow::MeshWindow(const std::string& title, const RenderOptions& render, ColorMode color_mode)
    : title_(title), render_(render), color_mode_(color_mode) {}

MeshWindow::~MeshWindow() {
  try {
    if (!closed_) cv::destroyWindow(title_);
  } catch (const cv::Exception&) {
    // The window is already gone (closed by the user); nothing left to release.
  }
}

void MeshWindow::OnMouse(int event, int x, int y, int flags, void* self) {
  static_cast<MeshWindow*>(self)->HandleMouse(event, x, y, flags);
}

void MeshWindow::HandleMouse(int event, int x, int y, int flags) {
  const int dx = x - last_x_, dy = y - last_y_;
  switch (event) {
    case cv::EVENT_LBUTTONDOWN:
    case cv::EVENT_RBUTTONDOWN:
      break;
    case cv::EVENT_MOUSEMOVE:
      if (flags & cv::EVENT_FLAG_LBUTTON) {
        view_.yaw -= dx * kRadiansPerPixel;
        view_.pitch = std::clamp(view_.pitch + dy * kRadiansPerPixel, -kMaxPitch, kMaxPitch);
        view_dirty_ = true;
      } else if (flags & cv::EVENT_FLAG_RBUTTON) {
        view_.zoom = std::clamp(view_.zoom * std::pow(kZoomPerPixel, static_cast<float>(-dy)), kMinZoom, kMaxZoom);
        view_dirty_ = true;
      }
      break;
    case cv::EVENT_MOUSEWHEEL: {
      const int delta = cv::getMouseWheelDelta(flags);
      if (delta != 0) {
        view_.zoom = std::clamp(view_.zoom * (delta > 0 ? kZoomPerNotch : 1.f / kZoomPerNotch), kMinZoom, kMaxZoom);
        view_dirty_ = true;
      }
      break;
    }
    default:
      break;
  }
  last_x_ = x;
  last_y_ = y;
}

void MeshWindow::Render(const MeshReceiver& receiver) {
  const TriangleMesh* live = receiver.live_mesh();
  if (live == nullptr) {
    mesh_image_ = cv::Mat(render_.height, render_.width, CV_8UC3,
                          cv::Scalar(render_.background[0], render_.background[1], render_.background[2]));
    used_mode_ = color_mode_;
    cv::putText(mesh_image_, "waiting for the server's first mesh...",
                cv::Point(render_.width / 2 - 160, render_.height / 2), cv::FONT_HERSHEY_SIMPLEX, 0.55,
                cv::Scalar(200, 200, 200), 1, cv::LINE_AA);
    return;
  }
  const VertexColors colors = SelectVertexColors(*live, receiver.live_seq(), receiver.canonical_mesh(),
                                                 receiver.canonical_seq(), color_mode_);
  used_mode_ = colors.used;
  StatusOr<RenderResult> rendered = RenderMesh(*live, colors.rgb, render_, view_);
  if (!rendered.ok()) {
    VD_LOG_WARNING << "cannot render mesh " << receiver.live_seq() << ": " << rendered.status().ToString();
    return;
  }
  mesh_image_ = std::move(rendered->image);
}

bool MeshWindow::Update(const MeshReceiver& receiver, int wait_ms) {
  if (closed_) return false;
  try {
    if (view_dirty_ || receiver.version() != rendered_version_ || mesh_image_.empty()) {
      Render(receiver);
      rendered_version_ = receiver.version();
      view_dirty_ = false;
    }
    cv::Mat shown = mesh_image_.clone();
    DrawOverlay(shown, StatusOverlayLines(receiver.stats(), receiver.last_status(), color_mode_, used_mode_));
    cv::imshow(title_, shown);
    const int key = cv::waitKey(std::max(1, wait_ms));
    if (key >= 0) {
      switch (key & 0xff) {
        case 'q':
        case 27:
          closed_ = true;
          cv::destroyWindow(title_);
          return false;
        case 'c':
          color_mode_ = NextColorMode(color_mode_);
          view_dirty_ = true;
          break;
        case 'r':
          view_ = ViewParams{};
          view_dirty_ = true;
          break;
        case '+':
        case '=':
          view_.zoom = std::min(view_.zoom * kZoomPerNotch, kMaxZoom);
          view_dirty_ = true;
          break;
        case '-':
          view_.zoom = std::max(view_.zoom / kZoomPerNotch, kMinZoom);
          view_dirty_ = true;
          break;
        default:
          break;
      }
    }
    // The user closed the window with its title-bar button.
    if (cv::getWindowProperty(title_, cv::WND_PROP_VISIBLE) < 1) {
      closed_ = true;
      return false;
    }
  } catch (const cv::Exception& e) {
    VD_LOG_ERROR << "viewer window failed: " << e.what();
    closed_ = true;
    return false;
  }
  return true;
}

}  // namespace vd
