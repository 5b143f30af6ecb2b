// Given landmarks put into the layout (see given_landmarks.h).
#include "massage_cell/cect/given_landmarks.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <map>
#include <sstream>
#include <utility>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "acupoint_model_detail.h"
#include "stats_detail.h"

namespace massage_cell::cect {

namespace {

std::string pixelText(const cv::Point2f& p) {
  std::ostringstream s;
  s.precision(1);
  s << std::fixed << "(" << p.x << ", " << p.y << ")";
  return s.str();
}

/// A given landmark may lie this far (a fraction of C7 -> L4) beyond the found midline's ends: the silhouette's top
/// is the neck's base seen from above, which a palpated C7 can lie just above; farther is not this back.
constexpr double kMaxBeyondMidline = 0.15;

/// The midline continued in a straight line (its end's direction, one point a row) to take in row `y`.
void extendMidline(BackLandmarks* landmarks, double y) {
  auto& m = landmarks->midline;
  auto& lat = landmarks->lateral;
  if (m.size() < 2 || lat.size() != m.size()) return;
  while (y < m.front().y) {
    const cv::Point2f step = m[0] - m[1];
    m.insert(m.begin(), m[0] + step);
    lat.insert(lat.begin(), lat.front());
  }
  while (y > m.back().y) {
    const cv::Point2f step = m[m.size() - 1] - m[m.size() - 2];
    m.push_back(m.back() + step);
    lat.push_back(lat.back());
  }
}

/// The midline moved across to pass through the given pixels (body frame, by name): with one, shifted by a constant;
/// with more, the straight lines through them in order between the first and the last (spinous processes fix the
/// spine line; the outline's centre between them leans with the arms, hands and towels), the lateral directions
/// perpendicular to each, and beyond them the silhouette's midline shifted to join it.
void fitMidlineThrough(BackLandmarks* landmarks, const std::map<std::string, cv::Point2f>& body) {
  BackLandmarks& l = *landmarks;
  std::vector<cv::Point2f> knots;
  for (const auto& [name, p] : body) knots.push_back(p);
  std::sort(knots.begin(), knots.end(), [](const cv::Point2f& a, const cv::Point2f& b) { return a.y < b.y; });
  const cv::Point2f top = knots.front(), bottom = knots.back();
  const float top_shift = top.x - midlineAt(l, top.y, Beyond::kClamp).x;
  const float bottom_shift = bottom.x - midlineAt(l, bottom.y, Beyond::kClamp).x;
  std::size_t k = 0;  // the segment knots[k] .. knots[k + 1] holding the row
  for (std::size_t i = 0; i < l.midline.size(); ++i) {
    cv::Point2f& m = l.midline[i];
    if (m.y <= top.y) {
      m.x += top_shift;
      continue;
    }
    if (m.y >= bottom.y) {
      m.x += bottom_shift;
      continue;
    }
    while (k + 2 < knots.size() && m.y > knots[k + 1].y) ++k;
    const cv::Point2f a = knots[k], b = knots[k + 1];
    const double lean = (b.x - a.x) / (b.y - a.y);  // px across per row
    m.x = static_cast<float>(a.x + lean * (m.y - a.y));
    if (i < l.lateral.size()) {
      // Perpendicular to the segment: the caudal tangent (lean, 1) turned toward the subject's left.
      const double norm = std::hypot(1.0, lean);
      l.lateral[i] = cv::Point2f(static_cast<float>(-1.0 / norm), static_cast<float>(lean / norm));
    }
  }
}

/// How far below the back's top (metres, toward the table) a skin point still counts as the top of the back's
/// cross-section: the paraspinal muscles either side of the spine, the spinous processes between them (their groove
/// ~1 cm deep), the neck at C7; the flanks, arms, a sheet or a towel lie lower.
constexpr double kTopBand = 0.03;

/// The spine's place across row `row` of the body frame from the back's 3D: the middle of its cross-section's top
/// (the skin within kTopBand of its highest point, over three rows 6 px apart, its 5th to 95th percentile across),
/// which a sheet, an arm or a towel taken for the back does not move as they move the silhouette's centre. NaN with
/// fewer than 8 points there.
double spineAcross(const BackLandmarks& l, double row, const PointLookup& point) {
  if (!point) return kNaN;
  const double half = std::max(60.0, l.shoulder_width);
  const double centre = midlineAt(l, row, Beyond::kClamp).x;
  std::vector<std::pair<double, double>> samples;  // (x across, depth z)
  for (const double dy : {-6.0, 0.0, 6.0}) {
    for (int k = -25; k <= 25; ++k) {
      const double x = centre + half * k / 25.0;
      cv::Point3d p;
      if (point(toImage(l, cv::Point2f(static_cast<float>(x), static_cast<float>(row + dy))), &p) && std::isfinite(p.z))
        samples.push_back({x, p.z});
    }
  }
  if (samples.size() < 8) return kNaN;
  std::vector<double> z;
  for (const auto& s : samples) z.push_back(s.second);
  std::sort(z.begin(), z.end());
  const double top = z[z.size() / 10];  // the 10th percentile: a stray near point is not the top
  std::vector<double> xs;
  for (const auto& s : samples)
    if (s.second <= top + kTopBand) xs.push_back(s.first);
  if (xs.size() < 8) return kNaN;
  std::sort(xs.begin(), xs.end());
  return 0.5 * (xs[xs.size() / 20] + xs[xs.size() - 1 - xs.size() / 20]);
}

/// The spine line as the pair's 3D shows it: spineAcross at 15 rows from 15 % to 85 % of C7 -> L4 (`c7_row`,
/// `l4_row`), a straight line x = a + b y fitted to them (Huber), so that a row disturbed by an arm, a sheet or the
/// image's edge does not move it; false with fewer than 6 rows measured.
bool spineLine(const BackLandmarks& l, double c7_row, double l4_row, const PointLookup& point, double* a, double* b) {
  std::vector<cv::Point2d> across;
  for (int k = 0; k <= 14; ++k) {
    const double row = c7_row + (0.15 + 0.05 * k) * (l4_row - c7_row);
    const double x = spineAcross(l, row, point);
    if (std::isfinite(x)) across.emplace_back(x, row);
  }
  if (across.size() < 6) return false;
  Eigen::MatrixXd A(static_cast<Eigen::Index>(across.size()), 2), B(A.rows(), 1);
  for (Eigen::Index i = 0; i < A.rows(); ++i) {
    A.row(i) << 1.0, across[static_cast<std::size_t>(i)].y;
    B(i, 0) = across[static_cast<std::size_t>(i)].x;
  }
  auto huber = [](double r, double median) { return huberWeight(r, 1.5 * std::max(0.5, 1.4826 * median)); };
  Eigen::Vector2d c;
  if (!robustFit(A, B, 5, huber, &c)) return false;
  *a = c(0);
  *b = c(1);
  return true;
}

/// Each given landmark against the back as the pair measured it (`l` before the given ones are applied; `body`: the
/// given pixels in the body's frame, by name).
std::vector<BackLandmarks::GivenCheck> givenChecks(const BackLandmarks& l, const std::vector<GivenLandmark>& given,
                                                   const std::map<std::string, cv::Point2f>& body,
                                                   const PointLookup& point) {
  const double c7_row = body.count("C7") ? body.at("C7").y : l.c7.body.y;
  const double l4_row = body.count("L4") ? body.at("L4").y : l.l4.body.y;
  double a = 0.0, b = 0.0;
  const bool line = spineLine(l, c7_row, l4_row, point, &a, &b);
  std::vector<BackLandmarks::GivenCheck> checks;
  for (const GivenLandmark& g : given) {
    BackLandmarks::GivenCheck c;
    c.level = g.name;
    c.source = g.source;
    c.body = body.at(g.name);
    c.off_midline = c.body.x - (line ? a + b * c.body.y : midlineAt(l, c.body.y, Beyond::kClamp).x);
    c.confirmed = g.confirmed;
    c.stale = g.stale;
    if (g.name == "C7" && l.c7.atNeckBase()) {
      c.measured_row = l.c7.body.y;
      c.measured_from = kFromNeckBase;
    } else if (g.name == "L4" && l.l4.source == LandmarkSource::kMeasured) {  // measured: at the waist
      c.measured_row = l.l4.body.y;
      c.measured_from = kFromWaist;
    }
    checks.push_back(c);
  }
  return checks;
}

}  // namespace

const std::vector<std::string>& givenLandmarkNames() {
  static const std::vector<std::string> names{"C7", "T7", "L4"};
  return names;
}

std::string checkGivenLandmarkName(const std::string& name) {
  const auto& names = givenLandmarkNames();
  if (std::find(names.begin(), names.end(), name) != names.end()) return {};
  std::string known;
  for (const std::string& n : names) known += (known.empty() ? "" : ", ") + n;
  return "unknown landmark '" + name + "' (one of: " + known + ")";
}

std::string applyGivenLandmarks(BackLandmarks* landmarks, const std::vector<GivenLandmark>& given,
                                const PointLookup& point) {
  BackLandmarks& l = *landmarks;
  if (given.empty()) return {};
  if (!l.valid || l.midline.size() < 2) return "no landmarks of the back to put the given ones into";
  cv::Matx23d from_image;
  cv::invertAffineTransform(l.to_image, from_image);
  std::map<std::string, cv::Point2f> body, image;  // the given pixels in the body's frame and the image, by name
  for (const GivenLandmark& g : given) {
    if (const std::string problem = checkGivenLandmarkName(g.name); !problem.empty()) return problem;
    if (body.count(g.name)) return "landmark " + g.name + " given twice";
    if (!std::isfinite(g.pixel.x) || !std::isfinite(g.pixel.y)) return "landmark " + g.name + ": pixel not finite";
    if (!isGiven(g.source)) return "landmark " + g.name + ": its source is not a way to give one";
    const cv::Point2f p(
        static_cast<float>(from_image(0, 0) * g.pixel.x + from_image(0, 1) * g.pixel.y + from_image(0, 2)),
        static_cast<float>(from_image(1, 0) * g.pixel.x + from_image(1, 1) * g.pixel.y + from_image(1, 2)));
    const double reach = kMaxBeyondMidline * std::abs(l.l4.body.y - l.c7.body.y);
    if (p.y < l.midline.front().y - reach || p.y > l.midline.back().y + reach)
      return "landmark " + g.name + " at " + pixelText(g.pixel) + " is not on the back's rows (the back spans rows " +
             pixelText(cv::Point2f(l.midline.front().y, l.midline.back().y)) + " of its frame)";
    body[g.name] = p;
    image[g.name] = g.pixel;
  }
  const auto c7 = body.find("C7"), t7 = body.find("T7"), l4 = body.find("L4");
  const float c7_row = c7 != body.end() ? c7->second.y : l.c7.body.y;
  const float l4_row = l4 != body.end() ? l4->second.y : l.l4.body.y;
  if (!(l4_row > c7_row)) return "landmark L4 is not below C7 (toward the feet)";
  if (t7 != body.end() && !(t7->second.y > c7_row && t7->second.y < l4_row))
    return "landmark T7 at " + pixelText(image.at("T7")) +
           " is not between C7 and L4 (toward the feet from C7, the head from L4)";
  l.given_checks = givenChecks(l, given, body, point);
  for (const auto& [name, p] : body) extendMidline(&l, p.y);
  fitMidlineThrough(&l, body);
  auto onMidline = [&](float row) { return cv::Point2f(midlineAt(l, row, Beyond::kClamp).x, row); };
  l.c7.body = onMidline(c7_row);
  l.l4.body = onMidline(l4_row);
  l.iliac_row = l4_row;
  l.given_levels.clear();
  l.along.clear();
  l.given.clear();
  for (const GivenLandmark& g : given) {
    Landmark& m = g.name == "C7" ? l.c7 : g.name == "L4" ? l.l4 : l.given_levels.emplace_back();
    m.level = g.name;
    m.source = g.source;
    m.detail.clear();
    if (g.name != "C7" && g.name != "L4") m.body = onMidline(body.at(g.name).y);
    m.raw_pixel = g.raw_pixel;
    cv::Point3d p;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    m.point = point && point(toImage(l, m.body), &p) ? cv::Point3f(p) : cv::Point3f(nan, nan, nan);
    const std::string how = givenHowName(g.source);
    l.given.push_back(g.name + (how.empty() ? std::string() : " (" + how + ")"));
  }
  return {};
}

namespace {

/// What backMotion tracks: corners of the skin's texture inside the back (kept off its outline, which moves with the
/// arms, hair and towel rather than with the skin).
constexpr int kMaxFeatures = 400;
constexpr double kFeatureQuality = 0.005;
constexpr double kFeatureSpacing = 6.0;  // px
constexpr int kOutlineMargin = 7;        // px
/// Lucas-Kanade: a 21 px window over 5 pyramid levels follows a slide of ~15 cm at 640x480; a track counts when it
/// comes back within kRoundTrip px of where it started.
constexpr int kWindow = 21, kLevels = 4;
constexpr double kRoundTrip = 1.0;  // px
/// RANSAC's inlier distance, and how many tracks must agree (at least, and as a share of those tracked).
constexpr double kInlier = 1.5;  // px
constexpr int kMinAgreeing = 15;
constexpr double kMinAgreeingShare = 0.3;

cv::Mat grey(const cv::Mat& image) {
  cv::Mat g;
  if (image.channels() == 3)
    cv::cvtColor(image, g, cv::COLOR_BGR2GRAY);
  else
    g = image;
  return g;
}

/// A raw camera pixel carried by `motion` from the view `from` to the view `to`.
cv::Point2f carry(const cv::Point2f& raw, const BackMotion& motion, const BackView& from, const BackView& to) {
  const cv::Point2f rect = from.geometry.toRectified(from.decimation.toDecimated(raw));
  return to.decimation.toFull(to.geometry.toRaw(apply(motion.transform, rect)));
}

}  // namespace

BackView backView(const CectFrame& frame, const camera::Decimation& decimation) {
  BackView v;
  v.geometry = frame.geometry();
  v.decimation = decimation;
  const Segmentation& seg = frame.left();
  const cv::Moments mo = seg.valid ? cv::moments(seg.mask, true) : cv::Moments();
  if (!(mo.m00 > 0.0) || frame.leftRectified().empty()) {
    v.reason = seg.reason.empty() ? "no back in view" : seg.reason;
    return v;
  }
  v.grey = grey(frame.leftRectified()).clone();
  v.mask = seg.mask.clone();
  v.centre = cv::Point2f(static_cast<float>(mo.m10 / mo.m00), static_cast<float>(mo.m01 / mo.m00));
  // Metres per pixel at the centre: the median of the frame's scale over a 5 x 5 grid 8 px apart around it.
  const PixelScale scale = frameScale(frame);
  std::vector<double> near;
  for (int dy = -2; dy <= 2; ++dy)
    for (int dx = -2; dx <= 2; ++dx) near.push_back(scale(v.centre + cv::Point2f(8.0f * dx, 8.0f * dy)));
  v.metres_per_pixel = detail::median(near);
  v.valid = true;
  return v;
}

BackMotion backMotion(const BackView& from, const BackView& to) {
  BackMotion m;
  if (!from.valid || !to.valid) {
    m.reason = "the back is lost (" + (from.valid ? to.reason : from.reason) + ")";
    return m;
  }
  const cv::Mat &g0 = from.grey, &g1 = to.grey;
  if (g0.size() != g1.size()) {
    m.reason = "the images' size changed (the processing resolution)";
    return m;
  }
  // 1. Corners of the first back's skin, tracked there and back.
  cv::Mat inside;
  cv::erode(from.mask, inside,
            cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * kOutlineMargin + 1, 2 * kOutlineMargin + 1}));
  std::vector<cv::Point2f> p0, p1, back;
  cv::goodFeaturesToTrack(g0, p0, kMaxFeatures, kFeatureQuality, kFeatureSpacing, inside);
  if (static_cast<int>(p0.size()) < kMinAgreeing) {
    m.reason = "too little texture on the back to follow it (" + std::to_string(p0.size()) + " corners)";
    return m;
  }
  std::vector<unsigned char> there, again;
  std::vector<float> err;
  const cv::Size window(kWindow, kWindow);
  cv::calcOpticalFlowPyrLK(g0, g1, p0, p1, there, err, window, kLevels);
  cv::calcOpticalFlowPyrLK(g1, g0, p1, back, again, err, window, kLevels);
  std::vector<cv::Point2f> q0, q1;
  for (std::size_t i = 0; i < p0.size(); ++i)
    if (there[i] && again[i] && cv::norm(back[i] - p0[i]) <= kRoundTrip) {
      q0.push_back(p0[i]);
      q1.push_back(p1[i]);
    }
  m.tracks = static_cast<int>(q0.size());
  // 2. The similarity most tracks agree with.
  std::vector<unsigned char> inlier;
  const cv::Mat t = q0.size() >= 3 ? cv::estimateAffinePartial2D(q0, q1, inlier, cv::RANSAC, kInlier) : cv::Mat();
  m.agreeing = static_cast<int>(std::count(inlier.begin(), inlier.end(), 1));
  if (t.empty() || m.agreeing < std::max(kMinAgreeing, static_cast<int>(kMinAgreeingShare * p0.size()))) {
    m.reason = "cannot follow the back: " + std::to_string(m.agreeing) + " of " + std::to_string(p0.size()) +
               " corners move together";
    return m;
  }
  m.transform = cv::Matx23d(t);
  m.turn_deg = std::atan2(m.transform(1, 0), m.transform(0, 0)) * 180.0 / CV_PI;
  // 3. The back's centre carried, in metres at the skin there.
  m.move_m = cv::norm(apply(m.transform, from.centre) - from.centre) * from.metres_per_pixel;
  if (!std::isfinite(m.move_m)) {
    m.reason = "no depth at the back's centre to measure its move in metres";
    return m;
  }
  m.valid = true;
  return m;
}

std::string GivenLandmarkSet::set(const std::string& name, const cv::Point2f& raw_pixel, LandmarkSource source,
                                  cv::Size image_size, bool confirmed, const BackView& view) {
  if (const std::string problem = checkGivenLandmarkName(name); !problem.empty()) return problem;
  if (!std::isfinite(raw_pixel.x) || !std::isfinite(raw_pixel.y)) return "landmark " + name + ": pixel not finite";
  if (raw_pixel.x < -0.5f || raw_pixel.y < -0.5f || raw_pixel.x > image_size.width - 0.5f ||
      raw_pixel.y > image_size.height - 0.5f)
    return "landmark " + name + " at " + pixelText(raw_pixel) + " lies outside the " +
           std::to_string(image_size.width) + "x" + std::to_string(image_size.height) + " image";
  landmarks_[name] = Kept{GivenLandmark(name, raw_pixel, source, confirmed), raw_pixel, view};
  return {};
}

void GivenLandmarkSet::follow(const BackView& now, const FollowLimits& limits) {
  std::map<const uchar*, BackMotion> motions;  // one per view the landmarks were given on (its image)
  for (auto& [name, k] : landmarks_) {
    if (!k.anchor.valid && k.anchor.reason.empty()) continue;  // given without a back to follow (a tool's pair)
    auto it = motions.find(k.anchor.grey.data);
    if (it == motions.end()) it = motions.emplace(k.anchor.grey.data, backMotion(k.anchor, now)).first;
    const BackMotion& m = it->second;
    if (!m.valid) {
      k.given.stale = m.reason + " since it was given";
      continue;
    }
    // Carried with the back however far it moved (shown there, for a therapist to confirm) ...
    k.given.pixel = carry(k.anchor_pixel, m, k.anchor, now);
    k.given.stale.clear();
    // ... but beyond the limits the tracking may have slipped and the client may have moved under the skin: stale.
    if (m.move_m > limits.max_move_m || std::abs(m.turn_deg) > limits.max_turn_deg) {
      std::ostringstream why;
      why << std::fixed << std::setprecision(0) << "the back moved " << m.move_m * 1000.0 << " mm and turned "
          << std::setprecision(1) << m.turn_deg << " deg since it was given (more than " << std::setprecision(0)
          << limits.max_move_m * 1000.0 << " mm or " << limits.max_turn_deg << " deg)";
      k.given.stale = why.str();
    }
  }
}

std::string GivenLandmarkSet::confirm(const BackView& now) {
  if (!now.valid) return "no back in view to confirm the landmarks on: " + now.reason;
  for (auto& [name, k] : landmarks_) {
    k.anchor_pixel = k.given.pixel;
    k.anchor = now;
    k.given.stale.clear();
  }
  return {};
}

std::vector<GivenLandmark> GivenLandmarkSet::forPair(const camera::StereoModel& geometry,
                                                     const camera::Decimation& decimation) const {
  std::vector<GivenLandmark> out;
  for (const auto& [name, k] : landmarks_) {
    GivenLandmark g = k.given;
    g.raw_pixel = g.pixel;
    g.pixel = geometry.toRectified(decimation.toDecimated(g.pixel));
    out.push_back(g);
  }
  return out;
}

std::string GivenLandmarkSet::describe() const {
  std::string s;
  for (const auto& [name, k] : landmarks_) {
    const GivenLandmark& g = k.given;
    s += (s.empty() ? "" : ", ") + name + (givenHowName(g.source).empty() ? "" : " (" + givenHowName(g.source) + ")") +
         " at raw " + pixelText(g.pixel) + (g.confirmed ? " confirmed" : "") +
         (g.stale.empty() ? "" : " stale: " + g.stale);
  }
  return s.empty() ? "none" : s;
}

cv::Point2f cameraPixel(const cv::Point2f& rect_pixel, const camera::StereoModel& geometry,
                        const camera::Decimation& decimation) {
  return decimation.toFull(geometry.toRaw(rect_pixel));
}

ClickName nameClick(const BackLandmarks& landmarks, const AcupointModel& model, const cv::Point2f& rect_pixel) {
  if (!landmarks.valid || landmarks.midline.empty())
    return {"", "the latest pair has no layout to name the click by: name it (~set_landmark, or ~click_landmark)"};
  std::vector<std::pair<double, std::string>> by_distance;
  for (const std::string& name : givenLandmarkNames()) {
    if (!model.level_fraction.count(name)) continue;
    const cv::Point2f p = levelPixel(landmarks, model, name);
    by_distance.push_back({std::hypot(p.x - rect_pixel.x, p.y - rect_pixel.y), name});
  }
  if (by_distance.empty()) return {"", "the acupoint model has none of the landmarks' levels"};
  std::sort(by_distance.begin(), by_distance.end());
  if (by_distance.size() > 1 && by_distance[0].first > kClickNameRatio * by_distance[1].first) {
    std::ostringstream s;
    s.precision(0);
    s << std::fixed << "the click at " << pixelText(rect_pixel) << " is about as near " << by_distance[0].second << " ("
      << by_distance[0].first << " px) as " << by_distance[1].second << " (" << by_distance[1].first
      << " px): name it (~set_landmark, or ~click_landmark)";
    return {"", s.str()};
  }
  return {by_distance[0].second, ""};
}

}  // namespace massage_cell::cect
