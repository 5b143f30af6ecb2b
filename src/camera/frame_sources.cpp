// FolderSource (image-pair folders) and CaptureSource (V4L2 devices and video
// files through cv::VideoCapture), and openSource() choosing between them.
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <sstream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "massage_cell/camera/frame_source.h"

namespace massage_cell::camera {

namespace fs = std::filesystem;
using SystemClock = std::chrono::system_clock;

namespace {

std::string sizeText(cv::Size s) { return std::to_string(s.width) + "x" + std::to_string(s.height); }

/// Brings an image to a type the drivers publish: BGR8, MONO8 or MONO16.
/// Returns an empty Mat (and sets `why`) for other types.
cv::Mat toPublishable(const cv::Mat& image, std::string& why) {
  if (image.depth() != CV_8U && image.depth() != CV_16U) {
    why = "unsupported pixel depth (only 8- and 16-bit images)";
    return {};
  }
  switch (image.channels()) {
    case 1:
      return image;
    case 3:
      if (image.depth() != CV_8U) break;
      return image;
    case 4:
      if (image.depth() != CV_8U) break;
      {
        cv::Mat bgr;
        cv::cvtColor(image, bgr, cv::COLOR_BGRA2BGR);
        return bgr;
      }
    default:
      break;
  }
  why = "unsupported image type (" + std::to_string(image.channels()) + " channels, " +
        (image.depth() == CV_8U ? "8" : "16") + "-bit)";
  return {};
}

/// Checks that all views share one size and type, equal to the reference
/// when one is set. Sets `why` and returns false otherwise.
bool consistentViews(const std::vector<cv::Mat>& views, cv::Size ref_size, int ref_type, std::string& why) {
  for (std::size_t i = 0; i < views.size(); ++i) {
    if (views[i].size() != views[0].size() || views[i].type() != views[0].type()) {
      why = "left and right images differ in size or type (" + sizeText(views[0].size()) + " vs " +
            sizeText(views[i].size()) + ")";
      return false;
    }
  }
  if (ref_size.area() > 0 && (views[0].size() != ref_size || views[0].type() != ref_type)) {
    why = "image size or type changed from " + sizeText(ref_size) + " to " + sizeText(views[0].size());
    return false;
  }
  return true;
}

// ---------------------------------------------------------------- folders --

class FolderSource : public FrameSource {
 public:
  explicit FolderSource(const SourceConfig& config) : config_(config) {
    const fs::path folder(config.folder);
    std::error_code ec;
    if (!fs::exists(folder, ec)) throw ConfigError("image folder '" + config.folder + "' does not exist");
    if (!fs::is_directory(folder, ec)) throw ConfigError("'" + config.folder + "' is not a folder");
    split_ = config.layout == Layout::kSideBySide;
    for (const auto& pattern : config.patterns) {
      std::vector<std::string> names;
      try {
        names = listMatching(config.folder, pattern);
      } catch (const fs::filesystem_error& e) {
        throw ConfigError("cannot list image folder '" + config.folder + "': " + e.what());
      }
      if (names.empty()) {
        throw ConfigError("image folder '" + config.folder + "' has no file matching '" + pattern + "'");
      }
      files_.push_back(std::move(names));
    }
    if (files_.size() == 2 && files_[0].size() != files_[1].size()) {
      throw ConfigError("image folder '" + config.folder + "' has " + std::to_string(files_[0].size()) +
                        " left images ('" + config.patterns[0] + "') but " + std::to_string(files_[1].size()) +
                        " right images ('" + config.patterns[1] + "')");
    }
    // The first readable frame sets the size and type every later frame must keep.
    std::string first_error;
    for (std::size_t i = 0; i < count(); ++i) {
      std::vector<cv::Mat> views;
      std::string why;
      if (load(i, views, why) && consistentViews(views, {}, 0, why)) {
        size_ = views[0].size();
        type_ = views[0].type();
        break;
      }
      if (first_error.empty()) first_error = why;
      if (split_ && why.find("odd width") != std::string::npos) throw ConfigError(why);
      if (files_.size() == 2 && why.find("differ in size") != std::string::npos) throw ConfigError(why);
      warnings_.push_back(why);
    }
    if (size_.area() == 0) {
      throw ConfigError("image folder '" + config.folder + "' holds no readable image (" + first_error + ")");
    }
    rate_ = config.rate > 0.0 ? config.rate : 10.0;
  }

  ReadResult read(Frame& frame) override {
    if (next_ >= count()) {
      if (!config_.loop) return {ReadStatus::kEnd, "end of image folder '" + config_.folder + "'"};
      next_ = 0;
    }
    const std::size_t i = next_++;
    frame.index = static_cast<std::int64_t>(i);
    frame.capture_time = SystemClock::now();
    frame.view_skew_s = 0.0;
    frame.name = files_[0][i] + (files_.size() == 2 ? " / " + files_[1][i] : "");
    std::string why;
    if (!load(i, frame.views, why) || !consistentViews(frame.views, size_, type_, why)) {
      frame.views.clear();
      return {ReadStatus::kBadFrame, frame.name + ": " + why};
    }
    return {};
  }

  int views() const override { return config_.views(); }
  cv::Size viewSize() const override { return size_; }
  bool isLive() const override { return false; }
  double nominalRate() const override { return rate_; }
  std::int64_t frameCount() const override { return static_cast<std::int64_t>(count()); }
  std::string describe() const override {
    std::ostringstream s;
    s << "image folder '" << config_.folder << "': " << count() << (files_.size() == 2 ? " pairs " : " images ");
    for (std::size_t v = 0; v < config_.patterns.size(); ++v) s << (v ? " / " : "") << config_.patterns[v];
    s << (split_ ? " (side by side)" : "") << ", " << sizeText(size_) << " at " << rate_ << " Hz"
      << (config_.loop ? ", looping" : "");
    return s.str();
  }

 private:
  std::size_t count() const { return files_[0].size(); }

  bool load(std::size_t i, std::vector<cv::Mat>& views, std::string& why) const {
    views.clear();
    for (const auto& list : files_) {
      const std::string path = (fs::path(config_.folder) / list[i]).string();
      cv::Mat image;
      try {
        image = cv::imread(path, cv::IMREAD_ANYDEPTH | cv::IMREAD_ANYCOLOR);
      } catch (const cv::Exception& e) {
        image.release();
      }
      if (image.empty()) {
        why = "cannot read image '" + list[i] + "' (missing, truncated or not an image)";
        return false;
      }
      image = toPublishable(image, why);
      if (image.empty()) {
        why = list[i] + ": " + why;
        return false;
      }
      if (split_) {
        if (image.cols % 2 != 0) {
          why = "side-by-side image '" + list[i] + "' has an odd width (" + std::to_string(image.cols) + ")";
          return false;
        }
        for (auto& half : splitSideBySide(image)) views.push_back(half);
      } else {
        views.push_back(image);
      }
    }
    return true;
  }

  SourceConfig config_;
  bool split_ = false;
  std::vector<std::vector<std::string>> files_;  // per pattern, natural order
  cv::Size size_;
  int type_ = 0;
  double rate_ = 10.0;
  std::size_t next_ = 0;
};

// ------------------------------------------------ V4L2 devices and videos --

std::string devicePath(const std::string& location) {
  if (!location.empty() &&
      std::all_of(location.begin(), location.end(), [](unsigned char c) { return std::isdigit(c); })) {
    return "/dev/video" + location;
  }
  return location;
}

class CaptureSource : public FrameSource {
 public:
  explicit CaptureSource(const SourceConfig& config) : config_(config) {
    live_ = config.type == SourceType::kV4l2;
    split_ = config.layout == Layout::kSideBySide;
    for (const auto& location : config.locations) caps_.push_back(live_ ? openDevice(location) : openVideo(location));
    if (live_) {
      rate_ = caps_[0].get(cv::CAP_PROP_FPS);
      if (!(rate_ > 0.0)) rate_ = config.fps > 0.0 ? config.fps : 30.0;
    } else {
      rate_ = config.rate > 0.0 ? config.rate : caps_[0].get(cv::CAP_PROP_FPS);
      if (!(rate_ > 0.0) || rate_ > 1000.0) {
        warnings_.push_back("video '" + config.locations[0] + "' declares no usable frame rate; playing at 10 Hz");
        rate_ = 10.0;
      }
      count_ = static_cast<std::int64_t>(caps_[0].get(cv::CAP_PROP_FRAME_COUNT));
      if (caps_.size() == 2) {
        const auto right = static_cast<std::int64_t>(caps_[1].get(cv::CAP_PROP_FRAME_COUNT));
        if (count_ > 0 && right > 0 && right != count_) {
          throw ConfigError("video files differ in length: '" + config.locations[0] + "' has " +
                            std::to_string(count_) + " frames, '" + config.locations[1] + "' has " +
                            std::to_string(right));
        }
      }
    }
    // One frame now: proves the source delivers and tells the real size.
    Frame first;
    ReadResult r = read(first);
    if (r.status != ReadStatus::kOk) {
      throw ConfigError((live_ ? "device " : "video ") + config.locations[0] +
                        " delivered no usable frame: " + r.message);
    }
    size_ = first.views[0].size();
    type_ = first.views[0].type();
    pending_ = std::move(first);
    has_pending_ = true;
    if (live_ && config.width > 0 && config.height > 0) {
      const cv::Size asked(split_ ? config.width / 2 : config.width, config.height);
      if (asked != size_) {
        warnings_.push_back("asked for " + sizeText(asked) + " per view, the device delivers " + sizeText(size_));
      }
    }
  }

  ReadResult read(Frame& frame) override {
    if (has_pending_) {
      frame = std::move(pending_);
      has_pending_ = false;
      return {};
    }
    std::vector<cv::Mat> raw(caps_.size());
    std::vector<SystemClock::time_point> stamps(caps_.size());
    if (live_) {
      // Grab every device first, then decode: keeps the views' exposures close.
      for (std::size_t c = 0; c < caps_.size(); ++c) {
        if (!caps_[c].grab())
          return {ReadStatus::kFailed, "device " + config_.locations[c] + " stopped delivering frames"};
        stamps[c] = deviceStamp(caps_[c]);
      }
      for (std::size_t c = 0; c < caps_.size(); ++c) {
        if (!caps_[c].retrieve(raw[c]) || raw[c].empty()) {
          return {ReadStatus::kBadFrame, "device " + config_.locations[c] + ": could not decode a frame"};
        }
      }
    } else {
      if (!readVideo(raw)) {
        if (!config_.loop) return {ReadStatus::kEnd, "end of video '" + config_.locations[0] + "'"};
        for (auto& cap : caps_) cap.set(cv::CAP_PROP_POS_FRAMES, 0);
        index_ = 0;
        if (!readVideo(raw)) return {ReadStatus::kFailed, "video '" + config_.locations[0] + "' cannot be rewound"};
      }
      std::fill(stamps.begin(), stamps.end(), SystemClock::now());
    }
    frame.index = index_++;
    frame.capture_time = *std::min_element(stamps.begin(), stamps.end());
    frame.view_skew_s =
        std::chrono::duration<double>(*std::max_element(stamps.begin(), stamps.end()) - frame.capture_time).count();
    frame.name.clear();
    frame.views.clear();
    std::string why;
    for (auto& image : raw) {
      cv::Mat usable = toPublishable(image, why);
      if (usable.empty()) return {ReadStatus::kBadFrame, why};
      if (split_) {
        if (usable.cols % 2 != 0) {
          return {ReadStatus::kBadFrame, "side-by-side frame has an odd width (" + std::to_string(usable.cols) + ")"};
        }
        for (auto& half : splitSideBySide(usable)) frame.views.push_back(half);
      } else {
        frame.views.push_back(usable);
      }
    }
    if (!consistentViews(frame.views, size_, type_, why)) {
      frame.views.clear();
      // Two devices delivering different sizes is a configuration error: report it at open.
      return {size_.area() == 0 ? ReadStatus::kFailed : ReadStatus::kBadFrame, why};
    }
    return {};
  }

  int views() const override { return config_.views(); }
  cv::Size viewSize() const override { return size_; }
  bool isLive() const override { return live_; }
  double nominalRate() const override { return rate_; }
  std::int64_t frameCount() const override { return live_ ? -1 : count_; }
  std::string describe() const override {
    std::ostringstream s;
    s << (live_ ? "V4L2 " : "video ");
    for (std::size_t c = 0; c < config_.locations.size(); ++c) s << (c ? " + " : "") << config_.locations[c];
    s << (split_ ? " (side by side)" : "") << ", " << sizeText(size_) << " per view at " << rate_ << " Hz";
    if (!live_) s << ", " << count_ << " frames" << (config_.loop ? ", looping" : "");
    return s.str();
  }

 private:
  cv::VideoCapture openDevice(const std::string& location) {
    const std::string path = devicePath(location);
    std::error_code ec;
    if (!fs::exists(path, ec)) throw ConfigError("V4L2 device '" + path + "' does not exist");
    cv::VideoCapture cap;
    if (!cap.open(path, cv::CAP_V4L2)) {
      throw ConfigError("cannot open V4L2 device '" + path + "' (busy, no permission, or not a capture device)");
    }
    if (!config_.pixel_format.empty()) {
      const auto& f = config_.pixel_format;
      cap.set(cv::CAP_PROP_FOURCC, cv::VideoWriter::fourcc(f[0], f[1], f[2], f[3]));
    }
    if (config_.width > 0) cap.set(cv::CAP_PROP_FRAME_WIDTH, config_.width);
    if (config_.height > 0) cap.set(cv::CAP_PROP_FRAME_HEIGHT, config_.height);
    if (config_.fps > 0.0) cap.set(cv::CAP_PROP_FPS, config_.fps);
    cap.set(cv::CAP_PROP_BUFFERSIZE, config_.buffer_size);
    if (config_.fps > 0.0) {
      const double got = cap.get(cv::CAP_PROP_FPS);
      if (got > 0.0 && std::abs(got - config_.fps) > 0.5) {
        warnings_.push_back("asked " + path + " for " + std::to_string(config_.fps) + " fps, it runs at " +
                            std::to_string(got));
      }
    }
    return cap;
  }

  cv::VideoCapture openVideo(const std::string& path) {
    std::error_code ec;
    if (!fs::exists(path, ec)) throw ConfigError("video file '" + path + "' does not exist");
    if (fs::is_directory(path, ec)) throw ConfigError("video file '" + path + "' is a folder");
    cv::VideoCapture cap;
    if (!cap.open(path, cv::CAP_ANY)) {
      throw ConfigError("cannot open video file '" + path + "' (not a video, or no decoder for it)");
    }
    return cap;
  }

  bool readVideo(std::vector<cv::Mat>& raw) {
    for (std::size_t c = 0; c < caps_.size(); ++c) {
      if (!caps_[c].read(raw[c]) || raw[c].empty()) return false;
    }
    return true;
  }

  /// The time the device took the frame: the V4L2 buffer timestamp
  /// (CLOCK_MONOTONIC, which std::chrono::steady_clock reads on Linux)
  /// moved to the wall clock; the grab time when the device gives none.
  static SystemClock::time_point deviceStamp(cv::VideoCapture& cap) {
    const auto now_wall = SystemClock::now();
    const double buffer_ms = cap.get(cv::CAP_PROP_POS_MSEC);
    const double now_mono_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
    const double age_ms = now_mono_ms - buffer_ms;
    if (buffer_ms > 0.0 && age_ms >= 0.0 && age_ms < 2000.0) {
      return now_wall -
             std::chrono::duration_cast<SystemClock::duration>(std::chrono::duration<double, std::milli>(age_ms));
    }
    return now_wall;
  }

  SourceConfig config_;
  bool live_ = false;
  bool split_ = false;
  std::vector<cv::VideoCapture> caps_;
  double rate_ = 0.0;
  std::int64_t count_ = -1;
  std::int64_t index_ = 0;
  cv::Size size_;
  int type_ = 0;
  Frame pending_;
  bool has_pending_ = false;
};

}  // namespace

std::unique_ptr<FrameSource> openSource(const SourceConfig& config) {
  validate(config);
  if (config.type == SourceType::kFolder) return std::make_unique<FolderSource>(config);
  return std::make_unique<CaptureSource>(config);
}

}  // namespace massage_cell::camera
