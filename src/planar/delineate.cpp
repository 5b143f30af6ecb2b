// Delineation of the facets by per-pixel photo-consistency (see delineate.h).
#include "massage_cell/planar/delineate.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iterator>
#include <mutex>
#include <stdexcept>
#include <string>

#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>

#include "massage_cell/planar/coplanarity.h"
#include "massage_cell/planar/photo_consistency.h"

namespace massage_cell::planar {

namespace {

constexpr int kUntextured = -2;  // label: the pixel cannot be judged
constexpr int kNoPlane = -1;     // label: judged, no facet agrees

void check(bool ok, const std::string& field, double value, const std::string& want) {
  if (!ok) {
    throw std::invalid_argument("DelineateParams." + field + " = " + std::to_string(value) + ": " + want);
  }
}

/// Box mean over the window.
cv::Mat boxMean(const cv::Mat& image, int window) {
  cv::Mat out;
  cv::boxFilter(image, out, CV_32F, cv::Size(window, window), cv::Point(-1, -1), true, cv::BORDER_REFLECT);
  return out;
}

/// The reference view's window statistics, shared by every facet.
struct ReferenceWindows {
  cv::Mat grey, mean, var;  // CV_32F
  cv::Mat textured;         // CV_8U
};

ReferenceWindows referenceWindows(const cv::Mat& grey, const DelineateParams& params) {
  ReferenceWindows w;
  w.grey = grey;
  w.mean = boxMean(grey, params.window);
  w.var = boxMean(grey.mul(grey), params.window) - w.mean.mul(w.mean);
  // Judged: texture in the window and around the pixel itself. The second
  // keeps a window that reaches over a border from labelling the blank
  // pixels beyond it (the window would correlate through the plane there).
  const cv::Mat m3 = boxMean(grey, 3);
  const cv::Mat v3 = boxMean(grey.mul(grey), 3) - m3.mul(m3);
  const double t = params.min_texture * params.min_texture;
  w.textured = (w.var >= t) & (v3 >= 0.25 * t);
  return w;
}

/// Pixels of `roi` of the labelling view where the plane lies in front of both cameras.
cv::Mat inFrontMask(const Projection& Pr, const Projection& Pv, const Eigen::Matrix<double, 4, 3>& M, cv::Rect roi) {
  const Eigen::Vector3d zr = (Pr * M).row(2).transpose(), zv = (Pv * M).row(2).transpose();
  const Eigen::Vector3d t = M.row(3).transpose();
  const double sr = Pr.leftCols<3>().determinant() > 0.0 ? 1.0 : -1.0;
  const double sv = Pv.leftCols<3>().determinant() > 0.0 ? 1.0 : -1.0;
  cv::Mat mask(roi.size(), CV_8U);
  for (int y = 0; y < roi.height; ++y) {
    auto* m = mask.ptr<std::uint8_t>(y);
    for (int x = 0; x < roi.width; ++x) {
      const Eigen::Vector3d p(x + roi.x, y + roi.y, 1.0);
      const double w = t.dot(p);
      m[x] = (sr * zr.dot(p) * w > 0.0 && sv * zv.dot(p) * w > 0.0) ? 255 : 0;
    }
  }
  return mask;
}

/// Windowed NCC over `roi` of the labelling view between it and view v
/// carried onto it by the plane; -2 where the window leaves view v or the
/// plane is behind a camera.
cv::Mat nccThroughPlane(const ReferenceWindows& ref, cv::Rect roi, const cv::Mat& grey_v, const Projection& Pr,
                        const Projection& Pv, const Eigen::Matrix<double, 4, 3>& M, int window) {
  Eigen::Matrix3d shift = Eigen::Matrix3d::Identity();  // roi pixel -> labelling-view pixel
  shift(0, 2) = roi.x;
  shift(1, 2) = roi.y;
  const Eigen::Matrix3d H = Pv * M * shift;  // roi pixel -> view v
  cv::Mat Hcv;
  cv::eigen2cv(H, Hcv);
  cv::Mat warped, inside;
  cv::warpPerspective(grey_v, warped, Hcv, roi.size(), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT, 0);
  cv::warpPerspective(cv::Mat(grey_v.size(), CV_32F, cv::Scalar(1.0f)), inside, Hcv, roi.size(),
                      cv::INTER_NEAREST | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT, 0);
  inside.setTo(0.0f, ~inFrontMask(Pr, Pv, M, roi));
  const cv::Mat mb = boxMean(warped, window);
  const cv::Mat vb = boxMean(warped.mul(warped), window) - mb.mul(mb);
  const cv::Mat cov = boxMean(ref.grey(roi).mul(warped), window) - ref.mean(roi).mul(mb);
  cv::Mat ncc;
  cv::sqrt(cv::max(ref.var(roi).mul(vb), 1e-6), ncc);
  ncc = cov / ncc;
  ncc.setTo(-2.0f, boxMean(inside, window) < 0.999f);
  return ncc;
}

/// Filled projections of the facet's polygons that lie in front of the view.
cv::Mat polygonMask(const View& view, const Facet& facet) {
  cv::Mat mask = cv::Mat::zeros(view.image.size(), CV_8U);
  for (const auto& polygon : facet.polygons) {
    std::vector<cv::Point> pts;
    for (const Eigen::Vector3d& X : polygon) {
      Eigen::Vector2d p;
      if (!project(view.P, X, &p)) break;
      pts.emplace_back(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
    }
    if (pts.size() == polygon.size() && pts.size() >= 3) cv::fillConvexPoly(mask, pts, 255);
  }
  return mask;
}

/// The part of the image a facet may reach: its polygon's bounding box grown
/// by `reach` times its size on every side (empty: not in view).
cv::Rect reachOf(const cv::Mat& seed, double reach) {
  std::vector<cv::Point> pixels;
  cv::findNonZero(seed, pixels);
  if (pixels.empty()) return {};
  const cv::Rect box = cv::boundingRect(pixels);
  const int margin = static_cast<int>(std::ceil(reach * std::max(box.width, box.height)));
  const cv::Rect grown(box.x - margin, box.y - margin, box.width + 2 * margin, box.height + 2 * margin);
  return grown & cv::Rect(0, 0, seed.cols, seed.rows);
}

/// Where the feature points let a plane be the visible surface: the pixels
/// nearer (in the labelling view) to a point on the plane than to one off it.
/// A repetitive print correlates through a wrong plane at some shift; the
/// points there, triangulated from all views, say which depth it is at.
cv::Mat pointsAllow(const View& view, int view_index, const std::vector<PointTrack>& points, const Plane& plane,
                    const CoplanarityTest& on) {
  cv::Mat on_seeds(view.image.size(), CV_8U, cv::Scalar(255)), off_seeds(view.image.size(), CV_8U, cv::Scalar(255));
  bool any_off = false;
  for (const PointTrack& t : points) {
    Eigen::Vector2d p;
    if (!project(view.P, t.X, &p)) continue;
    const int x = static_cast<int>(std::lround(p.x())), y = static_cast<int>(std::lround(p.y()));
    if (x < 0 || y < 0 || x >= on_seeds.cols || y >= on_seeds.rows) continue;
    const bool on_plane = on.onPlane(t.X, plane, view_index);
    (on_plane ? on_seeds : off_seeds).at<std::uint8_t>(y, x) = 0;
    any_off = any_off || !on_plane;
  }
  if (!any_off) return cv::Mat(view.image.size(), CV_8U, cv::Scalar(255));
  if (cv::countNonZero(on_seeds) == static_cast<int>(on_seeds.total())) return cv::Mat::zeros(view.image.size(), CV_8U);
  cv::Mat d_on, d_off;
  cv::distanceTransform(on_seeds, d_on, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  cv::distanceTransform(off_seeds, d_off, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  return d_on <= d_off;
}

/// The facet's pixels: the parts of its label that touch its polygon, and the
/// untextured pixels of its polygon no other facet claims. (A window that
/// straddles the facet's border still correlates through its plane, so the
/// region overruns a border with the untextured background by up to half a
/// window; shrinking it by that much lost more of the faces than it saved.)
cv::Mat facetRegion(const cv::Mat& labels, int f, const cv::Mat& seed, const cv::Mat& allowed) {
  cv::Mat mine = (labels == f) & allowed;
  cv::morphologyEx(mine, mine, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(5, 5)));
  cv::Mat components;
  const int n = cv::connectedComponents(mine, components, 8, CV_32S);
  std::vector<bool> touches(static_cast<std::size_t>(n), false);
  for (int y = 0; y < seed.rows; ++y) {
    const auto* s = seed.ptr<std::uint8_t>(y);
    const auto* c = components.ptr<int>(y);
    for (int x = 0; x < seed.cols; ++x) {
      if (s[x] != 0 && c[x] > 0) touches[static_cast<std::size_t>(c[x])] = true;
    }
  }
  cv::Mat region = cv::Mat::zeros(seed.size(), CV_8U);
  for (int y = 0; y < seed.rows; ++y) {
    const auto* s = seed.ptr<std::uint8_t>(y);
    const auto* c = components.ptr<int>(y);
    const auto* l = labels.ptr<int>(y);
    auto* r = region.ptr<std::uint8_t>(y);
    for (int x = 0; x < seed.cols; ++x) {
      if (touches[static_cast<std::size_t>(c[x])] && c[x] > 0) r[x] = 255;
      if (s[x] != 0 && l[x] == kUntextured) r[x] = 255;
    }
  }
  return region;
}

/// The convex hull of the region's pixels carried onto the plane,
/// counter-clockwise seen from the side the normal points to; empty when the
/// region is empty or a corner falls behind the view.
std::vector<Eigen::Vector3d> hullOnPlane(const cv::Mat& region, const Projection& P, const Plane& plane) {
  std::vector<cv::Point> pixels, hull;
  cv::findNonZero(region, pixels);
  if (pixels.size() < 3) return {};
  cv::convexHull(pixels, hull);
  std::vector<cv::Point> simple;
  cv::approxPolyDP(hull, simple, 1.0, true);
  if (simple.size() < 3) return {};
  const Eigen::Matrix<double, 4, 3> M = planeBackProjection(P, plane);
  std::vector<Eigen::Vector3d> polygon;
  for (const cv::Point& q : simple) {
    const Eigen::Vector4d X = M * Eigen::Vector3d(q.x, q.y, 1.0);
    if (std::abs(X.w()) < 1e-12 || !(depthOf(P, X.hnormalized()) > 0.0)) return {};
    polygon.push_back(X.hnormalized());
  }
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  // Newell's method
  for (std::size_t i = 0; i < polygon.size(); ++i) normal += polygon[i].cross(polygon[(i + 1) % polygon.size()]);
  if (normal.dot(plane.n) < 0.0) std::reverse(polygon.begin(), polygon.end());
  return polygon;
}

/// A point track seen in the labelling view at a pixel no facet explains.
struct LeftOver {
  Eigen::Vector3d X;
  Eigen::Vector2d pixel;
};

/// The point tracks whose pixel in the labelling view no facet explains: no
/// facet agrees there, or the one that does has the point off its plane.
std::vector<LeftOver> leftOverPoints(const std::vector<View>& views, int view, const std::vector<PointTrack>& points,
                                     const PlanarModel& model, const cv::Mat& labels, const CoplanarityTest& on) {
  std::vector<LeftOver> out;
  for (const PointTrack& t : points) {
    Eigen::Vector2d p;
    if (!project(views[static_cast<std::size_t>(view)].P, t.X, &p)) continue;
    const int x = static_cast<int>(std::lround(p.x())), y = static_cast<int>(std::lround(p.y()));
    if (x < 0 || y < 0 || x >= labels.cols || y >= labels.rows) continue;
    const int f = labels.at<int>(y, x);
    if (f == kUntextured) continue;
    if (f >= 0 && on.onPlane(t.X, model.facets[static_cast<std::size_t>(f)].plane, view)) continue;
    out.push_back({t.X, p});
  }
  return out;
}

/// The largest set of left-over points (indices into `free`) on one plane
/// through three of them near each other, by RANSAC.
std::vector<int> largestCoplanarGroup(const std::vector<LeftOver>& pts, const std::vector<int>& free,
                                      const CoplanarityTest& on, int view, const DelineateParams& params,
                                      cv::RNG& rng) {
  std::vector<int> best;
  const int n = static_cast<int>(free.size());
  for (int it = 0; it < 300; ++it) {
    const LeftOver& a = pts[static_cast<std::size_t>(free[static_cast<std::size_t>(rng.uniform(0, n))])];
    std::vector<int> near;
    for (int i : free) {
      if ((pts[static_cast<std::size_t>(i)].pixel - a.pixel).norm() <= params.point_reach) near.push_back(i);
    }
    if (static_cast<int>(near.size()) < params.min_plane_points) continue;
    const int m = static_cast<int>(near.size());
    Plane plane;
    if (!Plane::through(a.X, pts[static_cast<std::size_t>(near[static_cast<std::size_t>(rng.uniform(0, m))])].X,
                        pts[static_cast<std::size_t>(near[static_cast<std::size_t>(rng.uniform(0, m))])].X, &plane))
      continue;
    std::vector<int> inliers;
    for (int i : near) {
      if (on.onPlane(pts[static_cast<std::size_t>(i)].X, plane, view)) inliers.push_back(i);
    }
    if (inliers.size() > best.size()) best = inliers;
  }
  return best;
}

}  // namespace

std::vector<Facet> pointPlanes(const std::vector<View>& views, int view, const std::vector<PointTrack>& points,
                               const PlanarModel& model, const cv::Mat& labels, const DelineateParams& params) {
  params.validate();
  const View& v = views.at(static_cast<std::size_t>(view));
  const CoplanarityTest on(views, params.coplanar_pixels);
  const std::vector<LeftOver> pts = leftOverPoints(views, view, points, model, labels, on);
  std::vector<int> free(pts.size());
  for (std::size_t i = 0; i < free.size(); ++i) free[i] = static_cast<int>(i);
  cv::RNG rng(0x9e3779b9u);  // fixed: the same views give the same planes
  std::vector<Facet> out;
  while (static_cast<int>(out.size()) < params.point_planes &&
         static_cast<int>(free.size()) >= params.min_plane_points) {
    const std::vector<int> group = largestCoplanarGroup(pts, free, on, view, params, rng);
    if (static_cast<int>(group.size()) < params.min_plane_points) break;
    std::vector<Eigen::Vector3d> X;
    std::vector<cv::Point> pixels;
    for (int i : group) {
      X.push_back(pts[static_cast<std::size_t>(i)].X);
      pixels.emplace_back(static_cast<int>(std::lround(pts[static_cast<std::size_t>(i)].pixel.x())),
                          static_cast<int>(std::lround(pts[static_cast<std::size_t>(i)].pixel.y())));
    }
    std::vector<int> rest;
    std::set_difference(free.begin(), free.end(), group.begin(), group.end(), std::back_inserter(rest));
    free = rest;
    Facet facet;
    if (!Plane::fit(X, &facet.plane)) continue;
    if (facet.plane.distance(cameraCentre(v.P)) < 0.0) {
      facet.plane.n = -facet.plane.n;
      facet.plane.d = -facet.plane.d;
    }
    std::vector<cv::Point> hull;
    cv::convexHull(pixels, hull);
    cv::Mat mask = cv::Mat::zeros(labels.size(), CV_8U);
    cv::fillConvexPoly(mask, hull, 255);
    std::vector<Eigen::Vector3d> polygon = hullOnPlane(mask, v.P, facet.plane);
    if (polygon.empty()) continue;
    facet.polygons = {polygon};
    facet.support_points = static_cast<int>(group.size());
    out.push_back(facet);
  }
  return out;
}

void DelineateParams::validate() const {
  check(window >= 3 && window <= 51 && window % 2 == 1, "window", window, "expected an odd 3 .. 51 px");
  check(std::isfinite(min_ncc) && min_ncc > -1.0 && min_ncc < 1.0, "min_ncc", min_ncc, "expected -1 < x < 1");
  check(std::isfinite(min_texture) && min_texture >= 0.0, "min_texture", min_texture, "expected >= 0 grey levels");
  check(std::isfinite(min_agreeing) && min_agreeing >= 0.0 && min_agreeing <= 1.0, "min_agreeing", min_agreeing,
        "expected 0 .. 1");
  check(min_judged >= 1, "min_judged", min_judged, "expected >= 1 px");
  check(point_planes >= 0 && point_planes <= 100, "point_planes", point_planes, "expected 0 .. 100");
  check(min_plane_points >= 3, "min_plane_points", min_plane_points, "expected >= 3");
  check(std::isfinite(reach) && reach >= 0.0, "reach", reach, "expected >= 0");
  check(std::isfinite(point_reach) && point_reach > 0.0, "point_reach", point_reach, "expected > 0 px");
  check(std::isfinite(coplanar_pixels) && coplanar_pixels > 0.0 && coplanar_pixels <= 50.0, "coplanar_pixels",
        coplanar_pixels, "expected 0 < px <= 50");
}

int labellingView(const std::vector<View>& views, const PlanarModel& model) {
  int best = 0;
  long best_area = -1;
  for (std::size_t v = 0; v < views.size(); ++v) {
    long area = 0;
    for (const Facet& facet : model.facets) area += cv::countNonZero(polygonMask(views[v], facet));
    if (area > best_area) {
      best_area = area;
      best = static_cast<int>(v);
    }
  }
  return best;
}

cv::Mat labelPixels(const std::vector<View>& views, int view, const PlanarModel& model, const DelineateParams& params) {
  params.validate();
  const PhotoConsistency photo(views);
  const ReferenceWindows ref = referenceWindows(photo.grey(view), params);
  const Projection& Pr = views[static_cast<std::size_t>(view)].P;
  cv::Mat best(ref.grey.size(), CV_32F, cv::Scalar(-2.0f));
  cv::Mat labels(ref.grey.size(), CV_32S, cv::Scalar(kNoPlane));
  labels.setTo(kUntextured, ~ref.textured);
  std::mutex mutex;
  cv::parallel_for_(cv::Range(0, static_cast<int>(model.facets.size())), [&](const cv::Range& range) {
    for (int f = range.start; f < range.end; ++f) {
      const Facet& facet = model.facets[static_cast<std::size_t>(f)];
      const cv::Rect roi = reachOf(polygonMask(views[static_cast<std::size_t>(view)], facet), params.reach);
      if (roi.empty()) continue;
      const Eigen::Matrix<double, 4, 3> M = planeBackProjection(Pr, facet.plane);
      cv::Mat agree(roi.size(), CV_32F, cv::Scalar(-2.0f));
      for (std::size_t v = 0; v < views.size(); ++v) {
        if (static_cast<int>(v) == view) continue;
        agree = cv::max(agree,
                        nccThroughPlane(ref, roi, photo.grey(static_cast<int>(v)), Pr, views[v].P, M, params.window));
      }
      const std::lock_guard<std::mutex> lock(mutex);
      for (int y = 0; y < roi.height; ++y) {
        const float* a = agree.ptr<float>(y);
        float* b = best.ptr<float>(y + roi.y) + roi.x;
        int* l = labels.ptr<int>(y + roi.y) + roi.x;
        for (int x = 0; x < roi.width; ++x) {
          if (l[x] == kUntextured || a[x] < params.min_ncc) continue;
          if (a[x] > b[x] || (a[x] == b[x] && f < l[x])) {
            b[x] = a[x];
            l[x] = f;
          }
        }
      }
    }
  });
  return labels;
}

namespace {

/// One round: every facet of `model` redrawn from its pixels in `labels`, or
/// dropped when its pixels prefer other planes.
PlanarModel delineateOnce(const std::vector<View>& views, int lv, const std::vector<PointTrack>& points,
                          const PlanarModel& model, const cv::Mat& labels, const DelineateParams& params,
                          DelineateStats* s) {
  const View& view = views[static_cast<std::size_t>(lv)];
  const CoplanarityTest on(views, params.coplanar_pixels);
  PlanarModel out;
  for (std::size_t f = 0; f < model.facets.size(); ++f) {
    Facet facet = model.facets[f];
    const cv::Mat seed = polygonMask(view, facet);
    const int judged = cv::countNonZero(seed & (labels != kUntextured));
    const int agreeing = cv::countNonZero(seed & (labels == static_cast<int>(f)));
    if (judged >= params.min_judged) {
      if (agreeing < params.min_agreeing * judged) {
        ++s->dropped;
        continue;
      }
      std::vector<Eigen::Vector3d> polygon =
          hullOnPlane(facetRegion(labels, static_cast<int>(f), seed, pointsAllow(view, lv, points, facet.plane, on)),
                      view.P, facet.plane);
      if (!polygon.empty()) {
        facet.polygons = {polygon};
        ++s->delineated;
      }
    }
    out.facets.push_back(facet);
  }
  return out;
}

}  // namespace

PlanarModel delineate(const std::vector<View>& views, const std::vector<PointTrack>& points, const PlanarModel& given,
                      const DelineateParams& params, DelineateStats* stats) {
  params.validate();
  const auto t0 = std::chrono::steady_clock::now();
  DelineateStats s;
  s.facets_in = static_cast<int>(given.facets.size());
  PlanarModel out = given;
  if (params.enabled && !given.facets.empty()) {
    s.labelling_view = labellingView(views, given);
    const int lv = s.labelling_view;
    out = delineateOnce(views, lv, points, given, labelPixels(views, lv, given, params), params, &s);
    // The points the delineated facets leave unexplained propose further planes.
    if (params.point_planes > 0 && !out.facets.empty()) {
      const std::vector<Facet> extra = pointPlanes(views, lv, points, out, labelPixels(views, lv, out, params), params);
      s.point_planes = static_cast<int>(extra.size());
      if (!extra.empty()) {
        PlanarModel more = out;
        more.facets.insert(more.facets.end(), extra.begin(), extra.end());
        s.delineated = 0;
        out = delineateOnce(views, lv, points, more, labelPixels(views, lv, more, params), params, &s);
      }
    }
  }
  s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (stats) *stats = s;
  return out;
}

}  // namespace massage_cell::planar
