// Half-plane identification: the strip score shared by the thesis's
// feature-point search and Baillard's sweep (see half_plane.h).
#include "massage_cell/planar/half_plane.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/Dense>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

namespace massage_cell::planar {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kEndInset = 3.0;  // px left out at both ends of the segment (the corners belong to other edges)

void check(bool ok, const std::string& field, double value, const std::string& want) {
  if (!ok) throw std::invalid_argument("HalfPlaneParams." + field + " = " + std::to_string(value) + ": " + want);
}

/// Perpendicular basis (u, v) of a unit direction, the same for every call.
void basisAbout(const Eigen::Vector3d& d, Eigen::Vector3d* u, Eigen::Vector3d* v) {
  *u = d.unitOrthogonal();
  *v = d.cross(*u);
}

/// Angle difference modulo pi, in [0, pi/2].
double angleGap(double a, double b) {
  double g = std::fmod(std::abs(a - b), kPi);
  return std::min(g, kPi - g);
}

/// A grid over the convex hull of `points` (every `step` px, coarser so that
/// at most ~kRegionSamples samples fall inside); returns the hull's vertices.
std::vector<Eigen::Vector2d> regionGrid(const std::vector<Eigen::Vector2d>& points, double step,
                                        std::vector<Eigen::Vector2d>* pixels) {
  constexpr double kRegionSamples = 2000.0;
  std::vector<cv::Point2f> in, hull;
  for (const auto& p : points) in.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  cv::convexHull(in, hull);
  std::vector<Eigen::Vector2d> vertices;
  for (const auto& p : hull) vertices.emplace_back(p.x, p.y);
  if (hull.size() < 3) return vertices;
  const cv::Rect box = cv::boundingRect(hull);
  const double grid = std::max(step, std::sqrt(std::abs(cv::contourArea(hull)) / kRegionSamples));
  for (double y = box.y; y <= box.y + box.height; y += grid) {
    for (double x = box.x; x <= box.x + box.width; x += grid) {
      if (cv::pointPolygonTest(hull, cv::Point2f(static_cast<float>(x), static_cast<float>(y)), false) >= 0) {
        pixels->emplace_back(x, y);
      }
    }
  }
  return vertices;
}

}  // namespace

void HalfPlaneParams::validate() const {
  check(std::isfinite(strip_width) && strip_width >= 4.0 && strip_width <= 200.0, "strip_width", strip_width,
        "expected 4 .. 200 px");
  check(std::isfinite(strip_offset) && strip_offset >= 0.0 && strip_offset <= 20.0, "strip_offset", strip_offset,
        "expected 0 .. 20 px");
  check(std::isfinite(sample_step) && sample_step >= 0.5 && sample_step <= strip_width / 2, "sample_step", sample_step,
        "expected 0.5 px .. strip_width / 2");
  check(std::isfinite(min_ncc) && min_ncc > -1.0 && min_ncc < 1.0, "min_ncc", min_ncc, "expected -1 < min_ncc < 1");
  check(std::isfinite(region_depth) && region_depth > strip_offset, "region_depth", region_depth,
        "expected more than strip_offset");
  check(std::isfinite(coplanar_pixels) && coplanar_pixels > 0.0 && coplanar_pixels <= 50.0, "coplanar_pixels",
        coplanar_pixels, "expected 0 < px <= 50");
  check(min_coplanar_points >= 1 && min_coplanar_points <= 1000, "min_coplanar_points", min_coplanar_points,
        "expected 1 .. 1000");
  check(std::isfinite(sweep_step_deg) && sweep_step_deg >= 0.05 && sweep_step_deg <= 30.0, "sweep_step_deg",
        sweep_step_deg, "expected 0.05 .. 30 degrees");
  check(std::isfinite(grazing_deg) && grazing_deg >= 0.0 && grazing_deg < 80.0, "grazing_deg", grazing_deg,
        "expected 0 .. 80 degrees");
}

Plane planeAboutLine(const Eigen::Vector3d& point, const Eigen::Vector3d& direction, double angle) {
  Eigen::Vector3d u, v;
  basisAbout(direction, &u, &v);
  Plane plane;
  plane.n = (std::cos(angle) * v - std::sin(angle) * u).normalized();  // direction x (cos u + sin v)
  plane.d = -plane.n.dot(point);
  return plane;
}

double angleAboutLine(const Eigen::Vector3d& point, const Eigen::Vector3d& direction, const Eigen::Vector3d& X) {
  Eigen::Vector3d u, v;
  basisAbout(direction, &u, &v);
  const Eigen::Vector3d r = X - point;
  double a = std::atan2(r.dot(v), r.dot(u));
  if (a < 0.0) a += kPi;
  return a >= kPi ? a - kPi : a;
}

// ---------------------------------------------------------------------------

struct HalfPlaneSearch::Strip {
  PhotoConsistency::Samples samples;
  bool valid() const { return samples.textured; }
};

HalfPlaneSearch::HalfPlaneSearch(const std::vector<View>& views, const std::vector<PointTrack>& points,
                                 const std::vector<LineTrack>& lines, const HalfPlaneParams& params)
    : views_(views),
      points_(points),
      lines_(lines),
      params_(params),
      coplanarity_(views, (params.validate(), params.coplanar_pixels)),
      photo_((validateViews(views), views)) {}

int HalfPlaneSearch::referenceView(int line) const {
  const LineTrack& L = lines_.at(static_cast<std::size_t>(line));
  int best = -1;
  double best_length = -1.0;
  for (const Observation& o : L.observations) {
    Eigen::Vector2d pa, pb;
    if (!project(views_[o.first].P, L.a, &pa) || !project(views_[o.first].P, L.b, &pb)) continue;
    if ((pb - pa).norm() > best_length) {
      best_length = (pb - pa).norm();
      best = o.first;
    }
  }
  return best;
}

HalfPlaneSearch::Strip HalfPlaneSearch::makeStrip(int line, int side, int reference_view,
                                                  const std::vector<Eigen::Vector2d>& region) const {
  Strip strip;
  const LineTrack& L = lines_.at(static_cast<std::size_t>(line));
  const Projection& P = views_[static_cast<std::size_t>(reference_view)].P;
  Eigen::Vector2d pa, pb;
  if (!project(P, L.a, &pa) || !project(P, L.b, &pb)) return strip;
  const double length = (pb - pa).norm();
  if (length < 2.0 * kEndInset + params_.sample_step) return strip;
  const Eigen::Vector2d along = (pb - pa) / length;
  // imageLine's (a, b) is the unit normal along which its equation grows: `side` picks the sign.
  const Eigen::Vector2d across = side * imageLine(pa, pb).head<2>();
  const double o0 = params_.strip_offset, o1 = params_.strip_offset + params_.strip_width;
  std::vector<Eigen::Vector2d> corners = {pa + kEndInset * along + o0 * across, pb - kEndInset * along + o0 * across,
                                          pa + kEndInset * along + o1 * across, pb - kEndInset * along + o1 * across};
  std::vector<Eigen::Vector2d> pixels;
  if (region.empty()) {
    for (double t = kEndInset; t <= length - kEndInset; t += params_.sample_step) {
      for (double o = o0; o <= o1; o += params_.sample_step) pixels.push_back(pa + t * along + o * across);
    }
  } else {
    corners.insert(corners.end(), region.begin(), region.end());
    corners = regionGrid(corners, params_.sample_step, &pixels);
  }
  strip.samples = photo_.sample(reference_view, pixels, corners);
  return strip;
}

double HalfPlaneSearch::scoreStrip(const Strip& strip, const Plane& plane) const {
  return photo_.score(strip.samples, plane);
}

double HalfPlaneSearch::score(int line, int side, int reference_view, const Plane& plane) const {
  return scoreStrip(makeStrip(line, side, reference_view), plane);
}

bool HalfPlaneSearch::grazing(int line, int reference_view, const Plane& plane) const {
  const LineTrack& L = lines_.at(static_cast<std::size_t>(line));
  const Eigen::Vector3d ray =
      (0.5 * (L.a + L.b) - cameraCentre(views_[static_cast<std::size_t>(reference_view)].P)).normalized();
  return std::abs(plane.n.dot(ray)) < std::sin(params_.grazing_deg * kPi / 180.0);
}

std::vector<HalfPlaneSearch::RegionPoint> HalfPlaneSearch::regionPoints(int line, int side, int reference_view) const {
  const LineTrack& L = lines_.at(static_cast<std::size_t>(line));
  const Projection& P = views_[static_cast<std::size_t>(reference_view)].P;
  Eigen::Vector2d pa, pb;
  std::vector<RegionPoint> region;
  if (!project(P, L.a, &pa) || !project(P, L.b, &pb)) return region;
  const Eigen::Vector3d l = imageLine(pa, pb);
  const Eigen::Vector3d d = L.direction();
  const double length2 = (pb - pa).squaredNorm();
  // Region constraint: reference pixels on this side, near the line, alongside the segment.
  for (std::size_t k = 0; k < points_.size(); ++k) {
    Eigen::Vector2d q;
    if (!project(P, points_[k].X, &q)) continue;
    const double across = side * l.dot(q.homogeneous());
    const double t = (q - pa).dot(pb - pa) / length2;
    if (across <= params_.strip_offset || across > params_.region_depth || t < -0.1 || t > 1.1) continue;
    const Eigen::Vector3d r = points_[k].X - L.a;
    const Eigen::Vector3d off = r - r.dot(d) * d;
    const double radius = off.norm();
    if (radius <= 0.0) continue;
    const Eigen::Vector3d normal = d.cross(off / radius);  // of the plane through L and the point
    region.push_back({static_cast<int>(k), angleAboutLine(L.a, d, points_[k].X), radius,
                      coplanarity_.tolerance(points_[k].X, normal, reference_view), q});
  }
  return region;
}

std::vector<Plane> HalfPlaneSearch::pointCandidates(int line, int side, int reference_view,
                                                    std::vector<std::vector<int>>* groups) const {
  const LineTrack& L = lines_.at(static_cast<std::size_t>(line));
  const Eigen::Vector3d d = L.direction();
  std::vector<Plane> planes;
  const std::vector<RegionPoint> region = regionPoints(line, side, reference_view);
  // Coplanar constraint: the points at one angle about L (within each one's
  // tolerance at its distance from L) make one candidate, largest group first.
  std::vector<bool> used(region.size(), false);
  while (true) {
    std::vector<int> best;
    for (std::size_t s = 0; s < region.size(); ++s) {
      if (used[s]) continue;
      std::vector<int> group;
      for (std::size_t k = 0; k < region.size(); ++k) {
        if (!used[k] && angleGap(region[k].angle, region[s].angle) * region[k].radius <= region[k].tolerance)
          group.push_back(static_cast<int>(k));
      }
      if (group.size() > best.size()) best = group;
    }
    if (static_cast<int>(best.size()) < std::max(1, params_.min_coplanar_points)) break;
    // The plane about L nearest the group: theta minimising sum r^2 sin^2(theta - theta_k).
    double c2 = 0.0, s2 = 0.0;
    std::vector<int> members;
    for (int k : best) {
      used[static_cast<std::size_t>(k)] = true;
      const double w = region[k].radius * region[k].radius;
      c2 += w * std::cos(2.0 * region[k].angle);
      s2 += w * std::sin(2.0 * region[k].angle);
      members.push_back(region[k].index);
    }
    const Plane plane = planeAboutLine(L.a, d, 0.5 * std::atan2(s2, c2));
    if (grazing(line, reference_view, plane)) continue;
    planes.push_back(plane);
    if (groups) groups->push_back(members);
  }
  return planes;
}

namespace {

/// Runs `search_side(line, side, &half_plane, &candidates)` over every line
/// and both sides on all cores; keeps the accepted half-planes in line order.
template <typename SideSearch>
std::vector<HalfPlane> searchAll(int line_count, const SideSearch& search_side, SearchStats* stats) {
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<HalfPlane> found(static_cast<std::size_t>(2 * line_count));
  std::vector<long> counts(found.size(), 0);
  cv::parallel_for_(cv::Range(0, 2 * line_count), [&](const cv::Range& range) {
    for (int i = range.start; i < range.end; ++i) {
      search_side(i / 2, i % 2 == 0 ? 1 : -1, &found[static_cast<std::size_t>(i)],
                  &counts[static_cast<std::size_t>(i)]);
    }
  });
  std::vector<HalfPlane> accepted;
  for (const HalfPlane& h : found) {
    if (h.line >= 0) accepted.push_back(h);
  }
  if (stats) {
    stats->candidates = 0;
    for (long c : counts) stats->candidates += c;
    stats->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  return accepted;
}

}  // namespace

std::vector<HalfPlane> HalfPlaneSearch::byFeaturePoints(SearchStats* stats) const {
  auto side_search = [this](int line, int side, HalfPlane* out, long* count) {
    const int ref = referenceView(line);
    if (ref < 0) return;
    const Strip strip = makeStrip(line, side, ref);
    if (!strip.valid()) return;
    std::vector<std::vector<int>> groups;
    const std::vector<Plane> candidates = pointCandidates(line, side, ref, &groups);
    for (std::size_t c = 0; c < candidates.size(); ++c) {
      // Verified over the strip and the region its coplanar points span.
      std::vector<Eigen::Vector2d> spanned;
      for (int k : groups[c]) {
        Eigen::Vector2d q;
        if (project(views_[static_cast<std::size_t>(ref)].P, points_[static_cast<std::size_t>(k)].X, &q)) {
          spanned.push_back(q);
        }
      }
      const double s = scoreStrip(makeStrip(line, side, ref, spanned), candidates[c]);
      ++*count;
      if (s >= params_.min_ncc && s > out->score) *out = HalfPlane{line, side, ref, candidates[c], s, groups[c]};
    }
  };
  return searchAll(static_cast<int>(lines_.size()), side_search, stats);
}

std::vector<HalfPlane> HalfPlaneSearch::bySweep(SearchStats* stats) const {
  auto side_search = [this](int line, int side, HalfPlane* out, long* count) {
    const int ref = referenceView(line);
    if (ref < 0) return;
    const Strip strip = makeStrip(line, side, ref);
    if (!strip.valid()) return;
    const LineTrack& L = lines_[static_cast<std::size_t>(line)];
    const double step = params_.sweep_step_deg * kPi / 180.0;
    const int n = static_cast<int>(std::ceil(kPi / step));
    const std::vector<RegionPoint> region = regionPoints(line, side, ref);
    std::vector<double> scores(static_cast<std::size_t>(n), -1.0);
    for (int k = 0; k < n; ++k) {
      const Plane plane = planeAboutLine(L.a, L.direction(), k * step);
      if (grazing(line, ref, plane)) continue;
      // The same verification as the feature-point search: the strip and the region the plane's points span.
      std::vector<Eigen::Vector2d> spanned;
      for (const RegionPoint& p : region) {
        if (angleGap(p.angle, k * step) * p.radius <= p.tolerance) spanned.push_back(p.pixel);
      }
      scores[static_cast<std::size_t>(k)] =
          spanned.size() < 2 ? scoreStrip(strip, plane) : scoreStrip(makeStrip(line, side, ref, spanned), plane);
      ++*count;
    }
    const int best = static_cast<int>(std::max_element(scores.begin(), scores.end()) - scores.begin());
    if (scores[static_cast<std::size_t>(best)] < params_.min_ncc) return;
    // Sub-step angle: the parabola through the best score and its neighbours.
    const double sm = scores[static_cast<std::size_t>((best + n - 1) % n)];
    const double sp = scores[static_cast<std::size_t>((best + 1) % n)];
    const double s0 = scores[static_cast<std::size_t>(best)];
    const double denom = sm - 2.0 * s0 + sp;
    const double offset =
        (sm > -1.0 && sp > -1.0 && denom < 0.0) ? std::clamp(0.5 * (sm - sp) / denom, -0.5, 0.5) : 0.0;
    *out = HalfPlane{line, side, ref, planeAboutLine(L.a, L.direction(), (best + offset) * step), s0, {}};
  };
  return searchAll(static_cast<int>(lines_.size()), side_search, stats);
}

}  // namespace massage_cell::planar
