// CECT queries: a pixel's disparity by barycentric transfer, the geometric constraints it must pass, and the
// triangulated point with its uncertainty (see cect.h, cect_detail.h).
#include "cect_detail.h"

namespace massage_cell::cect {

namespace {

/// matchAlongRow for a window that may cross the back's border: only the
/// window's pixels on `from_mask` whose candidate lies on `to_mask` count
/// (at least a third of the window). Whole pixels (x, y rounded). Also
/// returns the peak's sharpness (minus the second difference of the NCC).
MatchResult maskedMatchAlongRow(const cv::Mat& from, const cv::Mat& to, const cv::Mat& from_mask,
                                const cv::Mat& to_mask, float x, float y, double d_lo, double d_hi, int r, int ry,
                                bool to_left, double* sharpness) {
  MatchResult res;
  *sharpness = 0.0;
  const int xi = cvRound(x), yi = cvRound(y);
  const int lo = static_cast<int>(std::floor(d_lo)), hi = static_cast<int>(std::ceil(d_hi));
  if (hi - lo < 2) {
    res.why = "search range too small";
    return res;
  }
  const int min_count = (2 * r + 1) * (2 * ry + 1) / 3;
  std::vector<double> score(static_cast<std::size_t>(hi - lo + 1), -2.0);
  for (int d = lo; d <= hi; ++d) {
    const int dx = to_left ? d : -d;
    double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
    int n = 0;
    for (int v = yi - ry; v <= yi + ry; ++v) {
      if (v < 0 || v >= from.rows) continue;
      const float* a = from.ptr<float>(v);
      const float* b = to.ptr<float>(v);
      const std::uint8_t* ma = from_mask.ptr<std::uint8_t>(v);
      const std::uint8_t* mb = to_mask.ptr<std::uint8_t>(v);
      for (int u = xi - r; u <= xi + r; ++u) {
        const int uc = u + dx;
        if (u < 0 || u >= from.cols || uc < 0 || uc >= to.cols || !ma[u] || !mb[uc]) continue;
        sa += a[u];
        sb += b[uc];
        saa += static_cast<double>(a[u]) * a[u];
        sbb += static_cast<double>(b[uc]) * b[uc];
        sab += static_cast<double>(a[u]) * b[uc];
        ++n;
      }
    }
    if (n < min_count) continue;
    const double va = saa - sa * sa / n, vb = sbb - sb * sb / n;
    if (va <= 1e-9 || vb <= 1e-9) continue;
    score[static_cast<std::size_t>(d - lo)] = (sab - sa * sb / n) / std::sqrt(va * vb);
  }
  return peakOf(score, lo, "too little of the window on the back", sharpness);
}

}  // namespace

std::size_t CectFrame::foundationalCount() const {
  return static_cast<std::size_t>(
      std::count_if(vertices_.begin(), vertices_.end(), [](const Correspondence& c) { return c.foundational(); }));
}

double CectFrame::transfer(const cv::Point2f& q, double* spread, int* count, cv::Point2d* gradient) const {
  *spread = 0.0;
  *count = 0;
  if (gradient) *gradient = cv::Point2d(0.0, 0.0);
  const int x = cvRound(q.x), y = cvRound(q.y);
  if (x < 0 || y < 0 || x >= triangle_index_.cols || y >= triangle_index_.rows)
    return std::numeric_limits<double>::quiet_NaN();
  const int t = triangle_index_.at<int>(y, x);
  if (t < 0) return std::numeric_limits<double>::quiet_NaN();
  // The containing triangle and every triangle sharing an edge with it.
  std::vector<int> tris{t};
  const cv::Vec3i& T = triangles_[static_cast<std::size_t>(t)];
  for (int j = 0; j < 3; ++j)
    for (int o : vertex_triangles_[static_cast<std::size_t>(T[j])]) {
      if (o == t || std::find(tris.begin(), tris.end(), o) != tris.end()) continue;
      const cv::Vec3i& O = triangles_[static_cast<std::size_t>(o)];
      int shared = 0;
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) shared += T[a] == O[b];
      if (shared == 2) tris.push_back(o);
    }
  double own = std::numeric_limits<double>::quiet_NaN();
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  std::vector<double> cands;
  for (int k : tris) {
    const cv::Vec3i& K = triangles_[static_cast<std::size_t>(k)];
    const Correspondence &a = vertices_[static_cast<std::size_t>(K[0])], &b = vertices_[static_cast<std::size_t>(K[1])],
                         &c = vertices_[static_cast<std::size_t>(K[2])];
    double l0, l1, l2;
    if (!barycentric(q, a.left, b.left, c.left, &l0, &l1, &l2)) continue;
    // The right point is the same barycentric combination of the right
    // vertices; on a common row its x gives the disparity directly.
    const double d = l0 * a.disparity + l1 * b.disparity + l2 * c.disparity;
    if (k == t) {
      own = d;
      if (gradient) {
        // The plane through the three vertices: [ab ac]^T g = [d_b - d_a, d_c - d_a].
        const double ux = b.left.x - a.left.x, uy = b.left.y - a.left.y;
        const double vx = c.left.x - a.left.x, vy = c.left.y - a.left.y;
        const double det = ux * vy - uy * vx;
        const double du = b.disparity - a.disparity, dv = c.disparity - a.disparity;
        if (std::abs(det) > 1e-9) *gradient = cv::Point2d((du * vy - dv * uy) / det, (dv * ux - du * vx) / det);
      }
    }
    cands.push_back(d);
    lo = std::min(lo, d);
    hi = std::max(hi, d);
  }
  if (cands.empty()) return std::numeric_limits<double>::quiet_NaN();
  *spread = hi - lo;
  *count = static_cast<int>(cands.size());
  // The containing triangle interpolates; its neighbours extrapolate: the
  // median of all keeps one bad neighbour from dragging the estimate.
  return cands.size() >= 3 ? median(cands) : (std::isfinite(own) ? own : cands.front());
}

LocalizedPoint CectFrame::localize(const cv::Point2f& left_raw_pixel) const {
  LocalizedPoint out;
  out.pixel = left_raw_pixel;
  if (!valid_) {
    out.reason = "no valid frame: " + reason_;
    return out;
  }
  if (!(left_raw_pixel.x >= 0 && left_raw_pixel.y >= 0 && left_raw_pixel.x <= geometry_.size().width - 1 &&
        left_raw_pixel.y <= geometry_.size().height - 1)) {
    out.reason = "pixel outside the image";
    return out;
  }
  out = localizeRectified(geometry_.toRectified(left_raw_pixel));
  out.pixel = left_raw_pixel;
  return out;
}

LocalizedPoint CectFrame::localizeRectified(const cv::Point2f& q) const {
  LocalizedPoint out;
  out.rectified = q;
  out.pixel = valid_ ? geometry_.toRaw(q) : q;
  if (!valid_) {
    out.reason = "no valid frame: " + reason_;
    return out;
  }
  const int x = cvRound(q.x), y = cvRound(q.y);
  if (!(q.x >= 0 && q.y >= 0) || x >= left_seg_.mask.cols || y >= left_seg_.mask.rows) {
    out.reason = "pixel outside the image";
    return out;
  }
  if (!left_seg_.mask.at<std::uint8_t>(y, x)) {
    out.reason = "pixel is not on the back";
    return out;
  }
  double spread = 0;
  int count = 0;
  cv::Point2d gradient;
  const double d0 = transfer(q, &spread, &count, &gradient);
  if (!std::isfinite(d0)) return extrapolate(q, out);
  out.spread = spread;
  out.candidates = count;
  // Constraint 1.
  if (spread > params_.max_candidate_spread) {
    out.reason = "candidate triangles disagree by " + std::to_string(spread) + " px";
    return out;
  }
  double d = d0;
  double sigma = std::hypot(matchingSigma(), 0.25 * spread);
  if (params_.direct_min_sharpness > 0 && inRowBorderBand(x, y)) {
    // Next to a border running along the rows (the shoulders' top, the neck
    // base, the waist) the transfer leans on the first seeds, whose windows
    // reach across the band's steep relief (the shoulders' top is a ledge
    // behind the back): the transfer there is ~0.6 px too near. The pixel's
    // own window, wide along the border and short across it, is unbiased but
    // noisy (~0.7 px); their mean halves both.
    double dm = 0.0;
    const int r = params_.ncc_radius;
    if (directMatch(q, d0, cvRound(1.4 * r), std::max(2, r / 2), &dm)) d = 0.5 * (d0 + dm);
  }
  if (params_.query_search > 0) {
    const int ry = params_.ncc_half_height > 0 ? params_.ncc_half_height : params_.ncc_radius;
    const double reach = std::min(params_.query_search, params_.continuity_margin);  // constraint 2
    const MatchResult m = matchAlongRow(left_grey_, right_grey_, q.x, q.y, d0 - reach - 1.0, d0 + reach + 1.0,
                                        params_.ncc_radius, ry, false);
    if (m.ok && m.ncc >= params_.min_ncc && std::abs(m.disparity - d0) <= reach) {
      const MatchResult back = matchAlongRow(right_grey_, left_grey_, static_cast<float>(q.x - m.disparity), q.y,
                                             m.disparity - 2.0 - params_.lr_tolerance,
                                             m.disparity + 2.0 + params_.lr_tolerance, params_.ncc_radius, ry, true);
      if (back.ok && std::abs(back.disparity - m.disparity) <= params_.lr_tolerance) {  // constraint 3
        d = m.disparity;
        sigma = matchingSigma();
      }
    }
  }
  // A query_search match keeps the border's part: single windows on skin are
  // noisier than pixel_sigma (cect_eval --param query_search=2: 78 % of the
  // acupoints' errors within 2 sigma with it, 75 % without).
  return triangulated(q, d, structuralSigma(q, sigma, gradient), std::move(out));
}

double CectFrame::structuralSigma(const cv::Point2f& q, double sigma, const cv::Point2d& gradient,
                                  bool interpolated) const {
  double var = sigma * sigma;
  const int x = cvRound(q.x), y = cvRound(q.y);
  const double reach = params_.border_sigma_reach * std::max(1, params_.seed_step);
  if (interpolated && params_.border_sigma > 0 && reach > 0 && !border_distance_.empty() && x >= 0 && y >= 0 &&
      x < border_distance_.cols && y < border_distance_.rows) {
    const double ramp = std::max(0.0, 1.0 - border_distance_.at<float>(y, x) / reach);
    var += std::pow(params_.border_sigma * ramp, 2);
  }
  if (params_.slope_sigma > 0) var += std::pow(params_.slope_sigma * std::hypot(gradient.x, gradient.y), 2);
  return std::sqrt(var);
}

bool CectFrame::directMatch(const cv::Point2f& q, double d, int rx, int ry, double* disparity) const {
  const double reach = params_.continuity_margin;
  double sharp = 0.0, sharp_back = 0.0;
  const MatchResult m = maskedMatchAlongRow(left_grey_, right_grey_, left_inner_, right_inner_, q.x, q.y,
                                            d - reach - 1.0, d + reach + 1.0, rx, ry, false, &sharp);
  if (!m.ok || m.ncc < params_.min_ncc || sharp < params_.direct_min_sharpness || std::abs(m.disparity - d) > reach)
    return false;
  const float xr = static_cast<float>(cvRound(q.x) - std::round(m.disparity));
  const double d_back = cvRound(q.x) - xr;
  const MatchResult back = maskedMatchAlongRow(right_grey_, left_grey_, right_inner_, left_inner_, xr, q.y,
                                               d_back - 2.0 - params_.lr_tolerance, d_back + 2.0 + params_.lr_tolerance,
                                               rx, ry, true, &sharp_back);
  if (!back.ok || std::abs(back.disparity - d_back) > params_.lr_tolerance) return false;  // constraint 3
  *disparity = m.disparity;
  return true;
}

bool CectFrame::inRowBorderBand(int x, int y) const {
  if (seed_region_.at<std::uint8_t>(y, x)) return false;
  const cv::Mat& mask = left_seg_.mask;
  auto on = [&](int xx, int yy) {
    return xx >= 0 && yy >= 0 && xx < mask.cols && yy < mask.rows && mask.at<std::uint8_t>(yy, xx) != 0;
  };
  const int m = seed_margin_;
  return (!on(x, y - m) || !on(x, y + m)) && on(x - m, y) && on(x + m, y);
}

LocalizedPoint CectFrame::extrapolate(const cv::Point2f& q, LocalizedPoint out) const {
  // A back pixel between the contour and the triangulation where the
  // contour gives no foundational correspondences (it runs along the
  // epipolar lines: the neck base, the waist band): the local quadratic of
  // the seeds around it, evaluated at most max_extrapolation seed steps
  // beyond the nearest seed, with the fit's rms and the distance in its
  // uncertainty.
  const double step = std::max(1, params_.seed_step);
  double d = 0.0, rms = 0.0, nearest = 0.0;
  cv::Point2d gradient;
  std::vector<int> idx;
  for (std::size_t i = 0; i < vertices_.size(); ++i)
    if (!vertices_[i].foundational()) idx.push_back(static_cast<int>(i));
  if (params_.max_extrapolation <= 0 || params_.seed_step <= 0 ||
      !fitQuadratic(vertices_, idx, q, 4.0 * step, 12, &d, &rms, &nearest, &gradient) ||
      nearest > params_.max_extrapolation * step) {
    out.reason = "pixel outside the triangulated back (too close to its border)";
    return out;
  }
  // Seeds that scatter beyond three times their matching noise around
  // their own quadratic do not describe a smooth surface here.
  if (rms > 3.0 * params_.pixel_sigma) {
    out.reason = "pixel outside the triangulated back, and the seeds around it do not fit a smooth surface (rms " +
                 std::to_string(rms) + " px)";
    return out;
  }
  if (params_.direct_min_sharpness > 0 && !seed_region_.at<std::uint8_t>(cvRound(q.y), cvRound(q.x))) {
    // In the border band: a direct match where the pixel's own window holds
    // enough texture.
    const int ry = params_.ncc_half_height > 0 ? params_.ncc_half_height : params_.ncc_radius;
    double dm = 0.0;
    if (directMatch(q, d, params_.ncc_radius, ry, &dm))
      // Its own measurement: no interpolation across the band.
      return triangulated(q, dm, structuralSigma(q, matchingSigma(), gradient, false), std::move(out));
  }
  const double sigma = std::hypot(matchingSigma(), rms) * (1.0 + nearest / step);
  out.extrapolated = true;
  return triangulated(q, d, structuralSigma(q, sigma, gradient), std::move(out));
}

LocalizedPoint CectFrame::triangulated(const cv::Point2f& q, double d, double sigma, LocalizedPoint out) const {
  // Covariance: pixel_sigma across the image, the disparity's sigma along
  // it, through the triangulation's Jacobian.
  Eigen::Matrix3d J;
  out.position = geometry_.triangulate(q.x, q.y, d, &J);
  if (!(out.position.z() > 0.0) || !out.position.allFinite()) {
    out.reason = "point behind the camera";
    return out;
  }
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  S(0, 0) = S(1, 1) = matchingSigma() * matchingSigma();
  S(2, 2) = sigma * sigma;
  out.covariance = J * S * J.transpose();
  out.disparity = d;
  out.disparity_sigma = sigma;
  out.valid = true;
  return out;
}

}  // namespace massage_cell::cect
