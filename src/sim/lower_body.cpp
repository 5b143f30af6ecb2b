// The lower body (buttocks, gluteal fold, upper thighs) continuing BackModel,
// and the trunk surface the arms and the towel rest against.
//
// Shape, with t = (x_start - x) / (x_start - x_fold) (0 at the join, 1 at the
// gluteal fold):
//   height(x, y) = F(t) * Q(s; t) - cleft(t, y) (end cap at the thighs' end)
// Q blends the back's own cross-section at the join (it already carries the
// two buttock lobes) into two round thighs touching at the midline; F rises
// to the buttocks' peak, drops at the fold and tapers along the thighs; the
// intergluteal cleft deepens from the sacrum toward the fold.
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include "massage_cell/sim/body_parts.h"
#include "shape_math.h"

namespace massage_cell::sim {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kOverlap = 0.005;  // the mesh starts this far inside the back, just below its skin
constexpr double kEndCap = 0.03;
constexpr int kJoinSamples = 201;

/// Two round thighs side by side (one per half, |s| in [0, 1]), touching at
/// the midline up to about half their height.
double thighs(double s) {
  const double u = (std::abs(s) - 0.5) / 0.5;
  const double round = std::sqrt(std::max(0.0, 1.0 - u * u));
  return std::max(std::pow(round, 0.8), 0.5 * (1.0 - std::pow(std::abs(s), 6.0)));
}

}  // namespace

LowerBody::LowerBody(const BackModel& back) {
  const double k = back.body().torso_length / 0.5;
  x_start_ = back.fullHeightExtent()[0];
  x_fold_ = x_start_ - 0.19 * k;
  x_end_ = x_start_ - 0.42 * k;
  hw_join_ = back.halfWidth(x_start_);
  join_profile_.resize(kJoinSamples);
  for (int i = 0; i < kJoinSamples; ++i) {
    const double s = std::min(static_cast<double>(i) / (kJoinSamples - 1), 1.0 - 1e-9);
    const double h = back.height(x_start_, s * hw_join_);
    join_profile_[static_cast<std::size_t>(i)] = std::isfinite(h) ? h : 0.0;
  }
  join_profile_.back() = 0.0;
  const BodyParameters& b = back.body();
  peak_rise_ = 0.06 + 0.6 * b.buttock_height;  // buttocks' peak above the join, relative
  cleft_depth_ = 0.012 + 0.2 * b.buttock_height;
}

double LowerBody::halfWidth(double x) const {
  if (!(x >= x_end_ && x <= x_start_ + kOverlap)) return 0.0;
  const double t = std::max(0.0, (x_start_ - x) / (x_start_ - x_fold_));
  const double hips = 0.07 * std::pow(std::sin(kPi * std::min(t, 1.0)), 2.0);
  const double thigh = -0.07 * smooth5(1.0, 2.2, t);
  return hw_join_ * (1.0 + hips + thigh);
}

double LowerBody::profile(double x, double s) const {
  const double a = std::min(std::abs(s), 1.0);
  const double f = a * (kJoinSamples - 1);
  const std::size_t i = std::min(static_cast<std::size_t>(f), static_cast<std::size_t>(kJoinSamples - 2));
  const double w = f - static_cast<double>(i);
  const double join = (1.0 - w) * join_profile_[i] + w * join_profile_[i + 1];
  const double t = std::max(0.0, (x_start_ - x) / (x_start_ - x_fold_));
  const double thigh_w = smooth5(0.75, 1.3, t);
  const double q = (1.0 - thigh_w) * join + thigh_w * join_profile_[0] * 1.05 * thighs(s);
  const double fold_drop = 0.32;
  double factor = 1.0 + peak_rise_ * smooth5(0.0, 0.5, t);
  factor -= (peak_rise_ + fold_drop) * smooth5(0.55, 1.08, t);
  factor -= 0.12 * smooth5(1.1, 2.2, t);
  double h = factor * q;
  const double hw = halfWidth(x);
  const double sigma = 0.005 + 0.006 * std::min(t, 1.0);
  h -= cleft_depth_ * smooth5(0.05, 0.5, t) * (1.0 - thigh_w) * gauss(s * hw / sigma);
  // Just below the back's skin where the two overlap (cranial of the join),
  // so the back stays on top there; both meet tangentially at the join.
  h -= 0.001 * smooth5(x_start_, x_start_ + kOverlap, x);
  const double cap = (x_end_ + kEndCap - x) / kEndCap;
  if (cap > 0.0) h *= std::max(0.0, 1.0 - cap * cap);
  return std::max(h, 0.0);
}

double LowerBody::height(double x, double y) const {
  const double hw = halfWidth(x);
  if (!(hw > 0.0) || !(std::abs(y) <= hw)) return kNaN;
  return profile(x, y / hw);
}

Mesh LowerBody::mesh(const Material& skin, double spacing) const {
  if (!(spacing >= 0.0005 && spacing <= 0.05))
    throw std::invalid_argument("LowerBody::mesh: spacing not in 0.0005 .. 0.05 m");
  const double x0 = x_start_ + kOverlap, x1 = x_end_;
  const int rows = std::max(2, static_cast<int>(std::ceil((x0 - x1) / spacing)) + 1);
  const double max_hw = hw_join_ * 1.08;
  // Columns: uniform (for the narrow cleft at the midline) merged with
  // sine-spaced ones (dense toward the steep flanks).
  const int half = std::max(4, static_cast<int>(std::ceil(max_hw * kPi / 2.0 / spacing)));
  const int uniform = std::max(4, static_cast<int>(std::ceil(max_hw / (0.6 * spacing))));
  std::vector<double> cols;
  for (int j = -half; j <= half; ++j) cols.push_back(std::sin(kPi / 2.0 * j / half));
  for (int j = -uniform + 1; j < uniform; ++j) cols.push_back(static_cast<double>(j) / uniform);
  std::sort(cols.begin(), cols.end());
  cols.erase(std::unique(cols.begin(), cols.end(), [](double a, double b) { return b - a < 1e-4; }), cols.end());
  const int nc = static_cast<int>(cols.size());
  Mesh mesh;
  mesh.name = "lower_body";
  mesh.label = kLabelBack;
  mesh.material = skin;
  for (int i = 0; i < rows; ++i) {
    const double x = x0 + (x1 - x0) * i / (rows - 1);
    const double hw = halfWidth(x);
    for (int j = 0; j < nc; ++j) {
      const double s = cols[static_cast<std::size_t>(j)];
      const bool border = i + 1 == rows || j == 0 || j + 1 == nc;
      const double z = border ? 0.0 : profile(x, s);
      mesh.vertices.emplace_back(static_cast<float>(x), static_cast<float>(s * hw), static_cast<float>(z));
      mesh.uv.emplace_back(static_cast<float>(x), static_cast<float>(s * hw));
    }
  }
  for (int i = 0; i + 1 < rows; ++i) {
    for (int j = 0; j + 1 < nc; ++j) {
      // Rows run toward -x, so (a, b, c) is counter-clockwise seen from above.
      const int a = i * nc + j, b = a + 1, c = a + nc, d = c + 1;
      mesh.triangles.emplace_back(a, b, d);
      mesh.triangles.emplace_back(a, d, c);
    }
  }
  smoothNormals(mesh);
  return mesh;
}

// ---------------------------------------------------------------------------

TrunkSurface::TrunkSurface(const BackModel& back, const LowerBody* lower) : back_(back), lower_(lower) {}

double TrunkSurface::height(double x, double y) const {
  double h = 0.0;
  if (back_.halfWidth(x) > 0.0) {
    const double hb = back_.height(x, y);
    if (std::isfinite(hb)) h = hb;
  }
  if (lower_) {
    const double hl = lower_->height(x, y);
    if (std::isfinite(hl)) h = std::max(h, hl);
  }
  return h;
}

double TrunkSurface::halfWidth(double x) const {
  return std::max(back_.halfWidth(x), lower_ ? lower_->halfWidth(x) : 0.0);
}

double TrunkSurface::xMin() const { return lower_ ? lower_->xEnd() : back_.extent()[0]; }

double TrunkSurface::xMax() const { return back_.extent()[1]; }

}  // namespace massage_cell::sim
