// Scoring a piecewise-planar model against reference planes, the facets'
// index image per view (exact per-pixel depth of each facet's plane, nearest
// wins), and the reference of a VGG set: planes found in its 3D points by
// sequential RANSAC.
#include "massage_cell/planar/evaluation.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/LU>

namespace massage_cell::planar {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
/// Polygons are clipped this many pixels outside the image, and to depths
/// above kMinDepth (any world unit): the projected vertices stay finite and
/// small whatever lies behind or beside the camera.
constexpr double kClipMargin = 2.0;
constexpr double kMinDepth = 1e-9;
/// Reference planes closer than this in angle are not a pair (parallel faces).
constexpr double kMinPairAngleDeg = 5.0;
constexpr std::uint32_t kRansacSeed = 27;
constexpr int kRansacSamples = 2000;

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// ---------------------------------------------------------------------------
// Facet index image

using HalfSpace = Eigen::Vector4d;  ///< h . (X, 1) >= 0

/// Sutherland-Hodgman: the part of a convex polygon inside one half-space.
std::vector<Eigen::Vector3d> clip(const std::vector<Eigen::Vector3d>& polygon, const HalfSpace& h) {
  std::vector<Eigen::Vector3d> out;
  const auto side = [&](const Eigen::Vector3d& X) { return h.head<3>().dot(X) + h[3]; };
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const Eigen::Vector3d& a = polygon[i];
    const Eigen::Vector3d& b = polygon[(i + 1) % polygon.size()];
    const double sa = side(a), sb = side(b);
    if (sa >= 0.0) out.push_back(a);
    if ((sa >= 0.0) != (sb >= 0.0)) out.push_back(a + (b - a) * (sa / (sa - sb)));
  }
  return out;
}

/// In front of the camera and within the image (plus a margin): the image
/// coordinates x = P0.X / w, y = P1.X / w of normalised P, w = P2.X > 0.
std::vector<HalfSpace> frustum(const Projection& P, int width, int height) {
  const Eigen::Vector4d px = P.row(0).transpose(), py = P.row(1).transpose(), pw = P.row(2).transpose();
  return {pw - kMinDepth * Eigen::Vector4d::UnitW(), px + kClipMargin * pw, (width - 1 + kClipMargin) * pw - px,
          py + kClipMargin * pw, (height - 1 + kClipMargin) * pw - py};
}

/// Depth w of the facet plane along the ray of each pixel: with P = [M | p],
/// X = M^-1 (w u - p) on n.X + d = 0 gives w = (a.p - d) / (a.u), a = M^-T n.
struct PlaneDepth {
  Eigen::Vector3d a;
  double numerator = 0.0;
  PlaneDepth(const Projection& P, const Plane& plane) {
    a = P.leftCols<3>().transpose().inverse() * plane.n;
    numerator = a.dot(P.col(3)) - plane.d;
  }
  double at(int x, int y) const { return numerator / (a.x() * x + a.y() * y + a.z()); }
};

/// Columns [first, last] of row y whose pixel centres lie inside a convex
/// image polygon (edges included); first > last when none.
std::pair<int, int> rowSpan(const std::vector<Eigen::Vector2d>& polygon, int y, int width) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const Eigen::Vector2d& a = polygon[i];
    const Eigen::Vector2d& b = polygon[(i + 1) % polygon.size()];
    if (a.y() == b.y() || (a.y() - y) * (b.y() - y) > 0.0) continue;  // horizontal, or not crossing row y
    const double x = a.x() + (y - a.y()) / (b.y() - a.y()) * (b.x() - a.x());
    lo = std::min(lo, x);
    hi = std::max(hi, x);
  }
  if (!(lo <= hi)) return {0, -1};
  return {std::max(0, static_cast<int>(std::ceil(lo))), std::min(width - 1, static_cast<int>(std::floor(hi)))};
}

/// Writes facet + 1 at the pixels whose centres the polygon covers, where it
/// is nearer than what `depth` holds. Exact pixel-centre coverage: counting
/// the pixels an outline touches would let a neighbour's edge hide a face
/// seen at a grazing angle (a pixel wide).
void drawPolygon(const std::vector<Eigen::Vector3d>& polygon, const Projection& P, const PlaneDepth& plane_depth,
                 int facet, cv::Mat& index, cv::Mat& depth) {
  std::vector<Eigen::Vector3d> clipped = polygon;
  for (const HalfSpace& h : frustum(P, index.cols, index.rows)) {
    if (clipped.size() < 3) return;
    clipped = clip(clipped, h);
  }
  if (clipped.size() < 3) return;
  std::vector<Eigen::Vector2d> pixels;
  double top = std::numeric_limits<double>::infinity(), bottom = -top;
  for (const Eigen::Vector3d& X : clipped) {
    pixels.push_back((P * X.homogeneous()).hnormalized());
    top = std::min(top, pixels.back().y());
    bottom = std::max(bottom, pixels.back().y());
  }
  const int y_end = std::min(index.rows - 1, static_cast<int>(std::floor(bottom)));
  for (int y = std::max(0, static_cast<int>(std::ceil(top))); y <= y_end; ++y) {
    const auto [first, last] = rowSpan(pixels, y, index.cols);
    auto* id = index.ptr<int>(y);
    auto* z = depth.ptr<double>(y);
    for (int x = first; x <= last; ++x) {
      const double w = plane_depth.at(x, y);
      if (w > 0.0 && w < z[x]) {
        z[x] = w;
        id[x] = facet + 1;
      }
    }
  }
}

// ---------------------------------------------------------------------------
// Matching

void validateInputs(const std::vector<View>& views, const std::vector<ReferencePlane>& reference, double max_angle_deg,
                    double max_distance) {
  if (!std::isfinite(max_angle_deg) || !(max_angle_deg > 0.0) || max_angle_deg > 90.0) {
    throw std::invalid_argument("evaluateModel: max_angle_deg must be in (0, 90], got " + num(max_angle_deg));
  }
  if (!std::isfinite(max_distance) || !(max_distance > 0.0)) {
    throw std::invalid_argument("evaluateModel: max_distance must be > 0, got " + num(max_distance));
  }
  for (const ReferencePlane& r : reference) {
    if (!r.visible.empty() && r.visible.size() != views.size()) {
      throw std::invalid_argument("evaluateModel: reference '" + r.name + "' has " + std::to_string(r.visible.size()) +
                                  " visibility masks for " + std::to_string(views.size()) + " views");
    }
    for (std::size_t v = 0; v < r.visible.size(); ++v) {
      if (r.visible[v].type() != CV_8U || r.visible[v].size() != views[v].image.size()) {
        throw std::invalid_argument("evaluateModel: reference '" + r.name + "' mask " + std::to_string(v) +
                                    " must be CV_8U of its view's size");
      }
    }
  }
}

double meanVertexDistance(const Facet& facet, const Plane& plane) {
  double sum = 0.0;
  int count = 0;
  for (const auto& polygon : facet.polygons) {
    for (const Eigen::Vector3d& X : polygon) {
      sum += std::abs(plane.distance(X));
      ++count;
    }
  }
  return count > 0 ? sum / count : kNaN;
}

/// Per facet: the reference's visible pixels (all views) where it is the facet seen.
std::vector<long> coveredPixels(const ReferencePlane& r, const std::vector<cv::Mat>& index, std::size_t facets) {
  std::vector<long> covered(facets, 0);
  for (std::size_t v = 0; v < r.visible.size(); ++v) {
    for (int y = 0; y < index[v].rows; ++y) {
      const auto* m = r.visible[v].ptr<std::uint8_t>(y);
      const auto* id = index[v].ptr<int>(y);
      for (int x = 0; x < index[v].cols; ++x) {
        if (m[x] != 0 && id[x] > 0) ++covered[static_cast<std::size_t>(id[x] - 1)];
      }
    }
  }
  return covered;
}

long visiblePixels(const ReferencePlane& r) {
  long n = 0;
  for (const cv::Mat& m : r.visible) n += cv::countNonZero(m);
  return n;
}

/// Per facet: the reference points it shows in some view and lies within max_distance of.
std::vector<long> coveredPoints(const ReferencePlane& r, const PlanarModel& model, const std::vector<View>& views,
                                const std::vector<cv::Mat>& index, double max_distance) {
  std::vector<long> covered(model.facets.size(), 0);
  std::vector<int> seen_by;
  for (const Eigen::Vector3d& X : r.points) {
    seen_by.clear();
    for (std::size_t v = 0; v < views.size(); ++v) {
      Eigen::Vector2d px;
      if (!project(views[v].P, X, &px)) continue;
      const int x = static_cast<int>(std::lround(px.x())), y = static_cast<int>(std::lround(px.y()));
      if (x < 0 || y < 0 || x >= index[v].cols || y >= index[v].rows) continue;
      const int id = index[v].at<int>(y, x) - 1;
      if (id >= 0 && std::find(seen_by.begin(), seen_by.end(), id) == seen_by.end()) seen_by.push_back(id);
    }
    for (int f : seen_by) {
      if (std::abs(model.facets[static_cast<std::size_t>(f)].plane.distance(X)) <= max_distance) {
        ++covered[static_cast<std::size_t>(f)];
      }
    }
  }
  return covered;
}

struct Candidate {
  int reference = -1, facet = -1;
  double overlap = 0.0;  ///< share of the reference's pixels (or points) the facet covers
  double angle_deg = 0.0;
};

/// Facets near each reference plane in angle and distance, with their overlap.
std::vector<Candidate> candidates(const PlanarModel& model, const std::vector<View>& views,
                                  const std::vector<ReferencePlane>& reference, const std::vector<cv::Mat>& index,
                                  double max_angle_deg, double max_distance) {
  std::vector<Candidate> out;
  for (std::size_t r = 0; r < reference.size(); ++r) {
    const ReferencePlane& ref = reference[r];
    const bool masks = !ref.visible.empty();
    const std::vector<long> covered =
        masks ? coveredPixels(ref, index, model.facets.size()) : coveredPoints(ref, model, views, index, max_distance);
    const double total = masks ? static_cast<double>(visiblePixels(ref)) : static_cast<double>(ref.points.size());
    for (std::size_t f = 0; f < model.facets.size(); ++f) {
      const Facet& facet = model.facets[f];
      const double angle = facet.plane.angleTo(ref.plane);
      if (covered[f] == 0 || !(angle <= max_angle_deg) || !(meanVertexDistance(facet, ref.plane) <= max_distance)) {
        continue;
      }
      out.push_back({static_cast<int>(r), static_cast<int>(f), covered[f] / total, angle});
    }
  }
  return out;
}

/// Greedy one-to-one assignment, largest overlap first (smaller angle, then
/// lower indices on ties).
std::vector<PlaneMatch> assign(std::vector<Candidate> cands, std::size_t references, std::size_t facets) {
  std::stable_sort(cands.begin(), cands.end(), [](const Candidate& a, const Candidate& b) {
    return a.overlap != b.overlap ? a.overlap > b.overlap : a.angle_deg < b.angle_deg;
  });
  std::vector<PlaneMatch> matches(references);
  for (std::size_t r = 0; r < references; ++r) {
    matches[r].reference = static_cast<int>(r);
    matches[r].angle_deg = kNaN;
  }
  std::vector<bool> used(facets, false);
  for (const Candidate& c : cands) {
    PlaneMatch& m = matches[static_cast<std::size_t>(c.reference)];
    if (m.facet >= 0 || used[static_cast<std::size_t>(c.facet)]) continue;
    m.facet = c.facet;
    m.angle_deg = c.angle_deg;
    used[static_cast<std::size_t>(c.facet)] = true;
  }
  return matches;
}

// ---------------------------------------------------------------------------
// Scores

/// Fills each match's coverage and the overall coverage.
void scoreCoverage(const std::vector<ReferencePlane>& reference, const std::vector<cv::Mat>& index, std::size_t facets,
                   Evaluation& e) {
  long covered_all = 0, visible_all = 0;
  for (PlaneMatch& m : e.matches) {
    const ReferencePlane& ref = reference[static_cast<std::size_t>(m.reference)];
    if (ref.visible.empty()) {
      m.coverage = kNaN;
      continue;
    }
    const long visible = visiblePixels(ref);
    const long covered = m.facet < 0 ? 0 : coveredPixels(ref, index, facets)[static_cast<std::size_t>(m.facet)];
    m.coverage = visible > 0 ? static_cast<double>(covered) / visible : kNaN;
    covered_all += covered;
    visible_all += visible;
  }
  e.coverage = visible_all > 0 ? static_cast<double>(covered_all) / visible_all : kNaN;
}

void scorePairs(const PlanarModel& model, const std::vector<ReferencePlane>& reference, Evaluation& e) {
  double sum = 0.0, max = 0.0;
  for (std::size_t a = 0; a < e.matches.size(); ++a) {
    for (std::size_t b = a + 1; b < e.matches.size(); ++b) {
      if (e.matches[a].facet < 0 || e.matches[b].facet < 0) continue;
      PairAngleError p;
      p.reference_a = static_cast<int>(a);
      p.reference_b = static_cast<int>(b);
      p.true_angle_deg = reference[a].plane.angleTo(reference[b].plane);
      if (p.true_angle_deg <= kMinPairAngleDeg) continue;
      const Plane& fa = model.facets[static_cast<std::size_t>(e.matches[a].facet)].plane;
      p.model_angle_deg = fa.angleTo(model.facets[static_cast<std::size_t>(e.matches[b].facet)].plane);
      p.error_deg = std::abs(p.model_angle_deg - p.true_angle_deg);
      sum += p.error_deg;
      max = std::max(max, p.error_deg);
      e.pair_errors.push_back(p);
    }
  }
  e.mean_pair_error_deg = e.pair_errors.empty() ? kNaN : sum / e.pair_errors.size();
  e.max_pair_error_deg = e.pair_errors.empty() ? kNaN : max;
}

void scoreVertices(const PlanarModel& model, const std::vector<ReferencePlane>& reference, Evaluation& e) {
  double sum = 0.0, max = 0.0;
  long count = 0;
  for (const PlaneMatch& m : e.matches) {
    if (m.facet < 0) continue;
    ++e.reconstructed;
    const Plane& plane = reference[static_cast<std::size_t>(m.reference)].plane;
    for (const auto& polygon : model.facets[static_cast<std::size_t>(m.facet)].polygons) {
      for (const Eigen::Vector3d& X : polygon) {
        const double d = std::abs(plane.distance(X));
        sum += d;
        max = std::max(max, d);
        ++count;
      }
    }
  }
  e.vertex_distance_mean = count > 0 ? sum / count : kNaN;
  e.vertex_distance_max = count > 0 ? max : kNaN;
}

// ---------------------------------------------------------------------------
// VGG files and RANSAC planes

/// Rows of exactly `columns` numbers; blank lines skipped.
std::vector<std::vector<double>> readRows(const std::string& path, int columns) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("VGG reference: cannot read " + path);
  std::vector<std::vector<double>> rows;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    std::istringstream s(line);
    std::vector<double> row;
    for (double v; s >> v;) row.push_back(v);
    if (!s.eof()) throw std::runtime_error(path + " line " + std::to_string(number) + ": not a number");
    if (row.empty()) continue;
    const bool finite = std::all_of(row.begin(), row.end(), [](double v) { return std::isfinite(v); });
    if (static_cast<int>(row.size()) != columns || !finite) {
      throw std::runtime_error(path + " line " + std::to_string(number) + ": expected " + std::to_string(columns) +
                               " finite numbers, got " + std::to_string(row.size()));
    }
    rows.push_back(std::move(row));
  }
  if (rows.empty()) throw std::runtime_error("VGG reference: " + path + " holds no rows");
  return rows;
}

std::vector<int> inliersOf(const Plane& plane, const std::vector<Eigen::Vector3d>& points,
                           const std::vector<int>& candidates, double tolerance) {
  std::vector<int> in;
  for (int i : candidates) {
    if (std::abs(plane.distance(points[static_cast<std::size_t>(i)])) <= tolerance) in.push_back(i);
  }
  return in;
}

/// The plane through three random points with the most inliers among `remaining`.
std::vector<int> ransacInliers(const std::vector<Eigen::Vector3d>& points, const std::vector<int>& remaining,
                               double tolerance, std::mt19937& rng) {
  std::vector<int> best;
  const std::size_t n = remaining.size();
  for (int s = 0; s < kRansacSamples; ++s) {
    const int a = remaining[rng() % n], b = remaining[rng() % n], c = remaining[rng() % n];
    Plane plane;
    if (a == b || b == c || a == c || !Plane::through(points[a], points[b], points[c], &plane)) continue;
    std::vector<int> in = inliersOf(plane, points, remaining, tolerance);
    if (in.size() > best.size()) best = std::move(in);
  }
  return best;
}

/// Least-squares refit on the inliers, then the inliers of the refitted plane (twice).
Plane refine(const std::vector<Eigen::Vector3d>& points, const std::vector<int>& remaining, double tolerance,
             std::vector<int>& inliers) {
  Plane plane;
  for (int round = 0; round < 2; ++round) {
    std::vector<Eigen::Vector3d> xs;
    for (int i : inliers) xs.push_back(points[static_cast<std::size_t>(i)]);
    if (!Plane::fit(xs, &plane)) break;
    inliers = inliersOf(plane, points, remaining, tolerance);
  }
  return plane;
}

}  // namespace

cv::Mat facetIndexImage(const PlanarModel& model, const View& view) {
  if (view.image.empty()) throw std::invalid_argument("facetIndexImage: view '" + view.name + "' has no image");
  const Projection P = normalisedProjection(view.P);
  cv::Mat index = cv::Mat::zeros(view.image.size(), CV_32S);
  cv::Mat depth(view.image.size(), CV_64F, cv::Scalar(std::numeric_limits<double>::infinity()));
  for (std::size_t f = 0; f < model.facets.size(); ++f) {
    const PlaneDepth plane_depth(P, model.facets[f].plane);
    for (const auto& polygon : model.facets[f].polygons) {
      drawPolygon(polygon, P, plane_depth, static_cast<int>(f), index, depth);
    }
  }
  return index;
}

Evaluation evaluateModel(const PlanarModel& model, const std::vector<View>& views,
                         const std::vector<ReferencePlane>& reference, double max_angle_deg, double max_distance) {
  validateInputs(views, reference, max_angle_deg, max_distance);
  std::vector<cv::Mat> index;
  for (const View& v : views) index.push_back(facetIndexImage(model, v));
  Evaluation e;
  e.matches = assign(candidates(model, views, reference, index, max_angle_deg, max_distance), reference.size(),
                     model.facets.size());
  scoreCoverage(reference, index, model.facets.size(), e);
  scorePairs(model, reference, e);
  scoreVertices(model, reference, e);
  return e;
}

std::vector<ReferencePlane> vggReferencePlanes(const std::string& folder, double tolerance, int min_points) {
  if (!std::isfinite(tolerance) || !(tolerance > 0.0)) {
    throw std::invalid_argument("vggReferencePlanes: tolerance must be > 0, got " + num(tolerance));
  }
  if (min_points < 3) {
    throw std::invalid_argument("vggReferencePlanes: min_points must be >= 3, got " + std::to_string(min_points));
  }
  const std::vector<Eigen::Vector3d> points = loadVggPoints(folder);
  std::vector<int> remaining(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) remaining[i] = static_cast<int>(i);
  std::mt19937 rng(kRansacSeed);
  std::vector<ReferencePlane> planes;
  while (static_cast<int>(remaining.size()) >= min_points) {
    std::vector<int> inliers = ransacInliers(points, remaining, tolerance, rng);
    const Plane plane = refine(points, remaining, tolerance, inliers);
    if (static_cast<int>(inliers.size()) < min_points) break;
    ReferencePlane ref;
    ref.plane = plane;
    for (int i : inliers) ref.points.push_back(points[static_cast<std::size_t>(i)]);
    planes.push_back(std::move(ref));
    std::vector<int> rest;
    std::set_difference(remaining.begin(), remaining.end(), inliers.begin(), inliers.end(), std::back_inserter(rest));
    remaining = std::move(rest);
  }
  // A refit may leave a later plane larger than an earlier one.
  std::stable_sort(planes.begin(), planes.end(),
                   [](const ReferencePlane& a, const ReferencePlane& b) { return a.points.size() > b.points.size(); });
  for (std::size_t i = 0; i < planes.size(); ++i) planes[i].name = "plane " + std::to_string(i + 1);
  return planes;
}

std::vector<Eigen::Vector3d> loadVggPoints(const std::string& folder) {
  std::vector<Eigen::Vector3d> points;
  for (const auto& row : readRows(folder + "/3D/p3d", 3)) points.emplace_back(row[0], row[1], row[2]);
  return points;
}

std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> loadVggLines(const std::string& folder) {
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> lines;
  for (const auto& row : readRows(folder + "/3D/l3d", 6)) {
    lines.emplace_back(Eigen::Vector3d(row[0], row[1], row[2]), Eigen::Vector3d(row[3], row[4], row[5]));
  }
  return lines;
}

}  // namespace massage_cell::planar
