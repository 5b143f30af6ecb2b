// Half-plane extension, bounding by fixed lines and merging (see extend.h).
#include "massage_cell/planar/extend.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

#include <opencv2/imgproc.hpp>

#include "massage_cell/planar/coplanarity.h"
#include "massage_cell/planar/photo_consistency.h"

namespace massage_cell::planar {

namespace {

void check(bool ok, const std::string& field, double value, const std::string& want) {
  if (!ok) throw std::invalid_argument("ExtendParams." + field + " = " + std::to_string(value) + ": " + want);
}

/// 2D coordinates on a plane: origin and axes e1, e2 with e1 x e2 = n, so a
/// counter-clockwise polygon in (e1, e2) is counter-clockwise seen from n.
struct PlaneFrame {
  Eigen::Vector3d origin, e1, e2;
  PlaneFrame(const Plane& plane, const Eigen::Vector3d& near, const Eigen::Vector3d& along) {
    origin = near - plane.distance(near) * plane.n;
    e1 = (along - along.dot(plane.n) * plane.n).normalized();
    e2 = plane.n.cross(e1);
  }
  Eigen::Vector2d to2d(const Eigen::Vector3d& X) const { return {(X - origin).dot(e1), (X - origin).dot(e2)}; }
  Eigen::Vector3d to3d(const Eigen::Vector2d& p) const { return origin + p.x() * e1 + p.y() * e2; }
};

/// A 2D half-space a . p + b >= 0.
struct Bound {
  Eigen::Vector2d a;
  double b;
  double at(const Eigen::Vector2d& p) const { return a.dot(p) + b; }
};

using Polygon2 = std::vector<Eigen::Vector2d>;

Polygon2 clip(const Polygon2& poly, const Bound& bound) {
  Polygon2 out;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const Eigen::Vector2d& p = poly[i];
    const Eigen::Vector2d& q = poly[(i + 1) % poly.size()];
    const double fp = bound.at(p), fq = bound.at(q);
    if (fp >= 0.0) out.push_back(p);
    if ((fp >= 0.0) != (fq >= 0.0)) out.push_back(p + (q - p) * (fp / (fp - fq)));
  }
  return out;
}

/// Counter-clockwise convex hull (cv::convexHull on coordinates relative to
/// the first point, so float precision does not depend on the world units).
Polygon2 hull(const std::vector<Eigen::Vector2d>& pts) {
  if (pts.size() < 3) return {};
  const Eigen::Vector2d o = pts.front();
  double scale = 0.0;
  for (const auto& p : pts) scale = std::max(scale, (p - o).norm());
  if (scale <= 0.0) return {};
  std::vector<cv::Point2f> in;
  for (const auto& p : pts) in.emplace_back(float((p.x() - o.x()) / scale), float((p.y() - o.y()) / scale));
  std::vector<cv::Point2f> h;
  cv::convexHull(in, h, /*clockwise=*/false);
  Polygon2 out;
  for (const auto& p : h) out.emplace_back(o.x() + p.x * scale, o.y() + p.y * scale);
  // cv::convexHull's orientation follows a y-down image convention: make it CCW in (e1, e2).
  double area2 = 0.0;
  for (std::size_t i = 0; i < out.size(); ++i) {
    const auto& p = out[i];
    const auto& q = out[(i + 1) % out.size()];
    area2 += p.x() * q.y() - q.x() * p.y();
  }
  if (area2 < 0.0) std::reverse(out.begin(), out.end());
  return out;
}

double area(const Polygon2& poly) {
  double a = 0.0;
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const auto& p = poly[i];
    const auto& q = poly[(i + 1) % poly.size()];
    a += p.x() * q.y() - q.x() * p.y();
  }
  return 0.5 * std::abs(a);
}

/// Distance from p to a convex CCW polygon (0 inside).
double distanceTo(const Polygon2& poly, const Eigen::Vector2d& p) {
  bool in = poly.size() >= 3;
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < poly.size(); ++i) {
    const Eigen::Vector2d a = poly[i], b = poly[(i + 1) % poly.size()];
    const Eigen::Vector2d ab = b - a;
    const double cross = ab.x() * (p - a).y() - ab.y() * (p - a).x();
    if (cross < 0.0) in = false;
    const double t = ab.squaredNorm() > 0 ? std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
    best = std::min(best, (a + t * ab - p).norm());
  }
  return in ? 0.0 : best;
}

/// One half-plane while it is being extended.
struct Region {
  Plane plane;
  int reference_view = 0;
  double pixels_per_unit = 1.0;          ///< at the line's midpoint, reference view
  std::vector<Eigen::Vector3d> support;  ///< the line's end points, then joined points and segment ends
  int line_points = 2;
  double score = 0.0;
  Polygon2 polygon;  ///< in `frame`
  PlaneFrame frame;
};

/// The candidate evidence of a region's plane: feature points and segment
/// end points (segments count only when both ends are on the plane).
std::vector<Eigen::Vector3d> coplanarEvidence(const Region& h, const CoplanarityTest& on,
                                              const std::vector<PointTrack>& points,
                                              const std::vector<LineTrack>& lines, int own_line) {
  std::vector<Eigen::Vector3d> out;
  for (const PointTrack& p : points) {
    if (on.onPlane(p.X, h.plane, h.reference_view)) out.push_back(p.X);
  }
  for (std::size_t l = 0; l < lines.size(); ++l) {
    if (static_cast<int>(l) == own_line) continue;
    if (on.onPlane(lines[l].a, h.plane, h.reference_view) && on.onPlane(lines[l].b, h.plane, h.reference_view)) {
      out.push_back(lines[l].a);
      out.push_back(lines[l].b);
    }
  }
  return out;
}

/// The fixed lines of `h` with its neighbours, as half-spaces of h's frame
/// keeping the side where h's line and the half-plane's inside lie. A bound
/// that would cut h's own line is not one (it is h's line itself, or a far
/// plane crossing it).
std::vector<Bound> fixedLineBounds(const Region& h, const LineTrack& L, const std::vector<Region>& all,
                                   const std::vector<LineTrack>& lines, const std::vector<HalfPlane>& half_planes,
                                   const CoplanarityTest& on, const ExtendParams& params, std::size_t self) {
  std::vector<Bound> bounds;
  const Eigen::Vector2d a2 = h.frame.to2d(L.a), b2 = h.frame.to2d(L.b);
  const Eigen::Vector2d inside = 0.5 * (a2 + b2) + Eigen::Vector2d(0, 1) * (0.05 * (b2 - a2).norm());
  const double reach = params.neighbour_reach / h.pixels_per_unit;
  for (std::size_t g = 0; g < all.size(); ++g) {
    if (g == self) continue;
    const Plane& pg = all[g].plane;
    if (h.plane.angleTo(pg) < params.merge_angle_deg) continue;
    // A neighbour bounds h where the two planes meet: its line must lie on h's plane (an edge they share).
    const LineTrack& Lg = lines[static_cast<std::size_t>(half_planes[g].line)];
    if (!on.onPlane(Lg.a, h.plane, h.reference_view) || !on.onPlane(Lg.b, h.plane, h.reference_view)) continue;
    const double near = std::min({(Lg.a - L.a).norm(), (Lg.a - L.b).norm(), (Lg.b - L.a).norm(), (Lg.b - L.b).norm(),
                                  (0.5 * (Lg.a + Lg.b) - 0.5 * (L.a + L.b)).norm()});
    if (near > reach) continue;
    // pg restricted to h's plane: pg.n . (o + x e1 + y e2) + pg.d = 0.
    Bound bound{Eigen::Vector2d(pg.n.dot(h.frame.e1), pg.n.dot(h.frame.e2)), pg.distance(h.frame.origin)};
    const double norm = bound.a.norm();
    if (norm < 1e-9) continue;
    bound.a /= norm;
    bound.b /= norm;
    if (bound.at(inside) < 0.0) {
      bound.a = -bound.a;
      bound.b = -bound.b;
    }
    const double slack = 0.02 * (b2 - a2).norm();
    if (bound.at(a2) < -slack || bound.at(b2) < -slack) continue;  // crosses h's own line
    bounds.push_back(bound);
  }
  return bounds;
}

/// Grows h over the coplanar evidence inside its bounds, nearest first.
void grow(Region* h, const std::vector<Eigen::Vector3d>& evidence, const std::vector<Bound>& bounds,
          const ExtendParams& params) {
  std::vector<Eigen::Vector2d> candidates;
  for (const Eigen::Vector3d& X : evidence) {
    const Eigen::Vector2d p = h->frame.to2d(X);
    if (p.y() <= 0.0) continue;  // the other side of the line
    bool in = true;
    for (const Bound& b : bounds) in = in && b.at(p) >= 0.0;
    if (in) candidates.push_back(p);
  }
  std::vector<Eigen::Vector2d> region = {h->frame.to2d(h->support[0]), h->frame.to2d(h->support[1])};
  std::vector<bool> joined(candidates.size(), false);
  const double step = params.growth_step / h->pixels_per_unit;
  for (bool changed = true; changed;) {
    changed = false;
    const Polygon2 current = region.size() >= 3 ? hull(region) : Polygon2{};
    for (std::size_t i = 0; i < candidates.size(); ++i) {
      if (joined[i]) continue;
      double d = current.empty() ? std::numeric_limits<double>::infinity() : distanceTo(current, candidates[i]);
      for (std::size_t k = 0; current.empty() && k < region.size(); ++k)
        d = std::min(d, (region[k] - candidates[i]).norm());
      if (d > step) continue;
      joined[i] = true;
      region.push_back(candidates[i]);
      h->support.push_back(h->frame.to3d(candidates[i]));
      changed = true;
    }
  }
  Polygon2 poly = hull(region);
  for (const Bound& b : bounds) poly = clip(poly, b);
  h->polygon = poly;
}

/// Median of the points' distances to the region's plane, in its tolerances.
double medianDistance(const std::vector<Eigen::Vector3d>& points, const Region& region, const CoplanarityTest& on) {
  std::vector<double> d;
  for (const auto& X : points) d.push_back(on.normalisedDistance(X, region.plane, region.reference_view));
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  return d.empty() ? std::numeric_limits<double>::infinity() : d[d.size() / 2];
}

/// Smallest distance between two regions' polygons, in a's plane.
double polygonGap(const Region& a, const Region& b) {
  double gap = std::numeric_limits<double>::infinity();
  for (const auto& p : b.polygon) gap = std::min(gap, distanceTo(a.polygon, a.frame.to2d(b.frame.to3d(p))));
  for (const auto& p : a.polygon) gap = std::min(gap, distanceTo(b.polygon, b.frame.to2d(a.frame.to3d(p))));
  return gap;
}

/// Photo-consistency of the whole grown region: its polygon's pixels in the
/// reference view (a grid of at most ~kRegionSamples) carried into the other
/// views by its plane.
double regionScore(const Region& r, const View& view, const PhotoConsistency& photo) {
  constexpr double kRegionSamples = 3000.0;
  std::vector<cv::Point2f> polygon;
  std::vector<Eigen::Vector2d> corners;
  for (const auto& p : r.polygon) {
    Eigen::Vector2d q;
    if (!project(view.P, r.frame.to3d(p), &q)) return -1.0;
    polygon.emplace_back(static_cast<float>(q.x()), static_cast<float>(q.y()));
    corners.push_back(q);
  }
  const cv::Rect box = cv::boundingRect(polygon) & cv::Rect(0, 0, view.image.cols, view.image.rows);
  const double area = std::abs(cv::contourArea(polygon));
  const double step = std::max(1.0, std::sqrt(area / kRegionSamples));
  std::vector<Eigen::Vector2d> pixels;
  for (double y = box.y; y < box.y + box.height; y += step) {
    for (double x = box.x; x < box.x + box.width; x += step) {
      if (cv::pointPolygonTest(polygon, cv::Point2f(float(x), float(y)), false) > 0) pixels.emplace_back(x, y);
    }
  }
  return photo.score(photo.sample(r.reference_view, pixels, corners), r.plane);
}

/// The region's plane refitted to its support (least squares), its frame
/// turned with it (e2 still into the half-plane). False when the support is
/// degenerate (the plane stays).
bool refit(Region* r) {
  Plane fitted;
  if (r->support.size() < 4 || !Plane::fit(r->support, &fitted)) return false;
  if (fitted.n.dot(r->plane.n) < 0.0) {
    fitted.n = -fitted.n;
    fitted.d = -fitted.d;
  }
  PlaneFrame frame(fitted, r->frame.origin, r->frame.e1);
  if (frame.e2.dot(r->frame.e2) < 0.0) {
    frame.e1 = -frame.e1;
    frame.e2 = fitted.n.cross(frame.e1);
  }
  r->plane = fitted;
  r->frame = frame;
  return true;
}

/// Union-find over the regions: within merge_angle_deg, each one's evidence
/// (median) on the other's plane, and touching.
std::vector<int> mergeGroups(const std::vector<Region>& regions, const CoplanarityTest& on,
                             const ExtendParams& params) {
  std::vector<int> parent(regions.size());
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int i) {
    while (parent[static_cast<std::size_t>(i)] != i) {
      i = parent[static_cast<std::size_t>(i)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(i)])];
    }
    return i;
  };
  for (std::size_t i = 0; i < regions.size(); ++i) {
    for (std::size_t j = i + 1; j < regions.size(); ++j) {
      const Region& a = regions[i];
      const Region& b = regions[j];
      if (find(int(i)) == find(int(j)) || a.plane.angleTo(b.plane) > params.merge_angle_deg) continue;
      if (medianDistance(b.support, a, on) > 1.0 || medianDistance(a.support, b, on) > 1.0) continue;
      const double touch = params.growth_step / std::min(a.pixels_per_unit, b.pixels_per_unit);
      if (polygonGap(a, b) <= touch) parent[static_cast<std::size_t>(find(int(i)))] = find(int(j));
    }
  }
  std::vector<int> group(regions.size());
  for (std::size_t i = 0; i < regions.size(); ++i) group[i] = find(int(i));
  return group;
}

/// One facet from a group of regions: the plane refitted to all their
/// support, one convex polygon when the hull adds little to the parts, else
/// the parts projected onto the common plane.
Facet mergeFacet(const std::vector<const Region*>& parts) {
  std::vector<Eigen::Vector3d> support;
  double score = 0.0, part_area = 0.0;
  for (const Region* r : parts) {
    support.insert(support.end(), r->support.begin(), r->support.end());
    score = std::max(score, r->score);
    part_area += area(r->polygon);
  }
  Facet facet;
  facet.plane = parts.front()->plane;
  Plane fitted;
  if (Plane::fit(support, &fitted)) {
    if (fitted.n.dot(facet.plane.n) < 0.0) {
      fitted.n = -fitted.n;
      fitted.d = -fitted.d;
    }
    facet.plane = fitted;
  }
  facet.score = score;
  facet.support_points = static_cast<int>(support.size());
  const Region& first = *parts.front();
  const PlaneFrame frame(facet.plane, first.frame.origin, first.frame.e1);
  std::vector<Eigen::Vector2d> all;
  std::vector<Polygon2> projected;
  for (const Region* r : parts) {
    Polygon2 poly;
    for (const auto& p : r->polygon) poly.push_back(frame.to2d(r->frame.to3d(p)));
    all.insert(all.end(), poly.begin(), poly.end());
    projected.push_back(hull(poly));
  }
  const Polygon2 whole = hull(all);
  if (parts.size() == 1 || area(whole) <= 1.15 * part_area) projected = {whole};
  for (const Polygon2& poly : projected) {
    if (poly.size() < 3) continue;
    std::vector<Eigen::Vector3d> p3;
    for (const auto& p : poly) p3.push_back(frame.to3d(p));
    facet.polygons.push_back(p3);
  }
  return facet;
}

/// Mean colour of the facet's first polygon in the reference view.
cv::Vec3b facetColour(const Facet& facet, const View& view) {
  std::vector<cv::Point> pix;
  for (const Eigen::Vector3d& X : facet.polygons.front()) {
    Eigen::Vector2d q;
    if (!project(view.P, X, &q)) return facet.colour;
    pix.emplace_back(static_cast<int>(std::lround(q.x())), static_cast<int>(std::lround(q.y())));
  }
  cv::Mat mask = cv::Mat::zeros(view.image.size(), CV_8U);
  cv::fillConvexPoly(mask, pix, cv::Scalar(255));
  if (cv::countNonZero(mask) == 0) return facet.colour;
  const cv::Scalar m = cv::mean(view.image, mask);
  return view.image.channels() == 3
             ? cv::Vec3b(cv::saturate_cast<uchar>(m[0]), cv::saturate_cast<uchar>(m[1]), cv::saturate_cast<uchar>(m[2]))
             : cv::Vec3b::all(cv::saturate_cast<uchar>(m[0]));
}

Region startRegion(const View& view, const LineTrack& L, const HalfPlane& h) {
  const Eigen::Vector3d mid = 0.5 * (L.a + L.b);
  PlaneFrame frame(h.plane, L.a, L.direction());
  // e2 must point into the half-plane: the side of the line its strip lies on in the reference view.
  Eigen::Vector2d pa, pb;
  project(view.P, L.a, &pa);
  project(view.P, L.b, &pb);
  const Eigen::Vector3d probe = mid + frame.e2 * (0.05 * (L.b - L.a).norm());
  Eigen::Vector2d q;
  if (project(view.P, probe, &q) && h.side * imageLine(pa, pb).dot(q.homogeneous()) < 0.0) {
    frame.e1 = -frame.e1;
    frame.e2 = h.plane.n.cross(frame.e1);
  }
  Region r{h.plane, h.reference_view, pixelsPerUnit(view.P, mid), {L.a, L.b}, 2, h.score, {}, frame};
  return r;
}

}  // namespace

void ExtendParams::validate() const {
  check(std::isfinite(coplanar_pixels) && coplanar_pixels > 0.0 && coplanar_pixels <= 50.0, "coplanar_pixels",
        coplanar_pixels, "expected 0 < px <= 50");
  check(std::isfinite(growth_step) && growth_step > 0.0, "growth_step", growth_step, "expected > 0 px");
  check(std::isfinite(neighbour_reach) && neighbour_reach >= 0.0, "neighbour_reach", neighbour_reach,
        "expected >= 0 px");
  check(std::isfinite(merge_angle_deg) && merge_angle_deg > 0.0 && merge_angle_deg < 45.0, "merge_angle_deg",
        merge_angle_deg, "expected 0 .. 45 degrees");
  check(min_support >= 0 && min_support <= 10000, "min_support", min_support, "expected 0 .. 10000");
  check(std::isfinite(min_region_ncc) && min_region_ncc > -1.0 && min_region_ncc < 1.0, "min_region_ncc",
        min_region_ncc, "expected -1 < min_region_ncc < 1");
}

PlanarModel extendAndMerge(const std::vector<View>& views, const std::vector<PointTrack>& points,
                           const std::vector<LineTrack>& lines, const std::vector<HalfPlane>& half_planes,
                           const ExtendParams& params, ExtendStats* stats) {
  params.validate();
  const auto t0 = std::chrono::steady_clock::now();
  const CoplanarityTest on(views, params.coplanar_pixels);
  const PhotoConsistency photo(views);
  std::vector<Region> regions;
  for (const HalfPlane& h : half_planes) {
    if (h.line < 0 || h.line >= static_cast<int>(lines.size()) || h.reference_view < 0 ||
        h.reference_view >= static_cast<int>(views.size()))
      throw std::invalid_argument("extendAndMerge: half-plane refers to line " + std::to_string(h.line) + " / view " +
                                  std::to_string(h.reference_view) + ", which do not exist");
    regions.push_back(
        startRegion(views[static_cast<std::size_t>(h.reference_view)], lines[static_cast<std::size_t>(h.line)], h));
  }
  std::vector<Region> extended;
  for (std::size_t i = 0; i < regions.size(); ++i) {
    const LineTrack& L = lines[static_cast<std::size_t>(half_planes[i].line)];
    Region r = regions[i];
    // Grow, refit the plane to what it grew over, grow again from the line on the refitted plane.
    for (int pass = 0; pass < 2; ++pass) {
      r.support = {L.a, L.b};
      const auto bounds = fixedLineBounds(r, L, regions, lines, half_planes, on, params, i);
      grow(&r, coplanarEvidence(r, on, points, lines, half_planes[i].line), bounds, params);
      if (pass == 0 && !refit(&r)) break;
    }
    if (static_cast<int>(r.support.size()) - r.line_points < params.min_support || r.polygon.size() < 3) continue;
    // A region grown over points of other planes does not carry the views onto each other: not a plane.
    const double score = regionScore(r, views[static_cast<std::size_t>(r.reference_view)], photo);
    if (score > -1.0 && score < params.min_region_ncc) continue;
    extended.push_back(r);
  }
  const std::vector<int> group = mergeGroups(extended, on, params);
  PlanarModel model;
  for (std::size_t g = 0; g < extended.size(); ++g) {
    std::vector<const Region*> parts;
    for (std::size_t i = 0; i < extended.size(); ++i) {
      if (group[i] == static_cast<int>(g)) parts.push_back(&extended[i]);
    }
    if (parts.empty()) continue;
    Facet facet = mergeFacet(parts);
    if (facet.polygons.empty()) continue;
    facet.colour = facetColour(facet, views[static_cast<std::size_t>(parts.front()->reference_view)]);
    model.facets.push_back(facet);
  }
  if (stats) {
    stats->half_planes = static_cast<int>(half_planes.size());
    stats->extended = static_cast<int>(extended.size());
    stats->facets = static_cast<int>(model.facets.size());
    stats->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  return model;
}

}  // namespace massage_cell::planar
