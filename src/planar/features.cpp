// Features of calibrated views and their matches (see features.h).
#include "massage_cell/planar/features.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Dense>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/ximgproc/fast_line_detector.hpp>

namespace massage_cell::planar {

namespace {

constexpr double kDegToRad = M_PI / 180.0;

// Segment refinement: gradient profiles across the segment every pixel,
// kRefineEndMargin px from its ends, sampled kRefineSteps times each side
// kRefineStep px apart; at least kMinRefinePeaks peaks (else the segment
// stays as detected), those off the fitted line by more than
// kMaxRefineResidual px left out.
constexpr double kRefineEndMargin = 3.0;
constexpr int kRefineSteps = 4;
constexpr double kRefineStep = 0.5;
constexpr std::size_t kMinRefinePeaks = 8;
constexpr double kMaxRefineResidual = 0.5;

// Line matching thresholds (the parameters hold the ones a user tunes).
/// Segments closer than this to the epipolar direction of a pair of views
/// are nearly in an epipolar plane: their end points do not transfer, and
/// the depth of their 3D line is 1 / sin(angle) times less certain than a
/// point's (6x at 10 degrees). On Merton College I, where all epipolar
/// lines run nearly horizontally, 5 degrees let wrong matches of
/// near-horizontal edges through (twice as many as at 10).
constexpr double kMinEpipolarAngleDeg = 10.0;
/// The part of a segment covered by the other's epipolar band, as a share of
/// the shorter of the two extents.
constexpr double kMinOverlap = 0.5;
/// Third-view support and track reprojection: segment end points within this
/// many epipolar_tolerance of the reprojected 3D line (the end points of
/// detected segments are noisier than keypoints).
constexpr double kLineToleranceFactor = 2.0;
/// A segment's best candidate is ambiguous when another one (not a fragment
/// of the same edge) with as many supporting views comes within this of its
/// quality: the support's (1 - mean residual / tolerance) or the strip
/// correlation. Repeated structure (window panes) is the usual cause.
constexpr double kSupportMargin = 0.2;
constexpr double kCorrelationMargin = 0.05;
/// Strip correlation: distances from the line sampled on either side
/// (pixels; the first pixel is left out, it holds the blurred edge itself),
/// and the spacing of the samples along the overlap.
constexpr double kStripOffsets[] = {2.0, 3.0, 4.0, 5.0, 6.0};
constexpr double kStripSpacing = 2.0;
constexpr int kMaxStripPositions = 40;
constexpr int kMinStripSamples = 12;
/// A candidate supported by other views must still correlate this well
/// (looser than min_line_ncc: the support is geometric evidence already).
/// Segments of different edges may line up with a third view's segment by
/// chance; such wrong candidates also block the right ones in the mutual
/// best test (Merton College I: 159 tracks, 107 on a reference line, with
/// this test; 148 and 99 without).
constexpr double kMinSupportedNcc = 0.5;

// ---------------------------------------------------------------------------
// Detection

cv::Mat greyImage(const cv::Mat& image) {
  if (image.channels() == 1) return image;
  cv::Mat grey;
  cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  return grey;
}

cv::Ptr<cv::Feature2D> makeDetector(const FeatureParams& params) {
  if (params.detector == "akaze") return cv::AKAZE::create();
  if (params.detector == "orb") return cv::ORB::create(params.max_keypoints);
  return cv::SIFT::create(params.max_keypoints);
}

/// The `count` keypoints of largest response, with their descriptors.
void keepStrongest(int count, std::vector<cv::KeyPoint>* keypoints, cv::Mat* descriptors) {
  if (static_cast<int>(keypoints->size()) <= count) return;
  std::vector<int> order(keypoints->size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return (*keypoints)[static_cast<std::size_t>(a)].response > (*keypoints)[static_cast<std::size_t>(b)].response;
  });
  order.resize(static_cast<std::size_t>(count));
  std::vector<cv::KeyPoint> kept;
  cv::Mat kept_descriptors(count, descriptors->cols, descriptors->type());
  for (int r = 0; r < count; ++r) {
    kept.push_back((*keypoints)[static_cast<std::size_t>(order[static_cast<std::size_t>(r)])]);
    descriptors->row(order[static_cast<std::size_t>(r)]).copyTo(kept_descriptors.row(r));
  }
  *keypoints = std::move(kept);
  *descriptors = kept_descriptors;
}

/// Bilinear value of a CV_32F image, nothing outside it.
std::optional<float> sample(const cv::Mat& grey, const Eigen::Vector2d& p) {
  const double fx = std::floor(p.x()), fy = std::floor(p.y());
  if (!(fx >= 0.0 && fy >= 0.0 && fx + 1.0 < grey.cols && fy + 1.0 < grey.rows)) return std::nullopt;
  const int x = static_cast<int>(fx), y = static_cast<int>(fy);
  const float dx = static_cast<float>(p.x() - fx), dy = static_cast<float>(p.y() - fy);
  const float* r0 = grey.ptr<float>(y);
  const float* r1 = grey.ptr<float>(y + 1);
  return (1 - dy) * ((1 - dx) * r0[x] + dx * r0[x + 1]) + dy * ((1 - dx) * r1[x] + dx * r1[x + 1]);
}

/// The gradient magnitude's peaks across the segment (a parabola through
/// the samples at the maximum) at every pixel along it, away from its ends.
std::vector<Eigen::Vector2d> edgePeaks(const cv::Mat& magnitude, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const double length = (b - a).norm();
  const Eigen::Vector2d dir = (b - a) / length, normal(-dir.y(), dir.x());
  std::vector<Eigen::Vector2d> peaks;
  for (double t = kRefineEndMargin; t <= length - kRefineEndMargin; t += 1.0) {
    std::array<float, 2 * kRefineSteps + 1> profile{};
    bool inside = true;
    for (int k = -kRefineSteps; k <= kRefineSteps && inside; ++k) {
      const auto v = sample(magnitude, a + t * dir + k * kRefineStep * normal);
      inside = v.has_value();
      if (inside) profile[static_cast<std::size_t>(k + kRefineSteps)] = *v;
    }
    const auto top = static_cast<std::size_t>(std::max_element(profile.begin(), profile.end()) - profile.begin());
    if (!inside || top == 0 || top == profile.size() - 1) continue;
    const double l = profile[top - 1], c = profile[top], r = profile[top + 1];
    if (!(l - 2.0 * c + r < 0.0)) continue;  // flat: no peak
    const double offset = (static_cast<double>(top) - kRefineSteps + 0.5 * (l - r) / (l - 2.0 * c + r)) * kRefineStep;
    peaks.push_back(a + t * dir + offset * normal);
  }
  return peaks;
}

/// The segment moved onto the edge it was detected on, to a fraction of a
/// pixel: the principal axis of its edgePeaks, refitted without the peaks
/// off the first fit by more than kMaxRefineResidual, with the end points
/// projected onto it. The detector's own fit follows whole edge pixels.
cv::Vec4f refineSegment(const cv::Mat& magnitude, const cv::Vec4f& segment) {
  const Eigen::Vector2d a(segment[0], segment[1]), b(segment[2], segment[3]);
  std::vector<Eigen::Vector2d> peaks = edgePeaks(magnitude, a, b);
  for (int pass = 0; pass < 2; ++pass) {
    if (peaks.size() < kMinRefinePeaks) return segment;
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    for (const Eigen::Vector2d& p : peaks) centre += p / static_cast<double>(peaks.size());
    Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
    for (const Eigen::Vector2d& p : peaks) scatter += (p - centre) * (p - centre).transpose();
    // The principal axis of a 2x2 scatter matrix, in closed form.
    const double angle = 0.5 * std::atan2(2.0 * scatter(0, 1), scatter(0, 0) - scatter(1, 1));
    const Eigen::Vector2d axis(std::cos(angle), std::sin(angle)), across(-axis.y(), axis.x());
    if (pass == 1) {
      const Eigen::Vector2d ra = centre + (a - centre).dot(axis) * axis, rb = centre + (b - centre).dot(axis) * axis;
      return cv::Vec4f(static_cast<float>(ra.x()), static_cast<float>(ra.y()), static_cast<float>(rb.x()),
                       static_cast<float>(rb.y()));
    }
    peaks.erase(std::remove_if(
                    peaks.begin(), peaks.end(),
                    [&](const Eigen::Vector2d& p) { return std::abs((p - centre).dot(across)) > kMaxRefineResidual; }),
                peaks.end());
  }
  return segment;
}

std::vector<cv::Vec4f> detectSegments(const cv::Mat& grey, double min_length) {
  const int length_threshold = std::max(10, static_cast<int>(min_length));
  std::vector<cv::Vec4f> all, kept;
  cv::ximgproc::createFastLineDetector(length_threshold, 1.414213562f, 50.0, 50.0, 3, true)->detect(grey, all);
  cv::Mat gx, gy, magnitude;
  cv::Sobel(grey, gx, CV_32F, 1, 0);
  cv::Sobel(grey, gy, CV_32F, 0, 1);
  cv::magnitude(gx, gy, magnitude);
  for (const cv::Vec4f& s : all)
    if (std::hypot(s[2] - s[0], s[3] - s[1]) >= min_length) kept.push_back(refineSegment(magnitude, s));
  return kept;
}

// ---------------------------------------------------------------------------
// Shared by point and line matching

void checkInputs(const std::vector<View>& views, const std::vector<ViewFeatures>& features, const FeatureParams& params,
                 const char* what) {
  params.validate();
  validateViews(views);
  if (features.size() != views.size())
    throw std::invalid_argument(std::string(what) + ": " + std::to_string(views.size()) + " views but " +
                                std::to_string(features.size()) + " feature sets");
}

std::vector<Projection> normalisedCameras(const std::vector<View>& views) {
  std::vector<Projection> cameras;
  for (const View& v : views) cameras.push_back(normalisedProjection(v.P));
  return cameras;
}

Eigen::Vector2d toEigen(const cv::Point2f& p) { return {p.x, p.y}; }

/// Line scaled so that (a, b) is a unit normal (a point's distance is then l . x).
Eigen::Vector3d unitLine(const Eigen::Vector3d& l) { return l / l.head<2>().norm(); }

/// Union-find over the features of all views, (view, index) -> one integer.
class FeatureSets {
 public:
  explicit FeatureSets(const std::vector<int>& counts) {
    for (int c : counts) {
      offsets_.push_back(static_cast<int>(parent_.size()));
      for (int k = 0; k < c; ++k) views_.push_back({static_cast<int>(offsets_.size()) - 1});
      parent_.resize(parent_.size() + static_cast<std::size_t>(c));
    }
    std::iota(parent_.begin(), parent_.end(), 0);
  }
  void join(const Observation& a, const Observation& b) { merge(find(id(a)), find(id(b))); }
  /// Joins the sets of a and b unless they hold features of a common view;
  /// false when they do.
  bool joinDisjoint(const Observation& a, const Observation& b) {
    const std::size_t ra = find(id(a)), rb = find(id(b));
    if (ra == rb) return true;
    for (int v : views_[ra])
      if (std::find(views_[rb].begin(), views_[rb].end(), v) != views_[rb].end()) return false;
    merge(ra, rb);
    return true;
  }
  /// Groups of >= 2 features with at most one per view (a group holding two
  /// features of one view joins inconsistent matches and is left out).
  std::vector<std::vector<Observation>> tracks() {
    std::vector<std::vector<Observation>> groups(parent_.size());
    for (std::size_t v = 0; v < offsets_.size(); ++v) {
      const int end = v + 1 < offsets_.size() ? offsets_[v + 1] : static_cast<int>(parent_.size());
      for (int i = offsets_[v]; i < end; ++i)
        groups[find(static_cast<std::size_t>(i))].emplace_back(static_cast<int>(v), i - offsets_[v]);
    }
    std::vector<std::vector<Observation>> result;
    for (auto& g : groups) {
      bool repeated_view = false;
      for (std::size_t k = 1; k < g.size(); ++k) repeated_view |= g[k].first == g[k - 1].first;
      if (g.size() >= 2 && !repeated_view) result.push_back(std::move(g));
    }
    return result;
  }

 private:
  std::size_t id(const Observation& o) const {
    return static_cast<std::size_t>(offsets_[static_cast<std::size_t>(o.first)] + o.second);
  }
  std::size_t find(std::size_t i) {
    while (parent_[i] != static_cast<int>(i)) {
      parent_[i] = parent_[static_cast<std::size_t>(parent_[i])];
      i = static_cast<std::size_t>(parent_[i]);
    }
    return i;
  }
  void merge(std::size_t ra, std::size_t rb) {
    if (ra == rb) return;
    parent_[ra] = static_cast<int>(rb);
    views_[rb].insert(views_[rb].end(), views_[ra].begin(), views_[ra].end());
    views_[ra].clear();
  }
  std::vector<int> offsets_, parent_;
  std::vector<std::vector<int>> views_;  ///< per set root: the views of its features
};

// ---------------------------------------------------------------------------
// Point matching

/// mask(k, m) = 1 when keypoint m of view b lies within `tolerance` of the
/// epipolar line of keypoint k of view a, and k within `tolerance` of m's.
cv::Mat epipolarMask(const std::vector<cv::KeyPoint>& ka, const std::vector<cv::KeyPoint>& kb, const Eigen::Matrix3d& F,
                     double tolerance) {
  std::vector<Eigen::Vector3d> lines_in_b, lines_in_a;
  for (const cv::KeyPoint& k : ka) lines_in_b.push_back(unitLine(F * toEigen(k.pt).homogeneous()));
  for (const cv::KeyPoint& k : kb) lines_in_a.push_back(unitLine(F.transpose() * toEigen(k.pt).homogeneous()));
  cv::Mat mask(static_cast<int>(ka.size()), static_cast<int>(kb.size()), CV_8U);
  for (std::size_t r = 0; r < ka.size(); ++r) {
    const Eigen::Vector3d xa = toEigen(ka[r].pt).homogeneous();
    auto* row = mask.ptr<unsigned char>(static_cast<int>(r));
    for (std::size_t c = 0; c < kb.size(); ++c) {
      const Eigen::Vector3d xb = toEigen(kb[c].pt).homogeneous();
      row[c] = std::abs(lines_in_b[r].dot(xb)) <= tolerance && std::abs(lines_in_a[c].dot(xa)) <= tolerance;
    }
  }
  return mask;
}

/// best[k]: the keypoint of `train` matched to query keypoint k, or -1. The
/// match is the nearest descriptor among the epipolar candidates and passes
/// Lowe's ratio against the second nearest candidate; a lone candidate
/// against the nearest other descriptor of the whole view.
std::vector<int> guidedMatches(const cv::Mat& query, const cv::Mat& train, const cv::Mat& mask, double ratio) {
  const int norm = query.type() == CV_8U ? cv::NORM_HAMMING : cv::NORM_L2;
  cv::BFMatcher matcher(norm);
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(query, train, knn, 2, mask);
  std::vector<int> best(static_cast<std::size_t>(query.rows), -1);
  for (const auto& m : knn) {
    if (m.empty()) continue;
    if (m.size() == 1) {
      std::vector<std::vector<cv::DMatch>> any;
      matcher.knnMatch(query.row(m[0].queryIdx), train, any, 2);
      if (any[0].size() < 2) continue;
      const cv::DMatch& other = any[0][0].trainIdx == m[0].trainIdx ? any[0][1] : any[0][0];
      if (m[0].distance < ratio * other.distance) best[static_cast<std::size_t>(m[0].queryIdx)] = m[0].trainIdx;
    } else if (m[0].distance < ratio * m[1].distance) {
      best[static_cast<std::size_t>(m[0].queryIdx)] = m[0].trainIdx;
    }
  }
  return best;
}

/// Mutually best, ratio-tested, epipolar-consistent keypoint pairs of views a and b.
std::vector<std::pair<int, int>> matchPair(const ViewFeatures& a, const ViewFeatures& b, const Eigen::Matrix3d& F,
                                           const FeatureParams& params) {
  if (a.keypoints.empty() || b.keypoints.empty()) return {};
  const cv::Mat mask = epipolarMask(a.keypoints, b.keypoints, F, params.epipolar_tolerance);
  const std::vector<int> ab = guidedMatches(a.descriptors, b.descriptors, mask, params.ratio);
  const std::vector<int> ba = guidedMatches(b.descriptors, a.descriptors, mask.t(), params.ratio);
  std::vector<std::pair<int, int>> pairs;
  for (std::size_t k = 0; k < ab.size(); ++k)
    if (ab[k] >= 0 && ba[static_cast<std::size_t>(ab[k])] == static_cast<int>(k))
      pairs.emplace_back(static_cast<int>(k), ab[k]);
  return pairs;
}

void checkPointFeatures(const std::vector<ViewFeatures>& features) {
  int type = -1;  // of the first view with keypoints
  for (std::size_t v = 0; v < features.size(); ++v) {
    const ViewFeatures& f = features[v];
    if (f.descriptors.rows != static_cast<int>(f.keypoints.size()))
      throw std::invalid_argument("matchPoints: view " + std::to_string(v) + " has " +
                                  std::to_string(f.keypoints.size()) + " keypoints but " +
                                  std::to_string(f.descriptors.rows) + " descriptors");
    if (f.keypoints.empty()) continue;
    if (type >= 0 && f.descriptors.type() != type)
      throw std::invalid_argument("matchPoints: view " + std::to_string(v) +
                                  "'s descriptors differ in type from the other views'");
    type = f.descriptors.type();
  }
}

/// The track triangulated from all its observations; while a reprojection
/// misses by more than `tolerance` (or the point is behind a camera) the
/// worst observation is dropped. Nothing when fewer than 2 remain.
std::optional<PointTrack> fitPointTrack(std::vector<Observation> observations, const std::vector<Projection>& cameras,
                                        const std::vector<ViewFeatures>& features, double tolerance) {
  while (observations.size() >= 2) {
    std::vector<Projection> P;
    std::vector<Eigen::Vector2d> x;
    for (const Observation& o : observations) {
      P.push_back(cameras[static_cast<std::size_t>(o.first)]);
      x.push_back(
          toEigen(features[static_cast<std::size_t>(o.first)].keypoints[static_cast<std::size_t>(o.second)].pt));
    }
    const Eigen::Vector3d X = triangulatePoint(P, x);
    std::vector<double> errors;
    for (std::size_t k = 0; k < P.size(); ++k) {
      Eigen::Vector2d pixel;
      errors.push_back(X.allFinite() && project(P[k], X, &pixel) ? (pixel - x[k]).norm()
                                                                 : std::numeric_limits<double>::infinity());
    }
    const auto worst = std::max_element(errors.begin(), errors.end());
    if (*worst <= tolerance) {
      PointTrack track;
      track.X = X;
      track.observations = std::move(observations);
      double sum = 0.0;
      for (double e : errors) sum += e * e;
      track.reprojection_rms = std::sqrt(sum / static_cast<double>(errors.size()));
      return track;
    }
    observations.erase(observations.begin() + (worst - errors.begin()));
  }
  return std::nullopt;
}

// ---------------------------------------------------------------------------
// Line matching

struct Segment {
  Eigen::Vector2d a = Eigen::Vector2d::Zero(), b = Eigen::Vector2d::Zero();
  Eigen::Vector2d dir = Eigen::Vector2d::Zero();   ///< unit, a -> b
  Eigen::Vector3d line = Eigen::Vector3d::Zero();  ///< imageLine(a, b)
  double length = 0.0;                             ///< 0 for a degenerate segment (never matched)
};

std::vector<Segment> toSegments(const std::vector<cv::Vec4f>& raw) {
  std::vector<Segment> segments(raw.size());
  for (std::size_t k = 0; k < raw.size(); ++k) {
    Segment& s = segments[k];
    s.a = {raw[k][0], raw[k][1]};
    s.b = {raw[k][2], raw[k][3]};
    s.length = (s.b - s.a).norm();
    if (!(s.length > 0.0) || !std::isfinite(s.length)) {
      s.length = 0.0;
      continue;
    }
    s.dir = (s.b - s.a) / s.length;
    s.line = imageLine(s.a, s.b);
  }
  return segments;
}

/// away[k]: segment k is at least kMinEpipolarAngleDeg from the epipolar
/// line through its midpoint (the line to `epipole`, the image of another
/// view's centre).
std::vector<bool> awayFromEpipolarPlanes(const std::vector<Segment>& segments, const Eigen::Vector3d& epipole) {
  const double min_sin = std::sin(kMinEpipolarAngleDeg * kDegToRad);
  std::vector<bool> away(segments.size(), false);
  for (std::size_t k = 0; k < segments.size(); ++k) {
    const Segment& s = segments[k];
    if (s.length == 0.0) continue;
    const Eigen::Vector3d l = epipole.cross((0.5 * (s.a + s.b)).homogeneous());
    const double n = l.head<2>().norm();
    away[k] = n > 0.0 && std::abs(l.head<2>().dot(s.dir)) / n >= min_sin;
  }
  return away;
}

/// Everything the line matching of a set of views uses.
struct LineViews {
  std::vector<Projection> cameras;
  std::vector<std::vector<Segment>> segments;
  /// usable[v][w][k]: segment k of view v is away from the epipolar planes
  /// of views v and w: its end points transfer to w, and a view w segment
  /// on its 3D line is evidence (in an epipolar plane, any would fit).
  std::vector<std::vector<std::vector<bool>>> usable;
  std::vector<cv::Size> sizes;
  std::vector<cv::Mat> grey;  ///< float grey images for the strip correlation
  double tolerance = 0.0;     ///< pixels: segment end points from a reprojected 3D line
  FeatureParams params;

  const Projection& P(int v) const { return cameras[static_cast<std::size_t>(v)]; }
  const std::vector<Segment>& S(int v) const { return segments[static_cast<std::size_t>(v)]; }
  const Segment& S(const Observation& o) const { return S(o.first)[static_cast<std::size_t>(o.second)]; }
  bool isUsable(int v, int w, int k) const {
    return usable[static_cast<std::size_t>(v)][static_cast<std::size_t>(w)][static_cast<std::size_t>(k)];
  }
  int count() const { return static_cast<int>(cameras.size()); }
};

std::vector<cv::Mat> floatGrey(const std::vector<View>& views) {
  std::vector<cv::Mat> grey;
  for (const View& v : views) {
    cv::Mat g;
    greyImage(v.image).convertTo(g, CV_32F);
    grey.push_back(g);
  }
  return grey;
}

LineViews makeLineViews(const std::vector<View>& views, const std::vector<ViewFeatures>& features,
                        const FeatureParams& params) {
  LineViews m;
  m.cameras = normalisedCameras(views);
  for (const ViewFeatures& f : features) m.segments.push_back(toSegments(f.segments));
  m.usable.resize(views.size(), std::vector<std::vector<bool>>(views.size()));
  for (std::size_t v = 0; v < views.size(); ++v)
    for (std::size_t w = 0; w < views.size(); ++w)
      if (v != w)
        m.usable[v][w] = awayFromEpipolarPlanes(m.segments[v], m.cameras[v] * cameraCentre(m.cameras[w]).homogeneous());
  for (const View& v : views) m.sizes.push_back(v.image.size());
  m.grey = floatGrey(views);
  m.tolerance = kLineToleranceFactor * params.epipolar_tolerance;
  m.params = params;
  return m;
}

/// Point of the image line l (unit normal) where line m crosses it, as the
/// distance from `origin` along `dir`; nothing when they are (nearly) parallel.
std::optional<double> crossingParameter(const Eigen::Vector3d& l, const Eigen::Vector3d& m,
                                        const Eigen::Vector2d& origin, const Eigen::Vector2d& dir) {
  const Eigen::Vector3d x = l.cross(m);
  if (!(std::abs(x.z()) > 1e-12 * x.head<2>().norm())) return std::nullopt;
  return (x.hnormalized() - origin).dot(dir);
}

/// The part of segment t (parameters along t, pixels from t.a) between the
/// epipolar lines of the other view's segment's end points.
struct Overlap {
  double lo = 0.0, hi = 0.0;
  bool reversed = false;  ///< t runs against the other segment's a -> b
};

std::optional<Overlap> epipolarOverlap(const Segment& t, const Eigen::Vector3d& epi_a, const Eigen::Vector3d& epi_b) {
  const auto ua = crossingParameter(t.line, epi_a, t.a, t.dir), ub = crossingParameter(t.line, epi_b, t.a, t.dir);
  if (!ua || !ub) return std::nullopt;
  Overlap o;
  o.lo = std::max(0.0, std::min(*ua, *ub));
  o.hi = std::min(t.length, std::max(*ua, *ub));
  o.reversed = *ub < *ua;
  if (!(o.hi - o.lo >= kMinOverlap * std::min(std::abs(*ub - *ua), t.length)) || o.hi <= o.lo) return std::nullopt;
  return o;
}

/// Image of the 3D line (point X, direction d) in camera P, with a unit
/// normal; nothing when the line passes through the camera centre.
std::optional<Eigen::Vector3d> projectedLine(const Projection& P, const Eigen::Vector3d& X, const Eigen::Vector3d& d) {
  const Eigen::Vector3d l = (P * X.homogeneous()).cross(P.leftCols<3>() * d);
  const double n = l.head<2>().norm();
  if (!(n > 0.0) || !l.allFinite()) return std::nullopt;
  return Eigen::Vector3d(l / n);
}

/// A 3D segment: its line (point, unit direction) and end points.
struct Line3 {
  Eigen::Vector3d point, direction, a, b;
};

/// The 3D line of segments s (view i) and t (view j), bounded by their
/// overlap on t; nothing when it cannot be triangulated or lies behind a camera.
std::optional<Line3> pairLine(const Projection& Pi, const Projection& Pj, const Segment& s, const Segment& t,
                              const Overlap& o) {
  Line3 L;
  if (!triangulateLine({Pi, Pj}, {s.line, t.line}, &L.point, &L.direction)) return std::nullopt;
  L.a = closestOnLineToRay(Pj, t.a + o.lo * t.dir, L.point, L.direction);
  L.b = closestOnLineToRay(Pj, t.a + o.hi * t.dir, L.point, L.direction);
  for (const Projection* P : {&Pi, &Pj})
    if (!(depthOf(*P, L.a) > 0.0) || !(depthOf(*P, L.b) > 0.0)) return std::nullopt;
  return L;
}

/// A pair of segments that may be one 3D line.
struct LineCandidate {
  Observation s, t;
  std::vector<Observation> support;  ///< segments of other views on the 3D line
  /// With support: 1 - mean support residual / tolerance; without (no other
  /// view sees the line): the strip correlation.
  double quality = 0.0;
};

/// More supporting views first, then the higher quality.
bool better(const LineCandidate& a, const LineCandidate& b) {
  return a.support.size() != b.support.size() ? a.support.size() > b.support.size() : a.quality > b.quality;
}

/// The reprojection into view k of the candidate's 3D segment, when view k
/// can check it: the candidate's segments are away from the epipolar planes
/// shared with k, and the 3D segment is in front of k and inside its image.
std::optional<std::pair<Eigen::Vector2d, Eigen::Vector2d>> verifiableIn(const LineViews& m, const LineCandidate& c,
                                                                        int k, const Line3& L) {
  if (!m.isUsable(c.s.first, k, c.s.second) || !m.isUsable(c.t.first, k, c.t.second)) return std::nullopt;
  Eigen::Vector2d a, b;
  if (!project(m.P(k), L.a, &a) || !project(m.P(k), L.b, &b) || !((b - a).norm() >= 1.0)) return std::nullopt;
  const cv::Size& size = m.sizes[static_cast<std::size_t>(k)];
  for (const Eigen::Vector2d& p : {a, b})
    if (!(p.x() >= 0.0 && p.y() >= 0.0 && p.x() <= size.width - 1.0 && p.y() <= size.height - 1.0)) return std::nullopt;
  return std::make_pair(a, b);
}

/// The segment of view k closest to the reprojected 3D segment a-b (usable
/// against the candidate's views), by the worse of its end points'
/// distances; nothing when none is within the tolerance and overlaps a-b.
std::optional<std::pair<int, double>> segmentOn(const LineViews& m, const LineCandidate& c, int k,
                                                const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const double length = (b - a).norm();
  const Eigen::Vector3d l = imageLine(a, b);
  const Eigen::Vector2d dir = (b - a) / length;
  std::optional<std::pair<int, double>> best;
  for (int u = 0; u < static_cast<int>(m.S(k).size()); ++u) {
    const Segment& seg = m.S(k)[static_cast<std::size_t>(u)];
    if (!m.isUsable(k, c.s.first, u) || !m.isUsable(k, c.t.first, u)) continue;
    const double residual = std::max(std::abs(l.dot(seg.a.homogeneous())), std::abs(l.dot(seg.b.homogeneous())));
    if (residual > m.tolerance || (best && residual >= best->second)) continue;
    const double pa = (seg.a - a).dot(dir), pb = (seg.b - a).dot(dir);
    const double overlap = std::min(length, std::max(pa, pb)) - std::max(0.0, std::min(pa, pb));
    if (overlap >= kMinOverlap * std::min(length, seg.length)) best = std::make_pair(u, residual);
  }
  return best;
}

/// The other views' segments on the candidate's reprojected 3D line (its
/// support and quality); returns the number of views that could check it.
int supportLine(const LineViews& m, const Line3& L, LineCandidate* c) {
  int verifiers = 0;
  double residuals = 0.0;
  for (int k = 0; k < m.count(); ++k) {
    if (k == c->s.first || k == c->t.first) continue;
    const auto ends = verifiableIn(m, *c, k, L);
    if (!ends) continue;
    ++verifiers;
    if (const auto u = segmentOn(m, *c, k, ends->first, ends->second)) {
      c->support.emplace_back(k, u->first);
      residuals += u->second;
    }
  }
  if (!c->support.empty()) c->quality = 1.0 - residuals / (static_cast<double>(c->support.size()) * m.tolerance);
  return verifiers;
}

double ncc(const std::vector<float>& u, const std::vector<float>& v) {
  const std::size_t n = u.size();
  if (static_cast<int>(n) < kMinStripSamples) return -1.0;
  double mu = 0.0, mv = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    mu += u[k];
    mv += v[k];
  }
  mu /= static_cast<double>(n);
  mv /= static_cast<double>(n);
  double suv = 0.0, suu = 0.0, svv = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    suv += (u[k] - mu) * (v[k] - mv);
    suu += (u[k] - mu) * (u[k] - mu);
    svv += (v[k] - mv) * (v[k] - mv);
  }
  if (!(suu > 1e-6 * static_cast<double>(n) && svv > 1e-6 * static_cast<double>(n))) return -1.0;
  return suv / std::sqrt(suu * svv);
}

/// The better of the normalised cross-correlations of the strips left and
/// right of segments s (view i) and t (view j), sampled at
/// epipolar-corresponding positions along their overlap (one side may be
/// occluded in one view, so the better side decides).
double stripCorrelation(const cv::Mat& grey_i, const cv::Mat& grey_j, const Segment& s, const Segment& t,
                        const Overlap& o, const Eigen::Matrix3d& F) {
  const int positions = std::clamp(static_cast<int>((o.hi - o.lo) / kStripSpacing), 3, kMaxStripPositions);
  const Eigen::Vector2d normal_s(-s.dir.y(), s.dir.x());
  const Eigen::Vector2d normal_t = Eigen::Vector2d(-t.dir.y(), t.dir.x()) * (o.reversed ? -1.0 : 1.0);
  std::vector<float> left_i, left_j, right_i, right_j;
  for (int k = 0; k < positions; ++k) {
    const Eigen::Vector2d q = t.a + (o.lo + (k + 0.5) * (o.hi - o.lo) / positions) * t.dir;
    const auto u = crossingParameter(s.line, F.transpose() * q.homogeneous(), s.a, s.dir);
    if (!u) continue;
    const Eigen::Vector2d p = s.a + *u * s.dir;
    for (double offset : kStripOffsets) {
      for (const double side : {1.0, -1.0}) {
        const auto vi = sample(grey_i, p + side * offset * normal_s), vj = sample(grey_j, q + side * offset * normal_t);
        if (!vi || !vj) continue;
        (side > 0 ? left_i : right_i).push_back(*vi);
        (side > 0 ? left_j : right_j).push_back(*vj);
      }
    }
  }
  return std::max(ncc(left_i, left_j), ncc(right_i, right_j));
}

/// t's direction against s's carried over by the infinite homography (the
/// views' rotation), within max_line_angle_deg: a cheap test before the
/// strip correlation.
bool orientationAgrees(const Eigen::Matrix3d& H_inf, const Segment& s, const Segment& t, double max_angle_deg) {
  const Eigen::Vector3d a = H_inf * s.a.homogeneous(), b = H_inf * s.b.homogeneous();
  if (!(std::abs(a.z()) > 0.0 && std::abs(b.z()) > 0.0)) return true;  // mapped to infinity: no evidence
  const Eigen::Vector2d d = b.hnormalized() - a.hnormalized();
  const double n = d.norm();
  return !(n > 0.0) || std::abs(d.dot(t.dir)) / n >= std::cos(max_angle_deg * kDegToRad);
}

/// Each segment of view i against each of view j: epipolar overlap and
/// triangulation, then the segments of other views on the 3D line and a
/// loose strip correlation, or (two views, or no other view sees the line)
/// the orientation and a strict strip correlation.
std::vector<LineCandidate> lineCandidates(const LineViews& m, int i, int j) {
  const Eigen::Matrix3d F = fundamental(m.P(i), m.P(j));
  const Eigen::Matrix3d H_inf = m.P(j).leftCols<3>() * m.P(i).leftCols<3>().inverse();
  std::vector<LineCandidate> candidates;
  for (int s = 0; s < static_cast<int>(m.S(i).size()); ++s) {
    if (!m.isUsable(i, j, s)) continue;
    const Segment& ss = m.S(i)[static_cast<std::size_t>(s)];
    const Eigen::Vector3d epi_a = F * ss.a.homogeneous(), epi_b = F * ss.b.homogeneous();
    for (int t = 0; t < static_cast<int>(m.S(j).size()); ++t) {
      if (!m.isUsable(j, i, t)) continue;
      const Segment& st = m.S(j)[static_cast<std::size_t>(t)];
      const auto overlap = epipolarOverlap(st, epi_a, epi_b);
      if (!overlap) continue;
      const auto line = pairLine(m.P(i), m.P(j), ss, st, *overlap);
      if (!line) continue;
      const auto correlation = [&] {
        return stripCorrelation(m.grey[static_cast<std::size_t>(i)], m.grey[static_cast<std::size_t>(j)], ss, st,
                                *overlap, F);
      };
      LineCandidate c{{i, s}, {j, t}, {}, 0.0};
      if (supportLine(m, *line, &c) > 0) {
        if (!c.support.empty() && correlation() >= kMinSupportedNcc) candidates.push_back(std::move(c));
        continue;
      }
      if (!orientationAgrees(H_inf, ss, st, m.params.max_line_angle_deg)) continue;
      c.quality = correlation();
      if (c.quality >= m.params.min_line_ncc) candidates.push_back(std::move(c));
    }
  }
  return candidates;
}

/// Segment b lies on a's line (both end points within `tolerance`): two
/// fragments of one edge.
bool onLineOf(const Segment& a, const Segment& b, double tolerance) {
  return std::abs(a.line.dot(b.a.homogeneous())) <= tolerance && std::abs(a.line.dot(b.b.homogeneous())) <= tolerance;
}

/// Per segment of one view (the first or second of the candidates' pair):
/// its best candidate, or -1 when it has none or an ambiguous one (another
/// candidate, not a fragment of the same edge, as good within a margin).
std::vector<int> distinctBest(const LineViews& m, const std::vector<LineCandidate>& candidates, bool first) {
  const auto own = [&](int k) {
    return first ? candidates[static_cast<std::size_t>(k)].s : candidates[static_cast<std::size_t>(k)].t;
  };
  const auto other = [&](int k) -> const Segment& {
    return m.S(first ? candidates[static_cast<std::size_t>(k)].t : candidates[static_cast<std::size_t>(k)].s);
  };
  std::vector<std::vector<int>> of(m.S(own(0).first).size());
  for (int k = 0; k < static_cast<int>(candidates.size()); ++k)
    of[static_cast<std::size_t>(own(k).second)].push_back(k);
  std::vector<int> best(of.size(), -1);
  for (std::size_t s = 0; s < of.size(); ++s) {
    if (of[s].empty()) continue;
    const auto c = [&](int k) -> const LineCandidate& { return candidates[static_cast<std::size_t>(k)]; };
    const int top = *std::max_element(of[s].begin(), of[s].end(), [&](int a, int b) { return better(c(b), c(a)); });
    const double margin = c(top).support.empty() ? kCorrelationMargin : kSupportMargin;
    bool ambiguous = false;
    for (int k : of[s])
      ambiguous |= k != top && c(k).support.size() == c(top).support.size() && c(k).quality > c(top).quality - margin &&
                   !onLineOf(other(top), other(k), m.tolerance);
    if (!ambiguous) best[s] = top;
  }
  return best;
}

/// The candidates that are the distinct best of both their segments.
std::vector<LineCandidate> mutualBest(const LineViews& m, const std::vector<LineCandidate>& candidates) {
  if (candidates.empty()) return {};
  const std::vector<int> best_s = distinctBest(m, candidates, true), best_t = distinctBest(m, candidates, false);
  std::vector<LineCandidate> kept;
  for (int k = 0; k < static_cast<int>(candidates.size()); ++k) {
    const LineCandidate& c = candidates[static_cast<std::size_t>(k)];
    if (best_s[static_cast<std::size_t>(c.s.second)] == k && best_t[static_cast<std::size_t>(c.t.second)] == k)
      kept.push_back(c);
  }
  return kept;
}

/// The extent on the 3D line of all observed segments' end points.
std::optional<LineTrack> boundedTrack(const LineViews& m, const Line3& L, std::vector<Observation> observations) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const Observation& o : observations) {
    for (const Eigen::Vector2d& end : {m.S(o).a, m.S(o).b}) {
      const Eigen::Vector3d X = closestOnLineToRay(m.P(o.first), end, L.point, L.direction);
      if (!(depthOf(m.P(o.first), X) > 0.0)) return std::nullopt;
      const double tau = (X - L.point).dot(L.direction);
      lo = std::min(lo, tau);
      hi = std::max(hi, tau);
    }
  }
  LineTrack track;
  track.a = L.point + lo * L.direction;
  track.b = L.point + hi * L.direction;
  track.observations = std::move(observations);
  return track;
}

/// The track's 3D line from all its observations; while an observed
/// segment's end point lies farther than the tolerance from the reprojected
/// line, the worst observation is dropped. Nothing when fewer than 2 remain.
std::optional<LineTrack> fitLineTrack(const LineViews& m, std::vector<Observation> observations) {
  while (observations.size() >= 2) {
    std::vector<Projection> P;
    std::vector<Eigen::Vector3d> lines;
    for (const Observation& o : observations) {
      P.push_back(m.P(o.first));
      lines.push_back(m.S(o).line);
    }
    Line3 L;
    if (!triangulateLine(P, lines, &L.point, &L.direction)) return std::nullopt;
    std::vector<double> residuals;
    for (std::size_t k = 0; k < P.size(); ++k) {
      const Segment& s = m.S(observations[k]);
      const auto l = projectedLine(P[k], L.point, L.direction);
      residuals.push_back(l ? std::max(std::abs(l->dot(s.a.homogeneous())), std::abs(l->dot(s.b.homogeneous())))
                            : std::numeric_limits<double>::infinity());
    }
    const auto worst = std::max_element(residuals.begin(), residuals.end());
    if (*worst <= m.tolerance) return boundedTrack(m, L, std::move(observations));
    observations.erase(observations.begin() + (worst - residuals.begin()));
  }
  return std::nullopt;
}

}  // namespace

void FeatureParams::validate() const {
  if (detector != "akaze" && detector != "orb" && detector != "sift")
    throw std::invalid_argument("FeatureParams.detector must be \"akaze\", \"orb\" or \"sift\", not \"" + detector +
                                "\"");
  if (max_keypoints < 1) throw std::invalid_argument("FeatureParams.max_keypoints must be >= 1");
  if (!(min_segment_length >= 0.0 && min_segment_length < 1.0))
    throw std::invalid_argument("FeatureParams.min_segment_length must be in [0, 1) (a fraction of the diagonal)");
  if (!(epipolar_tolerance > 0.0) || !std::isfinite(epipolar_tolerance))
    throw std::invalid_argument("FeatureParams.epipolar_tolerance must be > 0 pixels");
  if (!(ratio > 0.0 && ratio <= 1.0)) throw std::invalid_argument("FeatureParams.ratio must be in (0, 1]");
  if (!(min_line_ncc >= -1.0 && min_line_ncc <= 1.0))
    throw std::invalid_argument("FeatureParams.min_line_ncc must be in [-1, 1]");
  if (!(max_line_angle_deg > 0.0 && max_line_angle_deg <= 90.0))
    throw std::invalid_argument("FeatureParams.max_line_angle_deg must be in (0, 90]");
}

ViewFeatures detectFeatures(const View& view, const FeatureParams& params) {
  params.validate();
  if (view.image.empty()) throw std::invalid_argument("detectFeatures: view \"" + view.name + "\" has an empty image");
  if (view.image.depth() != CV_8U || (view.image.channels() != 1 && view.image.channels() != 3))
    throw std::invalid_argument("detectFeatures: view \"" + view.name + "\" image is not 8-bit grey or BGR");
  const cv::Mat grey = greyImage(view.image);
  ViewFeatures f;
  makeDetector(params)->detectAndCompute(grey, cv::noArray(), f.keypoints, f.descriptors);
  keepStrongest(params.max_keypoints, &f.keypoints, &f.descriptors);
  f.segments = detectSegments(grey, params.min_segment_length * std::hypot(grey.cols, grey.rows));
  return f;
}

std::vector<PointTrack> matchPoints(const std::vector<View>& views, const std::vector<ViewFeatures>& features,
                                    const FeatureParams& params) {
  checkInputs(views, features, params, "matchPoints");
  checkPointFeatures(features);
  const std::vector<Projection> cameras = normalisedCameras(views);
  std::vector<int> counts;
  for (const ViewFeatures& f : features) counts.push_back(static_cast<int>(f.keypoints.size()));
  FeatureSets sets(counts);
  for (int i = 0; i < static_cast<int>(views.size()); ++i)
    for (int j = i + 1; j < static_cast<int>(views.size()); ++j) {
      const Eigen::Matrix3d F = fundamental(cameras[static_cast<std::size_t>(i)], cameras[static_cast<std::size_t>(j)]);
      for (const auto& [a, b] :
           matchPair(features[static_cast<std::size_t>(i)], features[static_cast<std::size_t>(j)], F, params))
        sets.join({i, a}, {j, b});
    }
  std::vector<PointTrack> tracks;
  for (auto& observations : sets.tracks())
    if (auto track = fitPointTrack(std::move(observations), cameras, features, params.epipolar_tolerance))
      tracks.push_back(std::move(*track));
  return tracks;
}

std::vector<LineTrack> matchLines(const std::vector<View>& views, const std::vector<ViewFeatures>& features,
                                  const FeatureParams& params) {
  checkInputs(views, features, params, "matchLines");
  const LineViews m = makeLineViews(views, features, params);
  std::vector<int> counts;
  for (const ViewFeatures& f : features) counts.push_back(static_cast<int>(f.segments.size()));
  std::vector<LineCandidate> matches;
  for (int i = 0; i < m.count(); ++i)
    for (int j = i + 1; j < m.count(); ++j)
      for (LineCandidate& c : mutualBest(m, lineCandidates(m, i, j))) matches.push_back(std::move(c));
  // Best matches first; a match that would put two segments of one view in
  // a track (fragments of one edge, or a worse match) is left out.
  std::stable_sort(matches.begin(), matches.end(), better);
  FeatureSets sets(counts);
  for (const LineCandidate& c : matches)
    if (sets.joinDisjoint(c.s, c.t))
      for (const Observation& o : c.support) sets.joinDisjoint(c.s, o);
  std::vector<LineTrack> tracks;
  for (auto& observations : sets.tracks())
    if (auto track = fitLineTrack(m, std::move(observations))) tracks.push_back(std::move(*track));
  return tracks;
}

}  // namespace massage_cell::planar
