// Given landmarks put into the layout (see given_landmarks.h).
#include "massage_cell/cect/given_landmarks.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>

#include <opencv2/imgproc.hpp>

namespace massage_cell::cect {

namespace {

std::string pixelText(const cv::Point2f& p) {
  std::ostringstream s;
  s.precision(1);
  s << std::fixed << "(" << p.x << ", " << p.y << ")";
  return s.str();
}

/// The midline's x at row y of the body frame (linear between its points, constant beyond its ends).
double midlineX(const BackLandmarks& l, double y) {
  const auto& m = l.midline;
  const double t = std::clamp(y - m.front().y, 0.0, static_cast<double>(m.size() - 1));
  const std::size_t i = std::min(static_cast<std::size_t>(t), m.size() - 1);
  if (i + 1 >= m.size()) return m[i].x;
  return m[i].x + (t - static_cast<double>(i)) * (m[i + 1].x - m[i].x);
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
  const float top_shift = top.x - static_cast<float>(midlineX(l, top.y));
  const float bottom_shift = bottom.x - static_cast<float>(midlineX(l, bottom.y));
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

std::string applyGivenLandmarks(BackLandmarks* landmarks, const std::vector<GivenLandmark>& given) {
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
    const cv::Point2f p(
        static_cast<float>(from_image(0, 0) * g.pixel.x + from_image(0, 1) * g.pixel.y + from_image(0, 2)),
        static_cast<float>(from_image(1, 0) * g.pixel.x + from_image(1, 1) * g.pixel.y + from_image(1, 2)));
    const double reach = kMaxBeyondMidline * std::abs(l.l4.y - l.c7.y);
    if (p.y < l.midline.front().y - reach || p.y > l.midline.back().y + reach)
      return "landmark " + g.name + " at " + pixelText(g.pixel) + " is not on the back's rows (the back spans rows " +
             pixelText(cv::Point2f(l.midline.front().y, l.midline.back().y)) + " of its frame)";
    body[g.name] = p;
    image[g.name] = g.pixel;
  }
  const auto c7 = body.find("C7"), t7 = body.find("T7"), l4 = body.find("L4");
  const float c7_row = c7 != body.end() ? c7->second.y : l.c7.y;
  const float l4_row = l4 != body.end() ? l4->second.y : l.l4.y;
  if (!(l4_row > c7_row)) return "landmark L4 is not below C7 (toward the feet)";
  if (t7 != body.end() && !(t7->second.y > c7_row && t7->second.y < l4_row))
    return "landmark T7 at " + pixelText(image.at("T7")) +
           " is not between C7 and L4 (toward the feet from C7, the head from L4)";
  for (const auto& [name, p] : body) extendMidline(&l, p.y);
  fitMidlineThrough(&l, body);
  auto onMidline = [&](float row) { return cv::Point2f(static_cast<float>(midlineX(l, row)), row); };
  l.c7 = onMidline(c7_row);
  l.l4 = onMidline(l4_row);
  l.iliac_row = l4_row;
  l.given_levels.clear();
  if (t7 != body.end()) l.given_levels.push_back({"T7", t7->second.y});
  l.along.clear();
  l.given.clear();
  for (const GivenLandmark& g : given) {
    if (g.name == "C7") l.c7_given = true;
    if (g.name == "L4") l.l4_given = true;
    l.given.push_back(g.name + (g.source.empty() ? std::string() : " (" + g.source + ")"));
  }
  return {};
}

std::string GivenLandmarkSet::set(const std::string& name, const cv::Point2f& raw_pixel, const std::string& source,
                                  cv::Size image_size) {
  if (const std::string problem = checkGivenLandmarkName(name); !problem.empty()) return problem;
  if (!std::isfinite(raw_pixel.x) || !std::isfinite(raw_pixel.y)) return "landmark " + name + ": pixel not finite";
  if (raw_pixel.x < -0.5f || raw_pixel.y < -0.5f || raw_pixel.x > image_size.width - 0.5f ||
      raw_pixel.y > image_size.height - 0.5f)
    return "landmark " + name + " at " + pixelText(raw_pixel) + " lies outside the " +
           std::to_string(image_size.width) + "x" + std::to_string(image_size.height) + " image";
  landmarks_[name] = GivenLandmark{name, raw_pixel, source};
  return {};
}

std::vector<GivenLandmark> GivenLandmarkSet::forPair(const camera::StereoModel& geometry,
                                                     const camera::Decimation& decimation) const {
  std::vector<GivenLandmark> out;
  for (const auto& [name, g] : landmarks_)
    out.push_back({name, geometry.toRectified(decimation.toDecimated(g.pixel)), g.source});
  return out;
}

std::string GivenLandmarkSet::describe() const {
  std::string s;
  for (const auto& [name, g] : landmarks_)
    s += (s.empty() ? "" : ", ") + name + (g.source.empty() ? "" : " (" + g.source + ")") + " at raw " +
         pixelText(g.pixel);
  return s.empty() ? "none" : s;
}

cv::Point2f cameraPixel(const cv::Point2f& rect_pixel, const camera::StereoModel& geometry,
                        const camera::Decimation& decimation) {
  return decimation.toFull(geometry.toRaw(rect_pixel));
}

std::string nearestGivenLandmark(const BackLandmarks& landmarks, const AcupointModel& model,
                                 const cv::Point2f& rect_pixel) {
  if (!landmarks.valid || landmarks.midline.empty()) return {};
  std::string best;
  double best_d = std::numeric_limits<double>::infinity();
  for (const std::string& name : givenLandmarkNames()) {
    if (!model.level_fraction.count(name)) continue;
    const cv::Point2f p = levelPixel(landmarks, model, name);
    const double d = std::hypot(p.x - rect_pixel.x, p.y - rect_pixel.y);
    if (d < best_d) {
      best_d = d;
      best = name;
    }
  }
  return best;
}

}  // namespace massage_cell::cect
