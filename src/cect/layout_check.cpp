// Plausibility checks of a pair's layout (see layout_check.h).
//
// Each check compares a quantity that the chain measured with one that the
// adult population allows, and only where the quantity is not already fixed
// by the model's own proportions: the C7 -> L4 length over the shoulder width
// is checked when L4 hangs on the waist or was given (not when L4 was
// inferred from that very width), the shoulder line's place below C7 when C7
// was not taken from the shoulder line. A C7 not measured at a neck's base is
// not trusted at all (TrustRules::c7_at_neck, on by default), nor is an L4 inferred from C7 and the shoulder width
// (TrustRules::l4_measured); with C7 and L4 both given, the
// shoulder line is no longer used (the cun comes from C7 -> L4), so neither
// are its checks. Given landmarks pass the same gate as measured ones: on the
// spine line the pair's 3D shows, a given T7 within the population's spread,
// agreeing with the same landmark measured (or confirmed), not stale.
#include "massage_cell/cect/layout_check.h"

#include "acupoint_model_detail.h"
#include "stats_detail.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace massage_cell::cect {

namespace {

std::string fixed(double v, int precision) {
  std::ostringstream s;
  s.precision(precision);
  s << std::fixed << v;
  return s.str();
}

/// Median metres per pixel over the midline from C7 to L4 (nine samples), NaN without a scale.
double midlineMetresPerPixel(const BackLandmarks& l, const PixelScale& scale) {
  if (!scale) return kNaN;
  std::vector<double> s;
  for (int k = 0; k <= 8; ++k) {
    const double v =
        scale(toImage(l, midlineAt(l, l.c7.body.y + k / 8.0 * (l.l4.body.y - l.c7.body.y), Beyond::kClamp)));
    if (std::isfinite(v) && v > 0.0) s.push_back(v);
  }
  return s.size() < 3 ? kNaN : detail::median(s);
}

/// C7 -> L4 in metres: along the body in 3D when measured (measureLevelsIn3D), else the rows by the scale.
double lengthMetres(const BackLandmarks& l, double metres_per_pixel) {
  if (l.along.size() == l.midline.size() && !l.along.empty()) {
    const double t = std::clamp(l.l4.body.y - l.midline.front().y, 0.0f, static_cast<float>(l.midline.size() - 1));
    const double along = l.along[static_cast<std::size_t>(std::lround(t))];
    if (std::isfinite(along) && along > 0.0) return along;
  }
  return (l.l4.body.y - l.c7.body.y) * metres_per_pixel;
}

void within(LayoutCheck* c, double value, double lo, double hi, const std::string& what, const std::string& unit,
            int precision) {
  if (!std::isfinite(value) || (value >= lo && value <= hi)) return;
  c->problems.push_back(what + " " + fixed(value, precision) + unit + " is outside " + fixed(lo, precision) + ".." +
                        fixed(hi, precision) + unit);
}

/// "98 mm (3.9 cun)" with a scale, else "3.9 cun".
std::string across(double pixels, double cun_px, double mpp) {
  const std::string cun = fixed(std::abs(pixels) / cun_px, 1) + " cun";
  return std::isfinite(mpp) ? fixed(std::abs(pixels) * mpp * 1000.0, 0) + " mm (" + cun + ")" : cun;
}

/// A level given between C7 and L4 (T7) where the model puts it; beyond the model's proportions noted, beyond the
/// population's spread refused.
void checkGivenLevels(LayoutCheck* c, const BackLandmarks& l, const AcupointModel& model) {
  const AcupointModel::Plausibility& pl = model.plausibility;
  for (const Landmark& g : l.given_levels) {
    const auto expected = model.level_fraction.find(g.level);
    if (expected == model.level_fraction.end()) continue;
    const double at = fractionAtRow(l, g.body.y), off = std::abs(at - expected->second);
    const std::string where =
        g.level + " (given) lies at " + fixed(at, 2) + " of C7 -> L4, the model's " + fixed(expected->second, 2);
    if (off > pl.given_level_limit)
      c->problems.push_back(where + " +- " + fixed(pl.given_level_limit, 2) + " (the population's spread): C7, " +
                            g.level + " or L4 is not where it was given");
    else if (off > pl.given_level_tolerance)
      c->notes.push_back(where + ": more than " + fixed(pl.given_level_tolerance, 2) +
                         " off the model's proportions (used as given)");
  }
}

/// Each given landmark on the spine: within max_given_off_midline_cun of the back's midline as the pair measured it
/// (`midline_mpp`: the midline's median metres per pixel, NaN without a scale).
void checkGivenOnSpine(LayoutCheck* c, const BackLandmarks& l, const AcupointModel& model, const PixelScale& scale,
                       double midline_mpp) {
  const double limit = model.plausibility.max_given_off_midline_cun;
  const double cun_m = scale ? cunMetres(l, model, scale) : kNaN;
  for (const BackLandmarks::GivenCheck& g : l.given_checks) {
    // The scale at the given row; where the skin there has no depth (a C7 at the back's top edge), the midline's.
    const double here = scale ? scale(toImage(l, midlineAt(l, g.body.y))) : kNaN;
    const double mpp = std::isfinite(here) && here > 0.0 ? here : midline_mpp;
    const bool metric = std::isfinite(cun_m) && std::isfinite(mpp) && mpp > 0.0;
    // Without a scale the cun in pixels as cunMetres takes it: from C7 -> L4 with both given, else the shoulders.
    const double cun_px = metric ? cun_m / mpp
                          : l.c7.given() && l.l4.given()
                              ? model.cun_per_shoulder_width / model.length_per_shoulder_width *
                                    (static_cast<double>(l.l4.body.y) - l.c7.body.y)
                              : model.cun_per_shoulder_width * l.shoulder_width;
    if (!(cun_px > 0.0) || std::abs(g.off_midline) <= limit * cun_px) continue;
    c->problems.push_back("the given " + g.level + " (" + givenHowName(g.source) + ") lies " +
                          across(g.off_midline, cun_px, metric ? mpp : kNaN) + " to the subject's " +
                          (g.off_midline > 0.0 ? "right" : "left") + " of the back's midline (a spine lies within " +
                          fixed(limit, 1) + " cun of it): not on the spine");
  }
}

/// Each given landmark the pair also measured: within given_disagreement_sigmas of both sigmas along the body, or
/// confirmed.
void checkGivenAgainstMeasured(LayoutCheck* c, const BackLandmarks& l, const AcupointModel& model, double mpp) {
  const double length_rows = static_cast<double>(l.l4.body.y) - l.c7.body.y;
  for (const BackLandmarks::GivenCheck& g : l.given_checks) {
    if (!std::isfinite(g.measured_row) || g.confirmed) continue;
    const double sigma =
        std::hypot(layoutSigma(model, g.level, LandmarkSource::kMeasured), layoutSigma(model, g.level, g.source));
    const double apart = std::abs(g.body.y - g.measured_row) / length_rows;
    if (apart <= model.plausibility.given_disagreement_sigmas * sigma) continue;
    const cv::Point2f given = toImage(l, g.body), measured = toImage(l, midlineAt(l, g.measured_row));
    const std::string distance =
        std::isfinite(mpp) ? fixed(apart * length_rows * mpp * 1000.0, 0) + " mm" : fixed(apart, 2) + " of C7 -> L4";
    c->problems.push_back("the given " + g.level + " (" + givenHowName(g.source) + ") at pixel (" + fixed(given.x, 0) +
                          ", " + fixed(given.y, 0) + ") and " + g.level + " measured at " + g.measured_from + " at (" +
                          fixed(measured.x, 0) + ", " + fixed(measured.y, 0) + ") lie " + distance +
                          " apart along the body (more than " + fixed(model.plausibility.given_disagreement_sigmas, 1) +
                          " sigma of both): confirm the given one");
  }
}

}  // namespace

std::string LayoutCheck::reason() const {
  if (trusted) return {};
  std::string s = "layout not trusted: ";
  for (std::size_t i = 0; i < problems.size(); ++i) s += (i ? "; " : "") + problems[i];
  return s;
}

LayoutCheck checkLayout(const BackLandmarks& l, const AcupointModel& model, const PixelScale& scale,
                        const TrustRules& rules) {
  LayoutCheck c;
  c.length_m = c.shoulder_width_m = c.length_per_shoulder_width = c.shoulder_below_c7 = kNaN;
  if (!l.valid || l.midline.empty()) {
    c.trusted = false;
    c.problems.push_back("no landmarks" + (l.reason.empty() ? std::string() : ": " + l.reason));
    return c;
  }
  if (!rules.configuration_problem.empty()) c.problems.push_back(rules.configuration_problem);
  const AcupointModel::Plausibility& pl = model.plausibility;
  const double length_rows = static_cast<double>(l.l4.body.y) - l.c7.body.y;
  if (!(length_rows > 0.0)) {
    c.trusted = false;
    c.problems.push_back("L4 is not below C7");
    return c;
  }
  if (rules.c7_at_neck && !l.c7.given() && !l.c7.atNeckBase())
    c.problems.push_back(std::string("C7 not measured: ") +
                         (l.c7.source == LandmarkSource::kMeasured
                              ? "no neck's base in view, the back's top taken for it"
                              : "taken from the shoulder line") +
                         "; give C7 (a palpated landmark: a click, ~set_landmark, --landmark, a skin marker)");
  if (rules.l4_measured && l.l4.source == LandmarkSource::kInferred)
    c.problems.push_back(
        "L4 not measured: no waist in view, only inferred from C7 and the shoulder width; give L4 (the iliac crests' "
        "line: a click, ~set_landmark, --landmark, a skin marker)");
  const bool both_given = l.c7.given() && l.l4.given();
  // Sizes, where the back's 3D gives a scale.
  const double mpp = midlineMetresPerPixel(l, scale);
  c.length_m = lengthMetres(l, mpp);
  const double shoulder_mpp = scale ? scale(toImage(l, midlineAt(l, l.shoulder_row, Beyond::kClamp))) : kNaN;
  c.shoulder_width_m = l.shoulder_width * (std::isfinite(shoulder_mpp) && shoulder_mpp > 0.0 ? shoulder_mpp : mpp);
  within(&c, c.length_m, pl.min_length_m, pl.max_length_m, "C7 -> L4", " m", 3);
  // With the back's 3D a size that cannot be measured is no size that passed: too few of the midline's points have
  // a depth (a back found in part, its 3D lost).
  if (scale && !std::isfinite(c.length_m))
    c.problems.push_back("C7 -> L4 not measured: too few points of the midline between them have a depth");
  if (std::isfinite(rules.client_length_m) && std::isfinite(c.length_m) &&
      std::abs(c.length_m - rules.client_length_m) > rules.length_tolerance_m)
    c.problems.push_back("C7 -> L4 " + fixed(c.length_m, 3) + " m, the client's profile says " +
                         fixed(rules.client_length_m, 3) + " m (more than " + fixed(rules.length_tolerance_m, 3) +
                         " m apart: a landmark palpated a vertebra off, or another client)");
  if (!both_given)
    within(&c, c.shoulder_width_m, pl.min_shoulder_width_m, pl.max_shoulder_width_m, "the shoulder width", " m", 3);
  // Proportions, where they are not the model's own.
  const bool l4_independent = l.l4.source != LandmarkSource::kInferred && !both_given;
  if (l4_independent && l.shoulder_width > 0.0) {
    c.length_per_shoulder_width = length_rows / l.shoulder_width;
    const double expected = model.length_per_shoulder_width, tol = pl.proportion_tolerance * expected;
    within(&c, c.length_per_shoulder_width, expected - tol, expected + tol, "C7 -> L4 over the shoulder width", "", 2);
  }
  for (const BackLandmarks::GivenCheck& g : l.given_checks) {
    if (!g.stale.empty())
      c.problems.push_back("the given " + g.level + " (" + givenHowName(g.source) + ") is stale: " + g.stale +
                           "; confirm the landmarks again (~confirm_landmarks, a click, ~set_landmark)");
  }
  checkGivenLevels(&c, l, model);
  checkGivenOnSpine(&c, l, model, scale, mpp);
  checkGivenAgainstMeasured(&c, l, model, mpp);
  const bool c7_independent = l.c7.source != LandmarkSource::kInferred && !both_given;
  if (c7_independent) {
    c.shoulder_below_c7 = (l.shoulder_row - l.c7.body.y) / length_rows;
    within(&c, c.shoulder_below_c7, pl.min_shoulder_below_c7, pl.max_shoulder_below_c7,
           "the shoulder line below C7 (of C7 -> L4)", "", 2);
  }
  c.trusted = c.problems.empty();
  return c;
}

}  // namespace massage_cell::cect
