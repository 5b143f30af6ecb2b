#include "massage_cell/camera/frame_source.h"

#include <fnmatch.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <sstream>

namespace massage_cell::camera {

namespace fs = std::filesystem;

SourceType parseSourceType(const std::string& text) {
  if (text == "v4l2") return SourceType::kV4l2;
  if (text == "folder") return SourceType::kFolder;
  if (text == "video") return SourceType::kVideo;
  throw ConfigError("source '" + text + "' is not one of: v4l2, folder, video");
}

Layout parseLayout(const std::string& text) {
  if (text == "mono") return Layout::kMono;
  if (text == "pair") return Layout::kPair;
  if (text == "side_by_side") return Layout::kSideBySide;
  throw ConfigError("layout '" + text + "' is not one of: pair, side_by_side (stereo) or mono");
}

std::string toString(SourceType type) {
  switch (type) {
    case SourceType::kV4l2:
      return "v4l2";
    case SourceType::kFolder:
      return "folder";
    case SourceType::kVideo:
      return "video";
  }
  return "?";
}

std::string toString(Layout layout) {
  switch (layout) {
    case Layout::kMono:
      return "mono";
    case Layout::kPair:
      return "pair";
    case Layout::kSideBySide:
      return "side_by_side";
  }
  return "?";
}

namespace {
void require(bool ok, const std::string& message) {
  if (!ok) throw ConfigError(message);
}
}  // namespace

void validate(const SourceConfig& c) {
  const std::size_t channels = c.layout == Layout::kPair ? 2 : 1;
  const bool finite = std::isfinite(c.fps) && std::isfinite(c.rate);
  require(finite, "fps and rate must be finite numbers");
  require(c.width >= 0, "width must be >= 0 (0 keeps the device's default), got " + std::to_string(c.width));
  require(c.height >= 0, "height must be >= 0 (0 keeps the device's default), got " + std::to_string(c.height));
  require(c.fps >= 0.0, "fps must be >= 0 (0 keeps the device's default)");
  require(c.rate >= 0.0, "rate must be >= 0 (0 = the file's own rate)");
  require(c.rate <= 1000.0, "rate must be <= 1000 Hz");
  require(c.buffer_size >= 1 && c.buffer_size <= 32,
          "buffer_queue_size must be in 1..32, got " + std::to_string(c.buffer_size));
  require(c.pixel_format.empty() || c.pixel_format.size() == 4,
          "pixel_format must be a four-character code such as MJPG or YUYV, got '" + c.pixel_format + "'");
  if (c.layout == Layout::kSideBySide && c.width > 0) {
    require(c.width % 2 == 0, "width of a side-by-side device must be even, got " + std::to_string(c.width));
  }
  switch (c.type) {
    case SourceType::kV4l2:
    case SourceType::kVideo: {
      const char* what = c.type == SourceType::kV4l2 ? "device" : "video file";
      require(c.locations.size() == channels, std::string("layout ") + toString(c.layout) + " needs " +
                                                  std::to_string(channels) + " " + what + (channels == 1 ? "" : "s") +
                                                  ", got " + std::to_string(c.locations.size()));
      for (const auto& l : c.locations) require(!l.empty(), std::string("empty ") + what + " name");
      break;
    }
    case SourceType::kFolder:
      require(!c.folder.empty(), "folder source: parameter 'folder' is empty");
      require(c.layout != Layout::kSideBySide || c.patterns.size() == 1,
              "folder source with layout side_by_side needs one pattern");
      require(c.layout == Layout::kSideBySide || c.patterns.size() == static_cast<std::size_t>(c.views()),
              "folder source needs one file-name pattern per view");
      for (const auto& p : c.patterns) require(!p.empty(), "folder source: empty file-name pattern");
      break;
  }
}

bool naturalLess(const std::string& a, const std::string& b) {
  std::size_t i = 0, j = 0;
  while (i < a.size() && j < b.size()) {
    if (std::isdigit(static_cast<unsigned char>(a[i])) && std::isdigit(static_cast<unsigned char>(b[j]))) {
      std::size_t ie = i, je = j;
      while (ie < a.size() && std::isdigit(static_cast<unsigned char>(a[ie]))) ++ie;
      while (je < b.size() && std::isdigit(static_cast<unsigned char>(b[je]))) ++je;
      // Compare digit runs by value: strip leading zeros, then by length, then lexically.
      std::size_t is = i, js = j;
      while (is + 1 < ie && a[is] == '0') ++is;
      while (js + 1 < je && b[js] == '0') ++js;
      if (ie - is != je - js) return ie - is < je - js;
      const int cmp = a.compare(is, ie - is, b, js, je - js);
      if (cmp != 0) return cmp < 0;
      if (ie - i != je - j) return ie - i < je - j;  // fewer leading zeros first
      i = ie;
      j = je;
    } else {
      if (a[i] != b[j]) return a[i] < b[j];
      ++i;
      ++j;
    }
  }
  return a.size() - i < b.size() - j;
}

std::vector<std::string> listMatching(const std::string& folder, const std::string& pattern) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(folder)) {
    if (!entry.is_regular_file()) continue;  // follows symlinks
    const std::string name = entry.path().filename().string();
    if (fnmatch(pattern.c_str(), name.c_str(), FNM_PERIOD) == 0) names.push_back(name);
  }
  std::sort(names.begin(), names.end(), naturalLess);
  return names;
}

std::vector<cv::Mat> splitSideBySide(const cv::Mat& frame) {
  if (frame.cols % 2 != 0) {
    throw ConfigError("side-by-side frame has an odd width (" + std::to_string(frame.cols) +
                      "): cannot split it into two equal halves");
  }
  const int half = frame.cols / 2;
  return {frame(cv::Rect(0, 0, half, frame.rows)), frame(cv::Rect(half, 0, half, frame.rows))};
}

}  // namespace massage_cell::camera
