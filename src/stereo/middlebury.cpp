#include "massage_cell/stereo/middlebury.h"

#include <cmath>
#include <filesystem>
#include <map>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace massage_cell::stereo {

namespace {

cv::Mat readImage(const std::filesystem::path& path, int flags) {
  if (!std::filesystem::exists(path)) throw std::runtime_error("missing file '" + path.string() + "'");
  cv::Mat image = cv::imread(path.string(), flags);
  if (image.empty()) throw std::runtime_error("cannot read image '" + path.string() + "'");
  return image;
}

/// Pixels within 4 of a ground-truth jump of more than 2 px (a 9x9 window, as Middlebury's disc masks),
/// inside `nonocc`.
cv::Mat discontinuityMask(const cv::Mat& ground_truth, const cv::Mat& nonocc) {
  cv::Mat jumps(ground_truth.size(), CV_8U, cv::Scalar(0));
  for (int y = 0; y < ground_truth.rows; ++y) {
    for (int x = 0; x < ground_truth.cols; ++x) {
      const float g = ground_truth.at<float>(y, x);
      if (!(g > 0.0f)) continue;
      const float right = x + 1 < ground_truth.cols ? ground_truth.at<float>(y, x + 1) : 0.0f;
      const float down = y + 1 < ground_truth.rows ? ground_truth.at<float>(y + 1, x) : 0.0f;
      if ((right > 0.0f && std::abs(right - g) > 2.0f) || (down > 0.0f && std::abs(down - g) > 2.0f)) {
        jumps.at<uchar>(y, x) = 255;
      }
    }
  }
  cv::Mat disc;
  cv::dilate(jumps, disc, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(9, 9)));
  return disc & nonocc;
}

/// Middlebury 2005 (third size): no masks ship; `all` = every pixel (the GT's 0 = unknown is skipped by
/// badPixelPercent), `nonocc` = the pixels whose match lies inside the right image (x >= d_gt), `disc` =
/// discontinuityMask.
void derive2005Masks(MiddleburyScene& scene) {
  scene.all = cv::Mat(scene.ground_truth.size(), CV_8U, cv::Scalar(255));
  scene.nonocc = cv::Mat(scene.ground_truth.size(), CV_8U, cv::Scalar(0));
  for (int y = 0; y < scene.ground_truth.rows; ++y) {
    for (int x = 0; x < scene.ground_truth.cols; ++x) {
      const float g = scene.ground_truth.at<float>(y, x);
      if (g > 0.0f && x >= g) scene.nonocc.at<uchar>(y, x) = 255;
    }
  }
  scene.disc = discontinuityMask(scene.ground_truth, scene.nonocc);
}

struct SceneFacts {
  int dmax, scale;
  bool year2005;
};

const std::map<std::string, SceneFacts>& sceneFacts() {
  static const std::map<std::string, SceneFacts> facts{{"tsukuba", {15, 16, false}}, {"venus", {19, 8, false}},
                                                       {"teddy", {59, 4, false}},    {"cones", {59, 4, false}},
                                                       {"art", {79, 3, true}},       {"dolls", {79, 3, true}}};
  return facts;
}

}  // namespace

const std::vector<std::string>& middleburyScenes() {
  static const std::vector<std::string> scenes{"tsukuba", "venus", "teddy", "cones"};
  return scenes;
}

const std::vector<std::string>& middlebury2005Scenes() {
  static const std::vector<std::string> scenes{"art", "dolls"};
  return scenes;
}

bool isMiddlebury2005Scene(const std::string& name) {
  const auto fact = sceneFacts().find(name);
  return fact != sceneFacts().end() && fact->second.year2005;
}

MiddleburyScene loadMiddleburyScene(const std::string& root, const std::string& name) {
  const auto fact = sceneFacts().find(name);
  if (fact == sceneFacts().end()) {
    throw std::runtime_error("unknown Middlebury scene '" + name + "' (tsukuba, venus, teddy, cones, art, dolls)");
  }
  const std::filesystem::path dir = std::filesystem::path(root) / name;
  if (!std::filesystem::is_directory(dir))
    throw std::runtime_error("missing Middlebury scene folder '" + dir.string() + "'");
  MiddleburyScene scene;
  scene.name = name;
  scene.dmax = fact->second.dmax;
  scene.scale = fact->second.scale;
  scene.left = readImage(dir / "left.png", cv::IMREAD_COLOR);
  scene.right = readImage(dir / "right.png", cv::IMREAD_COLOR);
  readImage(dir / "gt_disp_left.png", cv::IMREAD_GRAYSCALE).convertTo(scene.ground_truth, CV_32F, 1.0 / scene.scale);
  if (fact->second.year2005) {
    derive2005Masks(scene);
  } else {
    scene.nonocc = readImage(dir / "nonocc.png", cv::IMREAD_GRAYSCALE);
    scene.all = readImage(dir / "all.png", cv::IMREAD_GRAYSCALE);
    scene.disc = readImage(dir / "disc.png", cv::IMREAD_GRAYSCALE);
  }
  return scene;
}

double badPixelPercent(const cv::Mat& disparity, const cv::Mat& ground_truth, const cv::Mat& mask, double threshold) {
  CV_Assert(disparity.size() == ground_truth.size() && mask.size() == disparity.size());
  long evaluated = 0, bad = 0;
  for (int y = 0; y < disparity.rows; ++y) {
    const float* d = disparity.ptr<float>(y);
    const float* g = ground_truth.ptr<float>(y);
    const unsigned char* m = mask.ptr<unsigned char>(y);
    for (int x = 0; x < disparity.cols; ++x) {
      if (m[x] != 255 || !(g[x] > 0.0f)) continue;
      ++evaluated;
      if (!std::isfinite(d[x]) || std::abs(d[x] - g[x]) > threshold) ++bad;
    }
  }
  return evaluated > 0 ? 100.0 * bad / evaluated : 0.0;
}

}  // namespace massage_cell::stereo
