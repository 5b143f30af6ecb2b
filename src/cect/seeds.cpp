// CECT step 3: interior seeds matched around their barycentric prediction, smoothed and slanted, and the rim
// band between the contour and the first seeds (see cect.h, cect_detail.h).
#include "cect_detail.h"

namespace massage_cell::cect {

namespace {

/// matchAlongRow with a slanted window: the left window's pixel (x+u, y+v)
/// is compared with the right view at x+u - (d + g.x u + g.y v), the
/// disparity plane through d with gradient g (bilinear samples), for
/// d = d0 - range .. d0 + range in whole pixels, then a parabola. A
/// fronto-parallel window on a slanted surface compares pixels whose
/// disparities differ by g.x r + g.y ry at its edges (~1.5 px at the
/// shoulders' top), and its peak follows wherever the window's texture is
/// strongest rather than its centre.
MatchResult slantedMatch(const cv::Mat& left, const cv::Mat& right, int x, int y, double d0, const cv::Point2d& g,
                         int range, int r, int ry) {
  MatchResult res;
  if (x - r < 0 || y - ry < 0 || x + r >= left.cols || y + ry >= left.rows) {
    res.why = "matching window leaves the image";
    return res;
  }
  std::vector<float> ref;
  if (!windowAt(left, static_cast<float>(x), static_cast<float>(y), r, ry, &ref)) {
    res.why = "no texture in the matching window";
    return res;
  }
  const int n = static_cast<int>(ref.size());
  std::vector<double> score(static_cast<std::size_t>(2 * range + 1), -2.0);
  std::vector<float> cand(ref.size());
  for (int k = -range; k <= range; ++k) {
    const double d = d0 + k;
    double sum = 0.0;
    int i = 0;
    bool inside = true;
    for (int v = -ry; v <= ry && inside; ++v)
      for (int u = -r; u <= r; ++u) {
        const double xr = x + u - (d + g.x * u + g.y * v);
        if (xr < 0.0 || xr > right.cols - 1.0) {
          inside = false;
          break;
        }
        const float c = sample(right, static_cast<float>(xr), static_cast<float>(y + v));
        cand[static_cast<std::size_t>(i++)] = c;
        sum += c;
      }
    if (!inside) continue;
    const double mean = sum / n;
    double ss = 0.0, dot = 0.0;
    for (int j = 0; j < n; ++j) {
      const double c = cand[static_cast<std::size_t>(j)] - mean;
      ss += c * c;
      dot += c * ref[static_cast<std::size_t>(j)];
    }
    if (ss < 1e-6 * n) continue;
    score[static_cast<std::size_t>(k + range)] = dot / std::sqrt(ss);
  }
  MatchResult m = peakOf(score, 0, "matching window leaves the image");
  if (m.ok) m.disparity += d0 - range;
  return m;
}

/// One seed beside a rim vertex: u along the rim's inward normal, t across
/// it (pixels), its disparity, its index among the vertices.
struct RimObservation {
  double u, t, d;
  int vertex;
};

/// The rim profile d(u, t) = k0 + k1 sqrt(u / step) + k2 u / step + k3 t / step.
double rimProfileAt(const Eigen::Vector4d& k, double u, double t, double step) {
  return k(0) + k(1) * std::sqrt(u / step) + k(2) * u / step + k(3) * t / step;
}

/// Least-squares rim profile through the rim's own disparity (at u = 0,
/// weight `rim_weight`) and the seeds `obs`; while its rms exceeds `max_rms`
/// the seed farthest from it goes to `outliers` and the fit is repeated,
/// as long as five seeds remain. False when it never holds.
bool fitRimProfile(double rim_disparity, double rim_weight, double step, double max_rms,
                   std::vector<RimObservation>* obs, Eigen::Vector4d* k, std::vector<int>* outliers) {
  while (obs->size() >= 5) {
    Eigen::Matrix4d A = Eigen::Matrix4d::Zero();
    Eigen::Vector4d b = Eigen::Vector4d::Zero();
    auto add = [&](double u, double t, double d, double w) {
      const Eigen::Vector4d phi(1.0, std::sqrt(u / step), u / step, t / step);
      A += w * phi * phi.transpose();
      b += w * d * phi;
    };
    add(0.0, 0.0, rim_disparity, rim_weight);
    for (const RimObservation& o : *obs) add(o.u, o.t, o.d, 1.0);
    *k = A.ldlt().solve(b);
    if (!k->allFinite()) return false;
    double ss = rim_weight * std::pow(rim_disparity - rimProfileAt(*k, 0.0, 0.0, step), 2), worst_res = -1.0;
    std::size_t worst = 0;
    for (std::size_t o = 0; o < obs->size(); ++o) {
      const RimObservation& r = (*obs)[o];
      const double res = std::abs(r.d - rimProfileAt(*k, r.u, r.t, step));
      ss += res * res;
      if (res > worst_res) {
        worst_res = res;
        worst = o;
      }
    }
    if (std::sqrt(ss / (static_cast<double>(obs->size()) + rim_weight)) <= max_rms) return true;
    outliers->push_back((*obs)[worst].vertex);
    obs->erase(obs->begin() + static_cast<std::ptrdiff_t>(worst));
  }
  return false;
}

}  // namespace

/// The band between the contour and the first seeds. The contour is the
/// back's occluding rim: there the surface turns away from the camera, and
/// across a smooth rim depth varies with the square root of the image
/// distance u to it (a cross-section of curvature radius R seen edge-on
/// rises by sqrt(2 R x) at a distance x from its rim). Linear interpolation
/// between a rim vertex and the first seeds ~30 px inside undershoots that
/// profile by up to ~4 px of disparity on a flank. So for every other rim
/// vertex, d(u, t) = c + a sqrt(u) + b u + e t is fitted (least squares)
/// to the seeds within a band along its inward normal (u along it, t
/// across it) and to the rim's own disparity at u = 0; where the fit holds
/// (rms within 2 pixel_sigma), vertices at u = 2, 5, 9, ... px are added up
/// to half a seed step short of the nearest seed. Where it does not hold,
/// the seed farthest from the fit is dropped and the fit repeated while
/// five seeds remain: one bad seed on a steep flank (a window spanning a
/// fall of several pixels of disparity) otherwise spoils both the profile
/// and the interpolation from it.
void CectFrameBuilder::rimProfiles() {
  auto& V = f_.vertices_;
  const double step = f_.params_.seed_step;
  const double band = 0.75 * step, reach = 5.0 * step;
  const double rim_weight = 2.0;  // the rim's own crossing counts as two seeds
  std::vector<int> seeds;
  for (std::size_t i = 0; i < V.size(); ++i)
    if (V[i].source == Correspondence::Source::kSeed) seeds.push_back(static_cast<int>(i));
  const cv::Mat& mask = f_.left_seg_.mask;
  std::vector<Correspondence> added;
  std::vector<int> drop;
  const std::size_t n_rim = std::min(rim_normals_.size(), V.size());
  for (std::size_t i = 0; i < n_rim; i += 2) {
    const Correspondence& rim = V[i];
    if (!rim.foundational()) continue;
    const cv::Point2f n = rim_normals_[i];
    const cv::Point2f t(-n.y, n.x);
    std::vector<RimObservation> obs;
    for (int j : seeds) {
      const cv::Point2f q = V[static_cast<std::size_t>(j)].left - rim.left;
      const double u = q.dot(n), tt = q.dot(t);
      if (u <= 0.0 || u > reach || std::abs(tt) > band) continue;
      obs.push_back({u, tt, V[static_cast<std::size_t>(j)].disparity, j});
    }
    Eigen::Vector4d k;
    std::vector<int> outliers;
    if (!fitRimProfile(rim.disparity, rim_weight, step, 2.0 * f_.params_.pixel_sigma, &obs, &k, &outliers)) continue;
    double u_min = reach;
    for (const RimObservation& o : obs) u_min = std::min(u_min, o.u);
    if (u_min > 3.0 * step) continue;
    drop.insert(drop.end(), outliers.begin(), outliers.end());
    // The profile interpolates between the rim and the seeds: a value
    // outside their range (beyond the continuity margin) is an
    // extrapolation of a fit the seeds do not hold, e.g. next to the
    // image's edge, where the back is cut and the seeds lie to one side.
    double lo = rim.disparity, hi = rim.disparity;
    for (const RimObservation& o : obs) {
      lo = std::min(lo, o.d);
      hi = std::max(hi, o.d);
    }
    lo -= f_.params_.continuity_margin;
    hi += f_.params_.continuity_margin;
    for (double u : {2.0, 5.0, 9.0, 14.0, 20.0, 27.0, 35.0, 44.0}) {
      if (u > u_min - 0.5 * step) break;
      const double d = rimProfileAt(k, u, 0.0, step);
      if (d < lo || d > hi) break;
      const cv::Point2f q = rim.left + static_cast<float>(u) * n;
      const int x = cvRound(q.x), y = cvRound(q.y);
      if (x < 0 || y < 0 || x >= mask.cols || y >= mask.rows || !mask.at<std::uint8_t>(y, x)) break;
      Correspondence c;
      c.left = q;
      c.disparity = static_cast<float>(d);
      c.sigma = static_cast<float>(f_.params_.pixel_sigma);
      c.source = Correspondence::Source::kRimProfile;
      added.push_back(c);
    }
  }
  std::sort(drop.begin(), drop.end());
  drop.erase(std::unique(drop.begin(), drop.end()), drop.end());
  for (auto it = drop.rbegin(); it != drop.rend(); ++it) V.erase(V.begin() + *it);
  f_.seed_stats_.rim_outliers += static_cast<int>(drop.size());
  V.insert(V.end(), added.begin(), added.end());
}

/// True when a border running along the rows lies within `reach` pixels
/// above or below (x, y) while the back continues `reach` pixels to
/// either side along the row (the shoulders' top, the neck base).
bool CectFrameBuilder::nearRowBorder(int x, int y, int reach) const {
  const cv::Mat& mask = f_.left_seg_.mask;
  auto on = [&](int xx, int yy) {
    return xx >= 0 && yy >= 0 && xx < mask.cols && yy < mask.rows && mask.at<std::uint8_t>(yy, xx) != 0;
  };
  return (!on(x, y - reach) || !on(x, y + reach)) && on(x - reach, y) && on(x + reach, y);
}

/// Each interior seed on a slanted part of the back (or within 2 seed
/// steps of a border along the rows) is matched again with a slanted
/// window: the disparity plane of the seeds' local quadratic around it
/// (its gradient at the seed), searched +-2 px around the seed's first
/// match. Kept when the peak is found, strong enough (min_ncc) and
/// within continuity_margin of the first match; otherwise the first match
/// stays.
void CectFrameBuilder::slantSeeds(double radius) {
  auto& V = f_.vertices_;
  const CectParams& p = f_.params_;
  const int r = p.ncc_radius;
  const int ry = p.ncc_half_height > 0 ? p.ncc_half_height : r;
  std::vector<int> idx;
  for (std::size_t i = 0; i < V.size(); ++i)
    if (V[i].source == Correspondence::Source::kSeed) idx.push_back(static_cast<int>(i));
  std::vector<float> refined(V.size(), std::numeric_limits<float>::quiet_NaN());
  cv::parallel_for_(cv::Range(0, static_cast<int>(idx.size())), [&](const cv::Range& range) {
    for (int k = range.start; k < range.end; ++k) {
      const std::size_t i = static_cast<std::size_t>(idx[static_cast<std::size_t>(k)]);
      double fit = 0.0;
      cv::Point2d g;
      if (!fitQuadratic(V, idx, V[i].left, radius, 8, &fit, nullptr, nullptr, &g)) continue;
      // Nearly fronto-parallel: the first match stands (a re-match there
      // only trades one noisy peak for another, with the right window
      // interpolated). But next to a border along the rows (the
      // shoulders' top) the skin rolls over toward the head, and the
      // quadratic, fitted from one side only, underestimates that slope:
      // those seeds are re-matched in any case.
      const bool ledge = nearRowBorder(cvRound(V[i].left.x), cvRound(V[i].left.y), 2 * p.seed_step);
      if (!ledge && std::abs(g.x) * r + std::abs(g.y) * ry < p.min_slant) continue;
      const MatchResult m = slantedMatch(f_.left_grey_, f_.right_grey_, cvRound(V[i].left.x), cvRound(V[i].left.y),
                                         std::round(V[i].disparity), g, 2, r, ry);
      if (m.ok && m.ncc >= p.min_ncc && std::abs(m.disparity - V[i].disparity) <= p.continuity_margin)
        refined[i] = static_cast<float>(m.disparity);
    }
  });
  for (int i : idx) {
    const float d = refined[static_cast<std::size_t>(i)];
    if (std::isfinite(d)) V[static_cast<std::size_t>(i)].disparity = d;
  }
}

/// Each interior seed's disparity becomes the value at the seed of a
/// weighted quadratic (with quartic_across: quartic across the body)
/// fitted to the seeds within `radius` pixels (Gaussian weights, sigma =
/// radius / 2; one refit without the residuals beyond 3 MAD): single
/// matches on skin are noisy (~0.6 px), the back is smooth.
/// A seed farther than continuity_margin from its fit is dropped
/// (constraint 2).
void CectFrameBuilder::smoothSeeds(double radius) {
  auto& V = f_.vertices_;
  std::vector<int> idx;
  for (std::size_t i = 0; i < V.size(); ++i)
    if (V[i].source == Correspondence::Source::kSeed) idx.push_back(static_cast<int>(i));
  std::vector<float> smoothed(V.size(), std::numeric_limits<float>::quiet_NaN());
  const bool quartic = f_.params_.quartic_across;
  cv::parallel_for_(cv::Range(0, static_cast<int>(idx.size())), [&](const cv::Range& range) {
    for (int k = range.start; k < range.end; ++k) {
      const std::size_t i = static_cast<std::size_t>(idx[static_cast<std::size_t>(k)]);
      double fit = 0.0;
      // Too few neighbours to fit: the seed stays as matched.
      if (fitQuadratic(V, idx, V[i].left, radius, 8, &fit, nullptr, nullptr, nullptr, quartic))
        smoothed[i] = static_cast<float>(fit);
    }
  });
  std::vector<Correspondence> kept;
  kept.reserve(V.size());
  for (std::size_t i = 0; i < V.size(); ++i) {
    Correspondence v = V[i];
    if (v.source == Correspondence::Source::kSeed && std::isfinite(smoothed[i])) {
      if (std::abs(v.disparity - smoothed[i]) > f_.params_.continuity_margin) {
        ++f_.seed_stats_.smoothing;
        continue;
      }
      v.disparity = smoothed[i];
    }
    kept.push_back(v);
  }
  V.swap(kept);
}

/// Interior seeds on a grid of `step` pixels (rows; columns every
/// `column_step`, 0: `step`), matched within `search` of their barycentric
/// prediction, kept when they pass the constraints.
void CectFrameBuilder::seeds(int step, double search, int column_step) {
  const int cstep = column_step > 0 ? column_step : step;
  const CectParams& p = f_.params_;
  const int r = p.ncc_radius;
  const int ry = p.ncc_half_height > 0 ? p.ncc_half_height : r;
  const cv::Mat& inner = f_.seed_region_;
  struct Seed {
    cv::Point2f left;
    double d;
    int gx, gy;
  };
  std::vector<Seed> found;
  const bool contour_only = f_.foundationalCount() == f_.vertices_.size();
  const double fxb = f_.geometry_.fx() * f_.geometry_.baseline();
  const int w = f_.left_rect_.cols, h = f_.left_rect_.rows;
  // Skip grid points already close to a vertex.
  cv::Mat taken = cv::Mat::zeros(h, w, CV_8U);
  for (const auto& v : f_.vertices_)
    cv::circle(taken, cv::Point(cvRound(v.left.x), cvRound(v.left.y)), std::max(2, step / 3), cv::Scalar(255), -1);
  struct Job {
    cv::Point2f q;
    double lo, hi;
    int gx, gy;
    enum { kNoPeak, kWeak, kLeftRight, kFound } outcome = kNoPeak;
    double d = 0.0;
  };
  std::vector<Job> jobs;
  for (int y = step / 2; y < h; y += step)
    for (int x = (step / 2) % cstep; x < w; x += cstep) {
      if (!inner.at<std::uint8_t>(y, x) || taken.at<std::uint8_t>(y, x)) continue;
      const cv::Point2f q(static_cast<float>(x), static_cast<float>(y));
      double spread = 0;
      int count = 0;
      const double d0 = f_.transfer(q, &spread, &count);
      if (!std::isfinite(d0)) continue;
      const double reach = search + 0.5 * spread;
      // The back rises above its contour (it rests on the table there), so
      // while the triangulation holds only the contour the search reaches
      // up to max_relief metres nearer than the prediction.
      double hi = d0 + reach;
      if (contour_only) {
        const double z0 = fxb / std::max(d0, 1e-3);
        hi = z0 > p.max_relief ? fxb / (z0 - p.max_relief) + reach : maxDisparity();
      }
      jobs.push_back({q, std::max(minDisparity(), d0 - reach), std::min(maxDisparity(), hi), x / cstep, y / step});
    }
  // Matching, the bulk of the work, on every core (each seed on its own).
  cv::parallel_for_(cv::Range(0, static_cast<int>(jobs.size())), [&](const cv::Range& range) {
    for (int i = range.start; i < range.end; ++i) {
      Job& j = jobs[static_cast<std::size_t>(i)];
      const MatchResult m = matchAlongRow(f_.left_grey_, f_.right_grey_, j.q.x, j.q.y, j.lo, j.hi, r, ry, false);
      if (!m.ok) continue;  // kNoPeak
      if (m.ncc < p.min_ncc) {
        j.outcome = Job::kWeak;
        continue;
      }
      // Constraint 3: back from the right view, from the whole pixel
      // nearest the match (its own disparity to the seed is q.x - xr).
      const float xr = std::round(static_cast<float>(j.q.x - m.disparity));
      const double d_back = j.q.x - xr;
      const MatchResult back = matchAlongRow(f_.right_grey_, f_.left_grey_, xr, j.q.y, d_back - 2.0 - p.lr_tolerance,
                                             d_back + 2.0 + p.lr_tolerance, r, ry, true);
      if (!back.ok || std::abs(back.disparity - d_back) > p.lr_tolerance) {
        j.outcome = Job::kLeftRight;
        continue;
      }
      j.outcome = Job::kFound;
      j.d = m.disparity;
    }
  });
  for (const Job& j : jobs) {
    ++f_.seed_stats_.tried;
    switch (j.outcome) {
      case Job::kNoPeak:
        ++f_.seed_stats_.no_peak;
        break;
      case Job::kWeak:
        ++f_.seed_stats_.weak;
        break;
      case Job::kLeftRight:
        ++f_.seed_stats_.left_right;
        break;
      case Job::kFound:
        found.push_back({j.q, j.d, j.gx, j.gy});
        break;
    }
  }
  // Constraint 2: continuity with the grid neighbours.
  std::map<std::pair<int, int>, double> grid;
  for (const auto& s : found) grid[{s.gx, s.gy}] = s.d;
  for (const auto& s : found) {
    std::vector<double> nb;
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        if (!dx && !dy) continue;
        const auto it = grid.find({s.gx + dx, s.gy + dy});
        if (it != grid.end()) nb.push_back(it->second);
      }
    if ((nb.size() >= 2 && std::abs(s.d - median(nb)) > p.continuity_margin) ||
        (nb.size() < 2 && step > p.seed_step)) {  // isolated coarse seeds are not trusted
      ++f_.seed_stats_.continuity;
      continue;
    }
    ++f_.seed_stats_.accepted;
    Correspondence c;
    c.left = s.left;
    c.disparity = static_cast<float>(s.d);
    c.sigma = static_cast<float>(p.pixel_sigma);
    c.source = Correspondence::Source::kSeed;
    f_.vertices_.push_back(c);
  }
}

}  // namespace massage_cell::cect
