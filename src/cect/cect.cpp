// CECT: foundational correspondences on the back's contour, barycentric
// transfer inside it, three geometric constraints, triangulation
// (see cect.h). Our design where the thesis extract is silent:
//
// * Epipolar lines are rows of the rectified pair (camera::StereoModel). A left
//   contour sample's own crossing and the right view's crossings of that row
//   are zero crossings of each view's continuous skin score, interpolated
//   between pixels, so foundational correspondences are sub-pixel.
// * Several right crossings on a row: only those of the same kind (entering
//   or leaving the back walking right) with a disparity in range are
//   candidates; the k-th such left crossing of the row takes the k-th right
//   one when both rows hold the same number, otherwise the candidate closest
//   to the disparity of the unambiguous samples along the contour nearby.
//   Samples where the border runs nearly along the row are dropped: there
//   the crossing's x is ill-conditioned.
// * The contour alone cannot carry the back's relief inward (the spine lies
//   ~5 cm above the flanks: ~9 px of disparity at 0.8 m), so interior seeds on
//   a grid are matched along their epipolar line by normalised cross
//   correlation, searching only around their barycentric prediction, and
//   join the triangulation once accepted; two passes (coarse grid, wide
//   search; then the grid of `seed_step`, narrow search around the denser
//   triangulation's prediction).
// * The three geometric constraints:
//   1. candidate agreement: the transfers through the containing triangle and
//      its edge neighbours must agree within max_candidate_spread pixels;
//   2. continuity: a seed's disparity may differ from the median of its grid
//      neighbours by at most continuity_margin (the back is smooth), and a
//      query's refinement may move its prediction by at most that much;
//   3. left-right consistency: matching the right point back into the left
//      view must return within lr_tolerance pixels.
//   Epipolar consistency itself holds by construction (every vertex has
//   y_left = y_right, and barycentric combinations keep it).
#include "cect_detail.h"

namespace massage_cell::cect {

namespace {

double msSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

/// Gaussian blur of `img` (CV_32F) over the pixels of weight `w` (CV_32F in
/// [0, 1]) only: blur(img w) / blur(w), normalised convolution. Blurs with
/// sigma >= 3 run at half resolution (their result is smooth; 8x fewer
/// operations).
cv::Mat maskedBlur(const cv::Mat& img, const cv::Mat& w, double sigma) {
  cv::Mat both, b;
  cv::merge(std::vector<cv::Mat>{img.mul(w), w}, both);
  if (sigma >= 3.0 && both.cols >= 8 && both.rows >= 8) {
    cv::Mat half;
    cv::resize(both, half, cv::Size((both.cols + 1) / 2, (both.rows + 1) / 2), 0, 0, cv::INTER_AREA);
    cv::GaussianBlur(half, half, cv::Size(0, 0), sigma / 2.0);
    cv::resize(half, b, both.size(), 0, 0, cv::INTER_LINEAR);
  } else {
    cv::GaussianBlur(both, b, cv::Size(0, 0), sigma);
  }
  cv::Mat ch[2];
  cv::split(b, ch);
  return ch[0] / cv::max(ch[1], 1e-3);
}

/// s rounded to the nearest power of 2^(1/4).
double quantisedScale(double s) { return std::exp2(std::round(4.0 * std::log2(s)) / 4.0); }

}  // namespace

double viewScale(double median_disparity, double baseline) {
  if (!(median_disparity > 0) || !(baseline > 0) || !std::isfinite(median_disparity / baseline)) return 1.0;
  return quantisedScale(median_disparity / baseline / kReferencePixelsPerMetre);
}

cv::Vec2d disparityRange(const CectParams& p, const camera::StereoModel& geometry) {
  const double width = geometry.size().width;
  double lo = p.min_disparity, hi = p.max_disparity;
  if (!(lo > 0)) lo = std::max(0.5, geometry.disparityAtDepth(p.max_depth));
  if (!(hi > 0)) hi = std::min(width - 1.0, geometry.disparityAtDepth(p.min_depth));
  if (!std::isfinite(lo) || !std::isfinite(hi)) return cv::Vec2d(0.0, 0.0);
  return cv::Vec2d(lo, hi);
}

CectParams scaledParams(const CectParams& p, double scale) {
  CectParams q = p;
  if (scale == 1.0 || !(scale > 0)) return q;
  const double s = scale;
  // A window's extent 2r + 1 scales (23 px -> 11.5 -> r = 5 at half size).
  auto radius = [s](int r) { return std::max(1, static_cast<int>(std::lround(((2 * r + 1) * s - 1.0) / 2.0))); };
  auto step = [s](int n) { return n > 0 ? std::max(2, static_cast<int>(std::lround(n * s))) : n; };
  q.sample_spacing = p.sample_spacing * s;
  q.edge_window = p.edge_window * s;
  q.seed_step = step(p.seed_step);
  q.seed_column_step = step(p.seed_column_step);
  q.ncc_radius = radius(p.ncc_radius);
  q.ncc_half_height = p.ncc_half_height > 0 ? radius(p.ncc_half_height) : 0;
  q.bandpass_low = p.bandpass_low * s;
  q.bandpass_high = p.bandpass_high * s;
  q.sheen_sigma = p.sheen_sigma * s;
  q.seed_margin = p.seed_margin >= 0 ? p.seed_margin * s : p.seed_margin;
  q.direct_min_sharpness = p.direct_min_sharpness / (s * s);
  q.seed_search = p.seed_search * s;
  q.query_search = p.query_search * s;
  q.max_candidate_spread = p.max_candidate_spread * s;
  q.continuity_margin = p.continuity_margin * s;
  q.min_slant = p.min_slant * s;
  q.border_sigma = p.border_sigma * s;
  q.slope_sigma = p.slope_sigma * s;
  SegmentationParams& g = q.segmentation;
  g.blur_sigma = p.segmentation.blur_sigma * s;
  g.open_radius = std::max(1, static_cast<int>(std::lround(p.segmentation.open_radius * s)));
  g.close_radius = std::max(1, static_cast<int>(std::lround(p.segmentation.close_radius * s)));
  g.contour_spacing = p.segmentation.contour_spacing * s;
  return q;  // (the trunk's pixel sizes scale with the body itself: trunk.h)
}

void CectFrameBuilder::run(const cv::Mat& left, const cv::Mat& right) {
  const auto t0 = Clock::now();
  f_.geometry_.rectify(left, right, &f_.left_rect_, &f_.right_rect_);
  // Rectified input comes back as the caller's own images, which may be a message's buffer that dies with it: the
  // frame keeps copies, so that its views outlive the pair (a node keeps its latest frame for its services).
  if (f_.left_rect_.data == left.data) f_.left_rect_ = left.clone();
  if (f_.right_rect_.data == right.data) f_.right_rect_ = right.clone();
  f_.timings_.rectify_ms = msSince(t0);
  f_.disparity_range_ = disparityRange(f_.params_, f_.geometry_);
  if (!(f_.disparity_range_[1] > f_.disparity_range_[0]))
    return fail("empty disparity range " + std::to_string(f_.disparity_range_[0]) + ".." +
                    std::to_string(f_.disparity_range_[1]) + " px (min_depth / max_depth or min / max_disparity)",
                t0);

  // With auto_scale the segmentation and the contour's sampling scale with
  // the image's width first (a prior); once the contour is matched, its
  // median disparity gives the view's scale for everything after it.
  const CectParams given = f_.params_;
  if (given.auto_scale) {
    const double s0 = quantisedScale(f_.left_rect_.cols / 640.0);
    f_.params_ = scaledParams(given, s0);
    f_.scale_ = s0;
  }

  auto t = Clock::now();
  f_.background_ = farBackground(f_.left_rect_, f_.right_rect_, f_.geometry_, f_.disparity_range_, given.background);
  // The two views are independent until matching: one core each.
  cv::parallel_for_(cv::Range(0, 2), [&](const cv::Range& views) {
    for (int v = views.start; v < views.end; ++v) {
      const cv::Mat& rect = v == 0 ? f_.left_rect_ : f_.right_rect_;
      (v == 0 ? f_.left_marks_ : f_.right_marks_) =
          given.skin_markers ? skinMarkerPixels(rect, *given.skin_markers) : cv::Mat();
      (v == 0 ? f_.left_seg_ : f_.right_seg_) = segmentBack(
          rect, f_.params_.segmentation, v == 0 ? f_.background_.left_far : f_.background_.right_far,
          v == 0 ? f_.background_.left_depth : f_.background_.right_depth, v == 0 ? f_.left_marks_ : f_.right_marks_);
    }
  });
  retryWithoutTheTable(given.background.table_margin);
  f_.timings_.segment_ms = msSince(t);
  if (!f_.left_seg_.valid) return fail("left view: " + f_.left_seg_.reason, t0);
  if (!f_.right_seg_.valid) return fail("right view: " + f_.right_seg_.reason, t0);

  t = Clock::now();
  foundational();
  f_.timings_.foundational_ms = msSince(t);
  if (f_.vertices_.size() < 8)
    return fail("only " + std::to_string(f_.vertices_.size()) +
                    " foundational correspondences (the contours' epipolar lines found no consistent crossings)",
                t0);
  if (given.auto_scale) {
    std::vector<double> d;
    d.reserve(f_.vertices_.size());
    for (const auto& v : f_.vertices_) d.push_back(v.disparity);
    const double s = viewScale(median(d), f_.geometry_.baseline());
    CectParams scaled = scaledParams(given, s);
    // What the segmentation and the contour's matching used stays.
    scaled.segmentation = f_.params_.segmentation;
    scaled.sample_spacing = f_.params_.sample_spacing;
    scaled.edge_window = f_.params_.edge_window;
    f_.params_ = scaled;
    f_.scale_ = s;
  }

  t = Clock::now();
  cv::parallel_for_(cv::Range(0, 2), [&](const cv::Range& views) {
    for (int v = views.start; v < views.end; ++v)
      (v == 0 ? f_.left_grey_ : f_.right_grey_) =
          matchingImage(v == 0 ? f_.left_rect_ : f_.right_rect_, v == 0 ? f_.left_seg_.mask : f_.right_seg_.mask);
  });
  f_.timings_.segment_ms += msSince(t);
  const cv::Mat k3 = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(7, 7));
  cv::erode(f_.left_seg_.mask, f_.left_inner_, k3);
  cv::erode(f_.right_seg_.mask, f_.right_inner_, k3);
  const int margin = f_.params_.seed_margin >= 0 ? cvRound(f_.params_.seed_margin) : f_.params_.ncc_radius + 2;
  f_.seed_margin_ = margin;
  cv::erode(f_.left_seg_.mask, f_.seed_region_,
            cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * margin + 1, 2 * margin + 1)));
  cv::distanceTransform(f_.left_seg_.mask, f_.border_distance_, cv::DIST_L2, 3);

  t = Clock::now();
  triangulate();
  if (f_.params_.seed_step > 0) {
    seeds(2 * f_.params_.seed_step, f_.params_.seed_search);
    triangulate();
    seeds(f_.params_.seed_step, std::max(2.0, 0.5 * f_.params_.seed_search),
          f_.params_.seed_column_step > 0 ? f_.params_.seed_column_step : f_.params_.seed_step);
    if (f_.params_.slanted_windows && f_.params_.smooth_radius > 0)
      slantSeeds(f_.params_.smooth_radius * f_.params_.seed_step);
    if (f_.params_.smooth_radius > 0) smoothSeeds(f_.params_.smooth_radius * f_.params_.seed_step);
    if (f_.params_.rim_profile) rimProfiles();
    triangulate(f_.params_.max_triangle_edge * f_.params_.seed_step);
  }
  f_.timings_.interior_ms = msSince(t);
  if (f_.triangles_.empty()) return fail("no triangles over the foundational correspondences", t0);
  f_.valid_ = true;
  f_.timings_.total_ms = msSince(t0);
}

/// A view whose segmentation failed (a sheet or towel of skin's colour
/// joined to the back: "multi-coloured") is segmented again with the
/// table's pixels (tablePixels) left out as well; kept when that works.
/// Only then: the coarse depth is too rough at the body's foot to leave
/// the table out everywhere.
void CectFrameBuilder::retryWithoutTheTable(double margin) {
  DepthGate& g = f_.background_;
  for (int v = 0; v < 2; ++v) {
    Segmentation& seg = v == 0 ? f_.left_seg_ : f_.right_seg_;
    const cv::Mat& depth = v == 0 ? g.left_depth : g.right_depth;
    if (seg.valid || !(margin > 0.0) || depth.empty()) continue;
    const cv::Mat& far = v == 0 ? g.left_far : g.right_far;
    const cv::Mat table = tablePixels(depth, far, f_.geometry_, margin);
    if (table.empty()) continue;
    Segmentation retry =
        segmentBack(v == 0 ? f_.left_rect_ : f_.right_rect_, f_.params_.segmentation,
                    far.empty() ? table : (far | table), depth, v == 0 ? f_.left_marks_ : f_.right_marks_);
    if (!retry.valid) continue;
    seg = std::move(retry);
    (v == 0 ? g.left_table : g.right_table) = table;
  }
}

void CectFrameBuilder::fail(const std::string& why, Clock::time_point t0) {
  f_.valid_ = false;
  f_.reason_ = why;
  f_.timings_.total_ms = msSince(t0);
}

/// Grey without the specular sheen, by the dichromatic reflection model:
/// in linear RGB (sRGB decoded) every back pixel is I = D c + S (1,1,1),
/// a diffuse part of the skin's own chromaticity c (the median over the
/// back) plus a specular part of the light's colour (white). D and S are
/// solved per pixel (least squares, 3 channels); S, noisy, is smoothed
/// (Gaussian, sheen_sigma; with sheen_twicing 2 G*S - G*G*S, which keeps
/// the highlights' peaks) and taken off every channel; the grey of the
/// rest is returned, scaled back to 0..255. Outside the back: plain grey.
cv::Mat CectFrameBuilder::diffuseGrey(const cv::Mat& bgr, const cv::Mat& mask) const {
  static const std::array<float, 256> lut = [] {
    std::array<float, 256> t{};
    for (int i = 0; i < 256; ++i) {
      const double v = i / 255.0;
      t[static_cast<std::size_t>(i)] =
          static_cast<float>(v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4));
    }
    return t;
  }();
  cv::Mat lin(bgr.size(), CV_32FC3);
  for (int y = 0; y < bgr.rows; ++y) {
    const cv::Vec3b* src = bgr.ptr<cv::Vec3b>(y);
    cv::Vec3f* dst = lin.ptr<cv::Vec3f>(y);
    for (int x = 0; x < bgr.cols; ++x) dst[x] = cv::Vec3f(lut[src[x][0]], lut[src[x][1]], lut[src[x][2]]);
  }
  // The skin's chromaticity: per-channel medians of the normalised colour
  // over the more saturated half of the back (the sheen whitens the rest).
  std::vector<cv::Vec3f> chroma;
  for (int y = 0; y < bgr.rows; y += 3) {
    const cv::Vec3f* l = lin.ptr<cv::Vec3f>(y);
    const std::uint8_t* m = mask.ptr<std::uint8_t>(y);
    for (int x = 0; x < bgr.cols; x += 3) {
      const float sum = l[x][0] + l[x][1] + l[x][2];
      if (m[x] && sum > 1e-3f) chroma.push_back(l[x] / sum);
    }
  }
  cv::Mat S = cv::Mat::zeros(bgr.size(), CV_32F);
  if (chroma.size() >= 32) {
    auto whiteness = [](const cv::Vec3f& v) { return std::min({v[0], v[1], v[2]}); };
    auto half = chroma.begin() + static_cast<std::ptrdiff_t>(chroma.size() / 2);
    std::nth_element(chroma.begin(), half, chroma.end(),
                     [&](const cv::Vec3f& a, const cv::Vec3f& b) { return whiteness(a) < whiteness(b); });
    Eigen::Vector3d c;
    for (int k = 0; k < 3; ++k) {
      std::vector<float> v;
      v.reserve(chroma.size() / 2);
      for (auto it = chroma.begin(); it != half; ++it) v.push_back((*it)[k]);
      c(k) = detail::median(v, detail::EvenCount::kUpperMiddle);
    }
    // Normal equations of min |I - D c - S 1|^2: [c.c c.1; c.1 3] [D S]' = [c.I 1.I]'.
    const double cc = c.squaredNorm(), c1 = c.sum();
    const double det = 3.0 * cc - c1 * c1;
    if (std::abs(det) > 1e-9) {
      const float a = static_cast<float>(-c1 / det), b = static_cast<float>(cc / det);
      const cv::Vec3f cf(static_cast<float>(c(0)), static_cast<float>(c(1)), static_cast<float>(c(2)));
      for (int y = 0; y < bgr.rows; ++y) {
        const cv::Vec3f* l = lin.ptr<cv::Vec3f>(y);
        float* s = S.ptr<float>(y);
        for (int x = 0; x < bgr.cols; ++x) {
          const float ci = cf[0] * l[x][0] + cf[1] * l[x][1] + cf[2] * l[x][2];
          const float oi = l[x][0] + l[x][1] + l[x][2];
          s[x] = a * ci + b * oi;
        }
      }
      cv::Mat m;
      mask.convertTo(m, CV_32F, 1.0 / 255.0);
      const cv::Mat smooth = maskedBlur(S, m, f_.params_.sheen_sigma);
      S = f_.params_.sheen_twicing ? cv::Mat(2.0 * smooth - maskedBlur(smooth, m, f_.params_.sheen_sigma)) : smooth;
      S.setTo(0, mask == 0);
    }
  }
  cv::Mat out(bgr.size(), CV_32F);
  for (int y = 0; y < bgr.rows; ++y) {
    const cv::Vec3f* l = lin.ptr<cv::Vec3f>(y);
    const float* s = S.ptr<float>(y);
    float* o = out.ptr<float>(y);
    for (int x = 0; x < bgr.cols; ++x) o[x] = 255.0f * (0.114f * l[x][0] + 0.587f * l[x][1] + 0.299f * l[x][2] - s[x]);
  }
  return out;
}

/// Matching image band-passed: a difference of Gaussians keeps
/// the skin's mottling and the relief's edges and drops the broad shading
/// and the specular sheen, which move with the viewpoint.
cv::Mat CectFrameBuilder::matchingImage(const cv::Mat& bgr, const cv::Mat& mask) const {
  const CectParams& p = f_.params_;
  auto grey = [&](const cv::Mat& img, const cv::Mat& m) {
    if (p.sheen_sigma > 0) return diffuseGrey(img, m);
    cv::Mat g, f;
    cv::cvtColor(img, g, cv::COLOR_BGR2GRAY);
    g.convertTo(f, CV_32F);
    return f;
  };
  if (p.bandpass_high <= 0) return grey(bgr, mask);
  // Normalised convolution inside the back: the step to the background at
  // the contour would otherwise ring ~2 sigma into the skin, and that
  // step is the occluding rim, a different surface line in each view.
  // Only the back's bounding box (plus the matching windows' reach) is needed.
  const int margin = 2 * (std::max(p.ncc_radius, p.ncc_half_height) + 2);
  const cv::Rect roi = (cv::boundingRect(mask) + cv::Size(2 * margin, 2 * margin) - cv::Point(margin, margin)) &
                       cv::Rect(0, 0, bgr.cols, bgr.rows);
  cv::Mat out = cv::Mat::zeros(bgr.size(), CV_32F);
  if (roi.empty()) return out;
  const cv::Mat f = grey(bgr(roi), mask(roi));
  cv::Mat m;
  mask(roi).convertTo(m, CV_32F, 1.0 / 255.0);
  const cv::Mat lo = p.bandpass_low > 0 ? maskedBlur(f, m, p.bandpass_low) : f;
  cv::Mat band = lo - maskedBlur(f, m, p.bandpass_high);
  band.setTo(0, mask(roi) == 0);
  band.copyTo(out(roi));
  return out;
}

CectFrame CectFrame::analyse(const cv::Mat& left, const cv::Mat& right, const camera::StereoModel& geometry,
                             const CectParams& params) {
  if (geometry.empty()) throw std::invalid_argument("CECT: no stereo geometry (calibration) given");
  if (left.empty() || right.empty()) throw std::invalid_argument("CECT: empty image");
  if (left.type() != CV_8UC3 || right.type() != CV_8UC3)
    throw std::invalid_argument("CECT: images must be 8-bit BGR (CV_8UC3)");
  if (params.ncc_radius < 1) throw std::invalid_argument("CECT: ncc_radius must be >= 1");
  if (params.seed_step < 0) throw std::invalid_argument("CECT: seed_step must be >= 0");
  if (params.seed_column_step < 0) throw std::invalid_argument("CECT: seed_column_step must be >= 0");
  if (!(params.sample_spacing > 0)) throw std::invalid_argument("CECT: sample_spacing must be > 0");
  if (!(params.min_depth > 0) || !(params.max_depth > params.min_depth) || !std::isfinite(params.max_depth))
    throw std::invalid_argument("CECT: the depth range must satisfy 0 < min_depth < max_depth (finite), got " +
                                std::to_string(params.min_depth) + ".." + std::to_string(params.max_depth) + " m");
  if (!(params.min_disparity >= 0) || !(params.max_disparity >= 0) ||
      (params.max_disparity > 0 && params.max_disparity <= params.min_disparity))
    throw std::invalid_argument("CECT: min_disparity / max_disparity must be >= 0 and max > min unless 0");
  CectFrame f;
  f.geometry_ = geometry;
  f.params_ = params;
  f.params_.segmentation.contour_spacing = params.sample_spacing;
  CectFrameBuilder(f).run(left, right);
  return f;
}

cv::Mat CectFrame::drawDebug() const {
  cv::Mat img = left_rect_.empty() ? cv::Mat() : left_rect_.clone();
  if (img.empty()) return img;
  for (const auto& t : triangles_) {
    const cv::Point pts[3] = {vertices_[static_cast<std::size_t>(t[0])].left,
                              vertices_[static_cast<std::size_t>(t[1])].left,
                              vertices_[static_cast<std::size_t>(t[2])].left};
    for (int j = 0; j < 3; ++j) cv::line(img, pts[j], pts[(j + 1) % 3], cv::Scalar(200, 200, 0), 1, cv::LINE_AA);
  }
  if (!left_seg_.contour.empty()) {
    std::vector<cv::Point> c;
    for (const auto& p : left_seg_.contour) c.emplace_back(cvRound(p.x), cvRound(p.y));
    cv::polylines(img, c, true, cv::Scalar(255, 0, 255), 1, cv::LINE_AA);
  }
  for (const auto& v : vertices_)
    cv::circle(img, cv::Point(cvRound(v.left.x), cvRound(v.left.y)), 2,
               v.foundational()                                  ? cv::Scalar(0, 0, 255)
               : v.source == Correspondence::Source::kRimProfile ? cv::Scalar(0, 200, 255)
                                                                 : cv::Scalar(0, 255, 0),
               -1, cv::LINE_AA);
  if (!valid_)
    cv::putText(img, reason_, cv::Point(10, 20), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 255), 1, cv::LINE_AA);
  return img;
}

}  // namespace massage_cell::cect
