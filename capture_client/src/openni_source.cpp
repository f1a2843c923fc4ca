// "openni2[:URI]" (live sensor) and "oni:FILE" (recording) through OpenNI2.
//
// - Every wait for a frame goes through OpenNI::waitForAnyStream with a deadline of
//   SourceOptions::read_timeout_s, and readFrame is only called on a stream that reported a new
//   frame, so a device or recording that stops delivering gives a DeadlineExceeded error instead
//   of a hang (STACK.md: a Dummy-device recording never delivers a frame).
// - Intrinsics come from the field of view of the stream the depth is registered to
//   (fx = width / (2 tan(hfov / 2)), cx = width / 2). Devices that report no field of view (the
//   Dummy device reports 0) get the nominal PrimeSense/Kinect v1 field of view, 58.5 x 45.6
//   degrees, with a warning; --intrinsics overrides.
// - Shut-down stops the streams, waits 200 ms, then destroys them (the Dummy device crashes when
//   its streams are destroyed right after stop(), STACK.md).
#include <OpenNI.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <mutex>
#include <sstream>
#include <thread>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "source_internal.h"
#include "vd/common/log.h"

namespace vd {
namespace {

constexpr double kPi = 3.14159265358979323846;
// Nominal PrimeSense / Kinect v1 field of view, used when the device reports none.
constexpr double kNominalHfovRad = 58.5 * kPi / 180.0;
constexpr double kNominalVfovRad = 45.6 * kPi / 180.0;
// The Dummy device crashes if its streams are destroyed sooner after stop() (STACK.md).
constexpr auto kStopSettle = std::chrono::milliseconds(200);
// Stands for "no end" in the frame arithmetic of a live sensor (2^60 frames is 10^9 years at 30 Hz).
constexpr int64_t kEndlessFrames = int64_t{1} << 60;

std::string ExtendedError() {
  std::string e = openni::OpenNI::getExtendedError();
  while (!e.empty() && std::isspace(static_cast<unsigned char>(e.back()))) e.pop_back();
  const size_t first = e.find_first_not_of(" \t\r\n");
  return first == std::string::npos ? std::string("no detail") : e.substr(first);
}

// OpenNI is initialised once per process and never shut down: several sources may be open and
// shutdown() would pull the drivers from under the others.
Status InitializeOpenNi() {
  static std::once_flag once;
  static openni::Status result = openni::STATUS_OK;
  static std::string detail;
  std::call_once(once, [] {
    result = openni::OpenNI::initialize();
    if (result != openni::STATUS_OK) detail = ExtendedError();
  });
  if (result != openni::STATUS_OK) return Unavailable("OpenNI2 initialisation failed: " + detail);
  return Status::Ok();
}

std::string ListDevices() {
  openni::Array<openni::DeviceInfo> devices;
  openni::OpenNI::enumerateDevices(&devices);
  if (devices.getSize() == 0) return "none";
  std::ostringstream os;
  for (int i = 0; i < devices.getSize(); ++i) {
    if (i) os << ", ";
    os << devices[i].getUri() << " (" << devices[i].getVendor() << " " << devices[i].getName() << ")";
  }
  return os.str();
}

bool IsDepthFormat(openni::PixelFormat f) {
  return f == openni::PIXEL_FORMAT_DEPTH_1_MM || f == openni::PIXEL_FORMAT_DEPTH_100_UM;
}
bool IsColorFormat(openni::PixelFormat f) {
  return f == openni::PIXEL_FORMAT_RGB888 || f == openni::PIXEL_FORMAT_YUV422 || f == openni::PIXEL_FORMAT_YUYV ||
         f == openni::PIXEL_FORMAT_GRAY8;
}

std::string ModeString(const openni::VideoMode& m) {
  std::ostringstream os;
  os << m.getResolutionX() << "x" << m.getResolutionY() << "@" << m.getFps() << " format " << m.getPixelFormat();
  return os.str();
}

// The supported mode closest to 640x480 at 30 Hz in a format we convert; nullopt if none is usable.
std::optional<openni::VideoMode> PickMode(const openni::SensorInfo* info, bool depth) {
  if (!info) return std::nullopt;
  const openni::Array<openni::VideoMode>& modes = info->getSupportedVideoModes();
  std::optional<openni::VideoMode> best;
  int best_score = 0;
  for (int i = 0; i < modes.getSize(); ++i) {
    const openni::VideoMode& m = modes[i];
    const openni::PixelFormat f = m.getPixelFormat();
    if (depth ? !IsDepthFormat(f) : !IsColorFormat(f)) continue;
    int score = 1;
    if (m.getResolutionX() == 640 && m.getResolutionY() == 480) score += 100;
    if (m.getFps() == 30) score += 10;
    if (f == openni::PIXEL_FORMAT_DEPTH_1_MM || f == openni::PIXEL_FORMAT_RGB888) score += 1;
    if (score > best_score) {
      best_score = score;
      best = m;
    }
  }
  return best;
}

StatusOr<cv::Mat> DepthToMat(const openni::VideoFrameRef& f) {
  const int w = f.getWidth(), h = f.getHeight(), stride = f.getStrideInBytes();
  if (w <= 0 || h <= 0 || w > 8192 || h > 8192 || stride < 2 * w ||
      static_cast<int64_t>(f.getDataSize()) < static_cast<int64_t>(stride) * h || !f.getData())
    return DataLoss("OpenNI2 depth frame has inconsistent size " + std::to_string(w) + "x" + std::to_string(h) +
                    " stride " + std::to_string(stride) + " bytes " + std::to_string(f.getDataSize()));
  cv::Mat wrapped(h, w, CV_16UC1, const_cast<void*>(f.getData()), static_cast<size_t>(stride));
  return wrapped.clone();
}

StatusOr<cv::Mat> ColorToMat(const openni::VideoFrameRef& f) {
  const int w = f.getWidth(), h = f.getHeight(), stride = f.getStrideInBytes();
  const openni::PixelFormat format = f.getVideoMode().getPixelFormat();
  int bytes_per_pixel = 0;
  switch (format) {
    case openni::PIXEL_FORMAT_RGB888: bytes_per_pixel = 3; break;
    case openni::PIXEL_FORMAT_YUV422:
    case openni::PIXEL_FORMAT_YUYV: bytes_per_pixel = 2; break;
    case openni::PIXEL_FORMAT_GRAY8: bytes_per_pixel = 1; break;
    default: return InvalidArgument("OpenNI2 colour pixel format " + std::to_string(format) + " is not supported");
  }
  if (w <= 0 || h <= 0 || w > 8192 || h > 8192 || stride < bytes_per_pixel * w ||
      static_cast<int64_t>(f.getDataSize()) < static_cast<int64_t>(stride) * h || !f.getData())
    return DataLoss("OpenNI2 colour frame has inconsistent size " + std::to_string(w) + "x" + std::to_string(h) +
                    " stride " + std::to_string(stride) + " bytes " + std::to_string(f.getDataSize()));
  void* data = const_cast<void*>(f.getData());
  cv::Mat bgr;
  switch (format) {
    case openni::PIXEL_FORMAT_RGB888: cv::cvtColor(cv::Mat(h, w, CV_8UC3, data, stride), bgr, cv::COLOR_RGB2BGR); break;
    case openni::PIXEL_FORMAT_YUV422:
      cv::cvtColor(cv::Mat(h, w, CV_8UC2, data, stride), bgr, cv::COLOR_YUV2BGR_UYVY);
      break;
    case openni::PIXEL_FORMAT_YUYV: cv::cvtColor(cv::Mat(h, w, CV_8UC2, data, stride), bgr, cv::COLOR_YUV2BGR_YUYV); break;
    default: cv::cvtColor(cv::Mat(h, w, CV_8UC1, data, stride), bgr, cv::COLOR_GRAY2BGR); break;
  }
  return bgr;
}

class OpenNiSource : public FrameSource {
 public:
  ~OpenNiSource() override { Stop(); }

  // Opens `uri` (a device URI or a recording path), creates and starts the streams.
  Status Open(const std::string& uri, bool is_file, const SourceOptions& options) {
    options_ = options;
    is_file_ = is_file;
    name_ = (is_file ? "oni:" : "openni2:") + (uri.empty() ? std::string("<first device>") : uri);
    if (device_.open(uri.empty() ? openni::ANY_DEVICE : uri.c_str()) != openni::STATUS_OK) {
      const std::string detail = ExtendedError();
      if (is_file) return DataLoss("cannot open recording '" + uri + "': " + detail);
      return NotFound("cannot open OpenNI2 device '" + uri + "': " + detail + "; devices found: " + ListDevices());
    }
    device_open_ = true;
    if (is_file != device_.isFile())
      return InvalidArgument(name_ + (is_file ? " is not a recording" : " is a recording; use oni:FILE"));
    if (!device_.hasSensor(openni::SENSOR_DEPTH)) return FailedPrecondition(name_ + " has no depth sensor");
    if (depth_.create(device_, openni::SENSOR_DEPTH) != openni::STATUS_OK)
      return Unavailable(name_ + ": cannot create the depth stream: " + ExtendedError());
    has_color_ = device_.hasSensor(openni::SENSOR_COLOR) && color_.create(device_, openni::SENSOR_COLOR) == openni::STATUS_OK;
    if (!has_color_) {
      VD_LOG_WARNING << name_ << ": no colour stream; frames carry depth only";
    }

    if (!is_file) {
      VD_RETURN_IF_ERROR(ChooseMode(depth_, openni::SENSOR_DEPTH, true));
      if (has_color_) VD_RETURN_IF_ERROR(ChooseMode(color_, openni::SENSOR_COLOR, false));
      depth_.setMirroringEnabled(false);
      if (has_color_) color_.setMirroringEnabled(false);
      if (has_color_ && device_.isImageRegistrationModeSupported(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR)) {
        registered_ = device_.setImageRegistrationMode(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR) == openni::STATUS_OK;
      }
      if (has_color_) device_.setDepthColorSyncEnabled(true);
    } else {
      playback_ = device_.getPlaybackControl();
      if (!playback_) return Internal(name_ + ": the recording has no playback control");
      // Manual speed: a frame is produced per read, so none is skipped however slowly we consume.
      if (playback_->setSpeed(-1.f) != openni::STATUS_OK)
        return Unavailable(name_ + ": cannot set manual playback speed: " + ExtendedError());
      playback_->setRepeatEnabled(false);
      raw_frames_ = playback_->getNumberOfFrames(depth_);
      if (raw_frames_ <= 0) return DataLoss(name_ + ": the recording holds no depth frames");
    }

    const openni::VideoMode depth_mode = depth_.getVideoMode();
    if (!IsDepthFormat(depth_mode.getPixelFormat()))
      return InvalidArgument(name_ + ": depth pixel format " + std::to_string(depth_mode.getPixelFormat()) +
                             " is not millimetres or 100 micrometres");
    if (has_color_ && !IsColorFormat(color_.getVideoMode().getPixelFormat()))
      return InvalidArgument(name_ + ": colour pixel format " + std::to_string(color_.getVideoMode().getPixelFormat()) +
                             " is not supported (RGB888, YUV422, YUYV, GRAY8)");
    own_depth_scale_ = depth_mode.getPixelFormat() == openni::PIXEL_FORMAT_DEPTH_100_UM ? 10000.f : 1000.f;
    depth_scale_ = options.depth_scale > 0.f ? options.depth_scale : own_depth_scale_;
    fps_ = depth_mode.getFps() > 0 ? depth_mode.getFps() : 30.0;

    const int w = depth_mode.getResolutionX(), h = depth_mode.getResolutionY();
    // Registered depth lies on the colour grid, so the colour camera's field of view applies.
    openni::VideoStream& fov_stream = registered_ ? color_ : depth_;
    double hfov = fov_stream.getHorizontalFieldOfView(), vfov = fov_stream.getVerticalFieldOfView();
    std::string origin = registered_ ? "colour field of view" : "depth field of view";
    if (!(std::isfinite(hfov) && hfov > 0.1 && hfov < 3.0 && std::isfinite(vfov) && vfov > 0.1 && vfov < 3.0)) {
      if (options.intrinsics.empty()) {
        VD_LOG_WARNING << name_ << " reports no field of view (" << hfov << ", " << vfov
                       << " rad); assuming the nominal Kinect v1 58.5 x 45.6 degrees (use --intrinsics)";
      }
      hfov = kNominalHfovRad;
      vfov = kNominalVfovRad;
      origin = "nominal Kinect v1 field of view";
    }
    Intrinsics own;
    own.fx = static_cast<float>(w / (2.0 * std::tan(hfov / 2.0)));
    own.fy = static_cast<float>(h / (2.0 * std::tan(vfov / 2.0)));
    own.cx = 0.5f * static_cast<float>(w);
    own.cy = 0.5f * static_cast<float>(h);
    VD_ASSIGN_OR_RETURN(intrinsics_, ResolveIntrinsics(own, options, w, h, name_));
    intrinsics_origin_ = options.intrinsics.empty() ? origin : "--intrinsics";

    if (is_file) {
      VD_ASSIGN_OR_RETURN(selection_, FrameSelection::Make(raw_frames_, options, name_));
    } else {
      // A live stream has no end to loop from; start/stride/count count frames as they arrive.
      SourceOptions live = options;
      live.loop = false;
      VD_ASSIGN_OR_RETURN(selection_, FrameSelection::Make(kEndlessFrames, live, name_));
      live_count_ = options.count;
    }
    if (depth_.start() != openni::STATUS_OK)
      return Unavailable(name_ + ": cannot start the depth stream: " + ExtendedError());
    started_ = true;
    if (has_color_ && color_.start() != openni::STATUS_OK)
      return Unavailable(name_ + ": cannot start the colour stream: " + ExtendedError());
    return Status::Ok();
  }

  StatusOr<std::optional<RgbdFrame>> Next() override {
    try {
      return NextFrame();
    } catch (const std::exception& e) {
      return Internal(name_ + ": " + e.what());
    }
  }

  double NominalFps() const override { return fps_; }
  int64_t NumFrames() const override {
    if (!selection_) return -1;
    return is_file_ ? selection_->NumFrames() : live_count_;
  }

  std::string Describe() const override {
    std::ostringstream os;
    os << name_ << " depth " << ModeString(depth_.getVideoMode());
    if (has_color_) os << ", colour " << ModeString(color_.getVideoMode());
    os << (registered_ ? ", registered to colour" : ", not registered") << ", " << intrinsics_.ToString() << " ("
       << intrinsics_origin_ << ") depth_scale=" << depth_scale_;
    if (is_file_ && selection_) os << " frames=" << selection_->per_pass() << "/" << raw_frames_;
    return os.str();
  }

 private:
  StatusOr<std::optional<RgbdFrame>> NextFrame() {
    const std::optional<int64_t> raw = selection_->Advance();
    if (!raw) return std::optional<RgbdFrame>();
    if (is_file_ && *raw < next_raw_) {
      // Looping: back to the first frame of the recording.
      if (playback_->seek(depth_, 0) != openni::STATUS_OK)
        return Unavailable(name_ + ": cannot rewind the recording: " + ExtendedError());
      next_raw_ = 0;
    }
    const int64_t skip = *raw - next_raw_;
    openni::VideoFrameRef depth_frame, color_frame;
    for (int64_t i = 0; i <= skip; ++i) {
      VD_RETURN_IF_ERROR(ReadPair(&depth_frame, &color_frame));
      ++next_raw_;
    }
    RgbdFrame frame;
    frame.seq = delivered_++;
    frame.utime = static_cast<int64_t>(depth_frame.getTimestamp());
    frame.intrinsics = intrinsics_;
    frame.depth_scale = depth_scale_;
    VD_ASSIGN_OR_RETURN(frame.depth, DepthToMat(depth_frame));
    if (frame.depth.cols != intrinsics_.width || frame.depth.rows != intrinsics_.height)
      return DataLoss(name_ + ": depth frame is " + std::to_string(frame.depth.cols) + "x" +
                      std::to_string(frame.depth.rows) + ", expected " + std::to_string(intrinsics_.width) + "x" +
                      std::to_string(intrinsics_.height));
    if (has_color_) {
      VD_ASSIGN_OR_RETURN(cv::Mat color, ColorToMat(color_frame));
      if (color.size() != frame.depth.size()) {
        cv::Mat resized;
        cv::resize(color, resized, frame.depth.size(), 0, 0, cv::INTER_AREA);
        color = resized;
      }
      frame.color = color;
    }
    return std::optional<RgbdFrame>(std::move(frame));
  }

  Status ChooseMode(openni::VideoStream& stream, openni::SensorType type, bool depth) {
    const std::optional<openni::VideoMode> mode = PickMode(device_.getSensorInfo(type), depth);
    if (!mode) return Status::Ok();
    const openni::VideoMode current = stream.getVideoMode();
    if (current.getResolutionX() == mode->getResolutionX() && current.getResolutionY() == mode->getResolutionY() &&
        current.getFps() == mode->getFps() && current.getPixelFormat() == mode->getPixelFormat())
      return Status::Ok();
    if (stream.setVideoMode(*mode) != openni::STATUS_OK) {
      VD_LOG_WARNING << name_ << ": cannot set " << (depth ? "depth" : "colour") << " mode " << ModeString(*mode)
                     << " (" << ExtendedError() << "); keeping " << ModeString(stream.getVideoMode());
    }
    return Status::Ok();
  }

  // Waits until a new depth frame and (with colour) a new colour frame have arrived.
  Status ReadPair(openni::VideoFrameRef* depth, openni::VideoFrameRef* color) {
    using Clock = std::chrono::steady_clock;
    const auto deadline = Clock::now() + std::chrono::duration<double>(options_.read_timeout_s);
    bool got_depth = false, got_color = !has_color_;
    openni::VideoStream* streams[2] = {&depth_, &color_};
    while (!got_depth || !got_color) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
      if (left <= 0) {
        std::ostringstream os;
        os << name_ << ": no " << (!got_depth ? "depth" : "colour") << " frame within " << options_.read_timeout_s
           << " s";
        if (is_file_) os << " (frame " << next_raw_ << " of " << raw_frames_ << " in the recording)";
        return DeadlineExceeded(os.str());
      }
      int ready = -1;
      const openni::Status s =
          openni::OpenNI::waitForAnyStream(streams, has_color_ ? 2 : 1, &ready, static_cast<int>(left));
      if (s == openni::STATUS_TIME_OUT) continue;
      if (s != openni::STATUS_OK || ready < 0 || ready > 1)
        return Unavailable(name_ + ": waiting for a frame failed: " + ExtendedError());
      openni::VideoFrameRef* out = ready == 0 ? depth : color;
      if (streams[ready]->readFrame(out) != openni::STATUS_OK || !out->isValid())
        return Unavailable(name_ + ": reading a frame failed: " + ExtendedError());
      (ready == 0 ? got_depth : got_color) = true;
    }
    return Status::Ok();
  }

  void Stop() {
    if (started_) {
      depth_.stop();
      if (has_color_) color_.stop();
      std::this_thread::sleep_for(kStopSettle);
      started_ = false;
    }
    depth_.destroy();
    color_.destroy();
    if (device_open_) device_.close();
    device_open_ = false;
  }

  SourceOptions options_;
  std::string name_;
  openni::Device device_;
  openni::VideoStream depth_;
  openni::VideoStream color_;
  bool device_open_ = false;
  bool started_ = false;
  bool has_color_ = false;
  bool registered_ = false;
  bool is_file_ = false;
  // Owned by device_; set for recordings.
  openni::PlaybackControl* playback_ = nullptr;
  // Depth frames in the recording.
  int64_t raw_frames_ = 0;
  // Index in the recording of the next depth frame a read returns.
  int64_t next_raw_ = 0;
  int64_t delivered_ = 0;
  // Which frames to deliver (for a live sensor: counted from the first frame read).
  std::optional<FrameSelection> selection_;
  // Live sensors: SourceOptions::count (-1: endless).
  int64_t live_count_ = -1;
  Intrinsics intrinsics_;
  std::string intrinsics_origin_;
  float own_depth_scale_ = 1000.f;
  float depth_scale_ = 1000.f;
  double fps_ = 30.0;
};

}  // namespace

StatusOr<std::unique_ptr<FrameSource>> OpenOpenNiSource(const std::string& uri, const SourceOptions& options) {
  VD_RETURN_IF_ERROR(options.Validate());
  VD_RETURN_IF_ERROR(InitializeOpenNi());
  std::string device_uri = uri;
  if (device_uri.empty()) {
    // The first real sensor: once opened, the Dummy device shows up in the list too, and a plain
    // "openni2" must not quietly stream fake frames.
    openni::Array<openni::DeviceInfo> devices;
    openni::OpenNI::enumerateDevices(&devices);
    for (int i = 0; i < devices.getSize() && device_uri.empty(); ++i)
      if (std::string(devices[i].getUri()) != "Dummy") device_uri = devices[i].getUri();
    if (device_uri.empty())
      return NotFound("no OpenNI2 sensor found (devices found: " +
                      std::string(devices.getSize() == 0 ? "none" : "only the Dummy device") +
                      "); connect one, or use openni2:Dummy, oni:FILE, folder:DIR or synthetic:SCENE");
  }
  auto source = std::make_unique<OpenNiSource>();
  VD_RETURN_IF_ERROR(source->Open(device_uri, false, options));
  return std::unique_ptr<FrameSource>(std::move(source));
}

StatusOr<std::unique_ptr<FrameSource>> OpenOniSource(const std::string& path, const SourceOptions& options) {
  VD_RETURN_IF_ERROR(options.Validate());
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return NotFound("recording '" + path + "' does not exist");
  if (!std::filesystem::is_regular_file(path, ec)) return InvalidArgument("recording '" + path + "' is not a file");
  VD_RETURN_IF_ERROR(InitializeOpenNi());
  auto source = std::make_unique<OpenNiSource>();
  VD_RETURN_IF_ERROR(source->Open(path, true, options));
  return std::unique_ptr<FrameSource>(std::move(source));
}

}  // namespace vd
