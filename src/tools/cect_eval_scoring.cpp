#include "cect_eval_scoring.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <tuple>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "massage_cell/sim/scene_builder.h"

namespace massage_cell::tools::cect_eval {
namespace {

/// Bilinear sample of a CV_32FC3 / CV_32F map where all four neighbours are finite.
bool sampleMap(const cv::Mat& m, double x, double y, Eigen::Vector3d* out) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= m.cols || y0 + 1 >= m.rows) return false;
  const double fx = x - x0, fy = y - y0;
  Eigen::Vector3d acc = Eigen::Vector3d::Zero();
  for (int dy = 0; dy <= 1; ++dy)
    for (int dx = 0; dx <= 1; ++dx) {
      Eigen::Vector3d v;
      if (m.type() == CV_32FC3) {
        const cv::Vec3f p = m.at<cv::Vec3f>(y0 + dy, x0 + dx);
        v = Eigen::Vector3d(p[0], p[1], p[2]);
      } else {
        v = Eigen::Vector3d::Constant(m.at<float>(y0 + dy, x0 + dx));
      }
      if (!v.allFinite()) return false;
      acc += (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy) * v;
    }
  *out = acc;
  return true;
}

}  // namespace

cv::Mat sgbmDisparity(const camera::StereoModel& geometry, const sim::StereoFrame& frame, int width) {
  cv::Mat left_rect, right_rect, disp16, disp;
  geometry.rectify(frame.left.image, frame.right.image, &left_rect, &right_rect);
  const int block = 5, num = 16 * static_cast<int>(std::ceil(width / 5.0 / 16.0));
  auto sgbm = cv::StereoSGBM::create(0, num, block, 8 * 3 * block * block, 32 * 3 * block * block, 1, 63, 10, 100, 1,
                                     cv::StereoSGBM::MODE_SGBM_3WAY);
  sgbm->compute(left_rect, right_rect, disp16);
  disp16.convertTo(disp, CV_32F, 1.0 / 16.0);
  disp.setTo(std::numeric_limits<float>::quiet_NaN(), disp16 < 0);
  return disp;
}

std::vector<Query> randomQueries(const cv::Mat& mask, std::uint32_t seed, int count,
                                 const camera::StereoModel& geometry) {
  std::vector<cv::Point> pts;
  cv::findNonZero(mask, pts);
  std::mt19937 rng(seed);
  std::shuffle(pts.begin(), pts.end(), rng);
  std::vector<Query> out;
  for (int i = 0; i < count && i < static_cast<int>(pts.size()); ++i)
    out.push_back(Query{geometry.toRectified(cv::Point2f(pts[static_cast<std::size_t>(i)])), nullptr, {}});
  return out;
}

bool Scorer::truth(const cv::Point2f& rect, Eigen::Vector3d* p) const {
  const cv::Point2f raw = geometry_.toRaw(rect);
  Eigen::Vector3d w;
  if (!sampleMap(frame_.left.points, raw.x, raw.y, &w)) return false;
  *p = left_from_world_ * w;
  return true;
}

std::pair<Stats, Stats> Scorer::score(const std::vector<Query>& qs, int queried) const {
  Stats sc, ss;
  sc.queried = ss.queried = queried;
  for (const Query& q : qs) {
    Eigen::Vector3d gt;
    if (!truth(q.rect, &gt)) {  // off the surface: not a fair query for either method
      --sc.queried;
      --ss.queried;
      continue;
    }
    const cect::LocalizedPoint lp = q.cect ? *q.cect : f_.localizeRectified(q.rect);
    if (lp.valid) {
      sc.errors_mm.push_back(1000.0 * (lp.position - gt).norm());
      sc.sigma_px.push_back(lp.disparity_sigma);
      sc.z.push_back(std::abs(lp.disparity - geometry_.project(gt).z()) / std::max(lp.disparity_sigma, 1e-9));
    }
    if (!q.name.empty()) {
      Stats& pp = res_->per_point[q.name];
      pp.queried = 1;
      if (lp.valid)
        pp.errors_mm.push_back(sc.errors_mm.back());
      else
        pp.misses[lp.reason.substr(0, lp.reason.find(" by "))] = 1;
    }
    Eigen::Vector3d ps;
    if (sgbmPoint(q.rect, &ps)) ss.errors_mm.push_back(1000.0 * (ps - gt).norm());
  }
  return std::make_pair(sc, ss);
}

bool Scorer::sgbmPoint(const cv::Point2f& q, Eigen::Vector3d* p) const {
  Eigen::Vector3d d;
  if (!sampleMap(sgbm_, q.x, q.y, &d) || !(d.x() > 0)) return false;
  *p = geometry_.triangulate(q.x, q.y, d.x());
  return true;
}

void scoreByBorder(const Options& o, const sim::StereoFrame& frame, const camera::StereoModel& geometry,
                   const Scorer& scorer, PairResult* res) {
  cv::Mat back_mask = (frame.left.labels == sim::kLabelBack) & (frame.left_visible > 0);
  cv::Mat dist;
  cv::distanceTransform(back_mask, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  const double k = o.width / 640.0;
  std::map<std::string, std::vector<Query>> bands;
  for (int y = 2; y < back_mask.rows; y += 4)
    for (int x = 2; x < back_mask.cols; x += 4) {
      if (!back_mask.at<std::uint8_t>(y, x)) continue;
      const double dpx = dist.at<float>(y, x) / k;
      std::size_t b = 0;
      while (b + 1 < borderBands().size() && dpx >= borderBands()[b + 1].first) ++b;
      const cv::Point2f raw(static_cast<float>(x), static_cast<float>(y));
      bands[borderBands()[b].second].push_back(Query{geometry.toRectified(raw), nullptr, {}});
    }
  for (const auto& [band, qs] : bands)
    std::tie(res->border["cect/" + band], res->border["sgbm/" + band]) = scorer.score(qs, static_cast<int>(qs.size()));
}

}  // namespace massage_cell::tools::cect_eval
