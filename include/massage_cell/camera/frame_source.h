// Frame sources of the camera drivers: V4L2 devices, image folders and video
// files, delivering one view (mono) or a synchronised pair (stereo) per read.
// ROS-free (OpenCV only); the nodelets in src/nodes/ wrap it.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace massage_cell::camera {

/// A configuration the source cannot work with (missing device, empty folder,
/// invalid value, ...). The message names the problem and the parameter.
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class SourceType { kV4l2, kFolder, kVideo };
/// kMono: one view. kPair: two devices / files / name patterns. kSideBySide:
/// one device or file whose frames hold the left view in the left half and the
/// right view in the right half.
enum class Layout { kMono, kPair, kSideBySide };

SourceType parseSourceType(const std::string& text);  // "v4l2" | "folder" | "video"
Layout parseLayout(const std::string& text);          // "mono" | "pair" | "side_by_side"
std::string toString(SourceType type);
std::string toString(Layout layout);

struct SourceConfig {
  SourceType type = SourceType::kV4l2;
  Layout layout = Layout::kPair;

  /// V4L2: device paths ("/dev/video0") or indices ("0"); video: file paths.
  /// One entry for kMono and kSideBySide, two (left, right) for kPair.
  std::vector<std::string> locations;

  /// Folder source: the folder and one glob pattern per view ("left*.png").
  std::string folder;
  std::vector<std::string> patterns;

  /// V4L2 settings; 0 / "" keep the device's default. For kSideBySide the
  /// width is that of the whole (double-width) frame.
  int width = 0;
  int height = 0;
  double fps = 0.0;
  std::string pixel_format;  ///< FourCC, e.g. "MJPG", "YUYV"
  int buffer_size = 1;       ///< driver queue length; 1 = freshest frame

  /// Folder / video playback: frames per second (0 = the video's own rate,
  /// 10 Hz for folders), and whether to start over at the end.
  double rate = 0.0;
  bool loop = false;

  int views() const { return layout == Layout::kMono ? 1 : 2; }
};

/// Throws ConfigError naming the first invalid value. Checks values only; the
/// devices and files are checked by openSource().
void validate(const SourceConfig& config);

/// One capture: the views (BGR8, MONO8 or MONO16; all of one size and type)
/// and the wall-clock time the exposure was taken (best estimate).
struct Frame {
  std::vector<cv::Mat> views;
  std::chrono::system_clock::time_point capture_time;
  std::int64_t index = -1;   ///< frame number within the source
  double view_skew_s = 0.0;  ///< |left - right| capture time (two devices)
  std::string name;          ///< file name(s) of the frame, if any
};

enum class ReadStatus {
  kOk,        ///< frame delivered
  kBadFrame,  ///< this frame is unusable (unreadable file, size change); next read continues
  kEnd,       ///< no more frames (files without loop)
  kFailed     ///< the device stopped delivering; reopen the source
};

struct ReadResult {
  ReadStatus status = ReadStatus::kOk;
  std::string message;  ///< what was wrong, for kBadFrame / kFailed / kEnd
};

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  /// Next frame. Devices block until the camera delivers; files return at
  /// once and the caller paces them with nominalRate().
  virtual ReadResult read(Frame& frame) = 0;
  virtual int views() const = 0;
  virtual cv::Size viewSize() const = 0;
  /// true for devices (the camera sets the pace), false for files.
  virtual bool isLive() const = 0;
  /// Frames per second: the device's rate or the playback rate.
  virtual double nominalRate() const = 0;
  /// Number of frames of a file source, -1 for devices.
  virtual std::int64_t frameCount() const = 0;
  /// Human-readable description ("folder /x: 20 pairs left*.png / right*.png").
  virtual std::string describe() const = 0;
  /// Things that work but differ from what was asked (e.g. the device chose
  /// another size). Collected at open.
  const std::vector<std::string>& warnings() const { return warnings_; }

 protected:
  std::vector<std::string> warnings_;
};

/// Opens the source described by the configuration. Throws ConfigError with a
/// message naming the problem (missing device, folder or file; empty folder;
/// counts or sizes that differ between views; no readable image; ...).
std::unique_ptr<FrameSource> openSource(const SourceConfig& config);

/// Splits a side-by-side frame into its left and right halves (views share
/// the frame's memory). Throws ConfigError for an odd width.
std::vector<cv::Mat> splitSideBySide(const cv::Mat& frame);

/// Natural ("version") order: "left_2.png" < "left_10.png".
bool naturalLess(const std::string& a, const std::string& b);

/// Files of `folder` whose names match the glob `pattern`, in natural order.
std::vector<std::string> listMatching(const std::string& folder, const std::string& pattern);

}  // namespace massage_cell::camera
