// The acupoint model's corrections with the back in 3D (acupoint_model.h): the silhouette's centre line moved onto
// the skin's midline (correctMidlineParallax: the flanks' rims lie below the spine, so a camera off the midline sees
// them shifted against it), the waist moved to the spine's row at its rims' place along the body
// (correctWaistParallax), and the levels spaced along the body's axis in 3D rather than in the image's rows
// (measureLevelsIn3D); frameScale / framePoints give a CECT frame's surface as these and the placement want it.
#include "massage_cell/cect/acupoint_model.h"
#include "massage_cell/cect/cect.h"

#include "acupoint_model_detail.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

namespace massage_cell::cect {

namespace {

/// The first and last back pixel of mask row y (-1 when the row has none).
void rowExtent(const cv::Mat& mask, int y, int* first, int* last) {
  *first = *last = -1;
  const std::uint8_t* row = mask.ptr<std::uint8_t>(y);
  for (int x = 0; x < mask.cols; ++x)
    if (row[x]) {
      if (*first < 0) *first = x;
      *last = x;
    }
}

/// The image's mask in the body's frame (for the landmarks' rows).
cv::Mat maskInBodyFrame(const BackLandmarks& l, const cv::Mat& mask) {
  if (isIdentity(l.to_image)) return mask;
  const cv::Matx23d to_body = inverse(l.to_image);
  float x1 = 0.0f, y1 = 0.0f;
  for (const cv::Point2f corner :
       {cv::Point2f(0, 0), cv::Point2f(static_cast<float>(mask.cols), 0), cv::Point2f(0, static_cast<float>(mask.rows)),
        cv::Point2f(static_cast<float>(mask.cols), static_cast<float>(mask.rows))}) {
    const cv::Point2f q = apply(to_body, corner);
    x1 = std::max(x1, q.x);
    y1 = std::max(y1, q.y);
  }
  cv::Mat out;
  cv::warpAffine(mask, out, to_body, cv::Size(static_cast<int>(std::ceil(x1)) + 1, static_cast<int>(std::ceil(y1)) + 1),
                 cv::INTER_NEAREST, cv::BORDER_CONSTANT, 0);
  return out;
}

}  // namespace

double correctMidlineParallax(BackLandmarks* landmarks, const Segmentation& left, const PointLookup& image_point) {
  BackLandmarks& l = *landmarks;
  if (!l.valid || l.midline.size() < 10 || left.mask.empty() || !image_point) return kNaN;
  // Rows of the body's frame.
  const cv::Mat mask = maskInBodyFrame(l, left.mask);
  PointLookup point = image_point;
  if (!isIdentity(l.to_image)) {
    point = [&l, &image_point](const cv::Point2f& q, cv::Point3d* p) { return image_point(toImage(l, q), p); };
  }
  auto dot = [](const cv::Point3d& a, const cv::Point3d& b) { return a.x * b.x + a.y * b.y + a.z * b.z; };
  std::vector<double> ys, shifts;
  const double y0 = std::min(l.c7.body.y, l.l4.body.y), y1 = std::max(l.c7.body.y, l.l4.body.y);
  for (const cv::Point2f& m : l.midline) {
    if (m.y < y0 || m.y > y1) continue;  // the torso between C7 and L4
    const int y = cvRound(m.y);
    if (y < 0 || y >= mask.rows) continue;
    int xl = -1, xr = -1;
    rowExtent(mask, y, &xl, &xr);
    if (xl < 0 || xr - xl < 20) continue;
    cv::Point3d pl, pr;
    const float fy = static_cast<float>(y);
    // The rims themselves (the outermost back pixels): points further in
    // are not symmetric (each view sees one flank more face-on).
    if (!point(cv::Point2f(static_cast<float>(xl), fy), &pl) || !point(cv::Point2f(static_cast<float>(xr), fy), &pr))
      continue;
    // Across the body parallel to the image plane (the table, seen from
    // above): the rims themselves lie at different heights (each is where
    // the view ray grazes the flank), so the chord between them tilts.
    const cv::Point3d mid = 0.5 * (pl + pr), across(pr.x - pl.x, pr.y - pl.y, 0.0);
    const double len = std::sqrt(dot(across, across));
    if (!(len > 0.0)) continue;
    const cv::Point3d n = across / len;
    double x = m.x;
    bool ok = true;
    for (int it = 0; it < 3 && ok; ++it) {
      cv::Point3d p, pa, pb;
      ok = point(cv::Point2f(static_cast<float>(x), fy), &p) &&
           point(cv::Point2f(static_cast<float>(x - 2), fy), &pa) &&
           point(cv::Point2f(static_cast<float>(x + 2), fy), &pb);
      if (!ok) break;
      const double slope = dot(pb - pa, n) / 4.0;  // metres along n per pixel
      if (!(slope > 0.0)) {
        ok = false;
        break;
      }
      x -= dot(p - mid, n) / slope;
      ok = x > xl && x < xr;
    }
    if (!ok) continue;
    ys.push_back(m.y);
    shifts.push_back(x - m.x);
  }
  if (ys.size() < 10) return kNaN;
  // shift(y) = a + b y, least squares, once more without the residuals beyond 3 MAD.
  const Eigen::Index n = static_cast<Eigen::Index>(ys.size());
  Eigen::MatrixXd A(n, 2), B(n, 1);
  for (Eigen::Index i = 0; i < n; ++i) {
    A.row(i) << 1.0, ys[static_cast<std::size_t>(i)];
    B(i, 0) = shifts[static_cast<std::size_t>(i)];
  }
  auto within3Mad = [](double r, double mad) { return r <= 3.0 * std::max(0.1, mad) ? 1.0 : 0.0; };
  Eigen::Vector2d line;
  Eigen::VectorXd used;
  if (!robustFit(A, B, 1, within3Mad, &line, &used) || (used.array() > 0.0).count() < 10) return kNaN;
  const double a = line(0), b = line(1);
  auto shiftAt = [&](double y) { return static_cast<float>(a + b * y); };
  double mean = 0.0;
  for (cv::Point2f& m : l.midline) {
    m.x += shiftAt(m.y);
    mean += shiftAt(m.y);
  }
  l.c7.body.x += shiftAt(l.c7.body.y);
  l.l4.body.x += shiftAt(l.l4.body.y);
  return mean / static_cast<double>(l.midline.size());
}

double correctWaistParallax(BackLandmarks* landmarks, const AcupointModel& model, const Segmentation& left,
                            const PointLookup& image_point) {
  BackLandmarks& l = *landmarks;
  if (!l.valid || l.midline.size() < 10 || left.mask.empty() || !image_point) return kNaN;
  if (l.c7.source != LandmarkSource::kMeasured || l.l4.source != LandmarkSource::kMeasured)
    return kNaN;  // C7 and L4 do not hang on the top and the waist
  const double c = model.c7_below_top, q = model.waist_fraction;
  if (!(c + q > 0.0)) return kNaN;
  const cv::Mat mask = maskInBodyFrame(l, left.mask);
  auto point = [&](const cv::Point2f& body, Eigen::Vector3d* out) {
    cv::Point3d p;
    if (!image_point(toImage(l, body), &p)) return false;
    *out = Eigen::Vector3d(p.x, p.y, p.z);
    return true;
  };
  // The waist's rims in 3D: the mean of the midpoints between the outermost
  // back pixels of the rows around the waist.
  Eigen::Vector3d rims = Eigen::Vector3d::Zero();
  int n = 0;
  const int wy = static_cast<int>(std::lround(l.waist_row));
  for (int y = wy - 3; y <= wy + 3; ++y) {
    if (y < 0 || y >= mask.rows) continue;
    int xl = -1, xr = -1;
    rowExtent(mask, y, &xl, &xr);
    Eigen::Vector3d pl, pr;
    const float fy = static_cast<float>(y);
    if (xl < 0 || xr - xl < 20 || !point(cv::Point2f(static_cast<float>(xl), fy), &pl) ||
        !point(cv::Point2f(static_cast<float>(xr), fy), &pr))
      continue;
    rims += 0.5 * (pl + pr);
    ++n;
  }
  if (n < 3) return kNaN;
  rims /= n;
  // Along the body parallel to the image plane (the camera looks down at the
  // table: the rims and the spine differ in height, so a chord that tilts
  // with the spine would pair them at different places): the body frame's
  // columns in the image.
  const Eigen::Vector3d axis = Eigen::Vector3d(l.to_image(0, 1), l.to_image(1, 1), 0.0).normalized();
  // The midline row at the rims' position along the axis (a sign change of
  // the distance along it, between C7 and L4).
  double spine_row = kNaN, prev_d = kNaN, prev_y = kNaN;
  for (const cv::Point2f& m : l.midline) {
    if (m.y < l.c7.body.y || m.y > l.l4.body.y) continue;
    Eigen::Vector3d p;
    if (!point(m, &p)) continue;
    const double d = (p - rims).dot(axis);
    if (std::isfinite(prev_d) && prev_d < 0.0 && d >= 0.0) {
      spine_row = prev_y + (m.y - prev_y) * (-prev_d) / (d - prev_d);
      break;
    }
    prev_d = d;
    prev_y = m.y;
  }
  if (!std::isfinite(spine_row)) return kNaN;
  const double length = static_cast<double>(l.l4.body.y) - l.c7.body.y;
  const double move = (spine_row - l.waist_row) - model.waist_rim_offset * length;
  const double waist = l.waist_row + move;
  const double new_length = (waist - l.top_row) / (c + q);
  if (!(new_length > 0.0)) return kNaN;
  const double c7_row = l.top_row + c * new_length, l4_row = c7_row + new_length;
  l.c7.body = midlineAt(l, c7_row);
  l.l4.body = midlineAt(l, l4_row);
  l.waist_row = waist;
  l.iliac_row = l4_row;
  l.along.clear();  // measured from the old C7: measureLevelsIn3D again
  return move;
}

double measureLevelsIn3D(BackLandmarks* landmarks, const PointLookup& image_point) {
  BackLandmarks& l = *landmarks;
  if (!l.valid || l.midline.size() < 10 || !image_point) return kNaN;
  const double length_rows = static_cast<double>(l.l4.body.y) - l.c7.body.y;
  if (!(length_rows > 10.0)) return kNaN;
  // The 3D points of the midline from just above C7 to a quarter of C7 -> L4
  // below L4 (the model's lowest levels), as functions of u = 0 at C7, 1 at L4.
  const double u_lo = -0.05, u_hi = 1.25;
  std::vector<double> us;
  std::vector<Eigen::Vector3d> ps;
  int near_c7 = 0, near_l4 = 0;
  for (const cv::Point2f& m : l.midline) {
    const double u = (m.y - l.c7.body.y) / length_rows;
    if (u < u_lo || u > u_hi) continue;
    cv::Point3d p;
    if (!image_point(toImage(l, m), &p)) continue;
    us.push_back(u);
    ps.emplace_back(p.x, p.y, p.z);
    near_c7 += std::abs(u) < 0.1 ? 1 : 0;
    near_l4 += std::abs(u - 1.0) < 0.1 ? 1 : 0;
  }
  if (us.size() < 30 || near_c7 < 5 || near_l4 < 5) return kNaN;
  // Each coordinate a cubic in u (least squares, Eigen), refitted twice with
  // Huber weights on the 3D residual (a hole or a wrong point in the surface).
  const Eigen::Index n = static_cast<Eigen::Index>(us.size());
  Eigen::MatrixXd A(n, 4), B(n, 3);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double u = us[static_cast<std::size_t>(i)];
    A.row(i) << 1.0, u, u * u, u * u * u;
    B.row(i) = ps[static_cast<std::size_t>(i)].transpose();
  }
  Eigen::Matrix<double, 4, 3> C;
  auto huber = [](double r, double median) { return huberWeight(r, 1.5 * std::max(1e-3, 1.4826 * median)); };
  if (!robustFit(A, B, 2, huber, &C)) return kNaN;
  auto P = [&](double u) { return Eigen::Vector3d((Eigen::RowVector4d(1.0, u, u * u, u * u * u) * C).transpose()); };
  const Eigen::Vector3d c7 = P(0.0), chord = P(1.0) - c7;
  const double length = chord.norm();
  if (!(length > 0.0)) return kNaN;
  const Eigen::Vector3d axis = chord / length;
  const double u_min = *std::min_element(us.begin(), us.end()), u_max = *std::max_element(us.begin(), us.end());
  std::vector<double> along(l.midline.size(), kNaN);
  double last = -std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < l.midline.size(); ++i) {
    const double u = (l.midline[i].y - l.c7.body.y) / length_rows;
    if (u < u_min || u > u_max) continue;
    along[i] = (P(u) - c7).dot(axis);
    if (!(along[i] > last)) return kNaN;  // not monotonic: not a back lying along its axis
    last = along[i];
  }
  l.along = std::move(along);
  return length;
}

PixelScale frameScale(const CectFrame& frame) {
  return [&frame](const cv::Point2f& q) {
    const LocalizedPoint p = frame.localizeRectified(q);
    return p.valid ? p.position.z() / frame.geometry().fx() : kNaN;
  };
}

PointLookup framePoints(const CectFrame& frame) {
  return [&frame](const cv::Point2f& q, cv::Point3d* out) {
    const LocalizedPoint p = frame.localizeRectified(q);
    if (!p.valid) return false;
    *out = cv::Point3d(p.position.x(), p.position.y(), p.position.z());
    return true;
  };
}

}  // namespace massage_cell::cect
