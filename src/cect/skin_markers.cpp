// Coloured skin markers found in a rectified stereo pair (see skin_markers.h): the kit's checks and its YAML file,
// then per sticker a colour mask (HSV in degrees from the float image), opened and split into blobs, the round ones
// of a dot's size kept; exactly one on the back in the left view, exactly one along its row in the right view.
#include "massage_cell/cect/skin_markers.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>
#include <opencv2/imgproc.hpp>

#include "massage_cell/cect/given_landmarks.h"

namespace massage_cell::cect {

namespace {

/// A blob is on the back when at least this fraction of the ring around it lies in the (dilated) back's mask.
constexpr double kMinRingOnBack = 0.5;
/// The ring's width, and the padding of a blob's crop (the weighted centroid takes in the anti-aliased rim too).
constexpr int kRingPx = 2;

// --- Text

/// `v` with at most one decimal, no trailing zero ("8", "8.5").
std::string num(double v) {
  std::ostringstream s;
  s.precision(1);
  s << std::fixed << v;
  std::string t = s.str();
  if (t.find('.') != std::string::npos) {
    while (t.back() == '0') t.pop_back();
    if (t.back() == '.') t.pop_back();
  }
  return t == "-0" ? "0" : t;
}

std::string pixelText(const cv::Point2f& p) {
  std::ostringstream s;
  s.precision(1);
  s << std::fixed << "(" << p.x << ", " << p.y << ")";
  return s.str();
}

/// The colour's everyday name of a hue (degrees).
std::string colourName(double hue) {
  static const std::vector<std::pair<double, const char*>> upper = {{15, "red"},     {45, "orange"},  {70, "yellow"},
                                                                    {165, "green"},  {195, "cyan"},   {255, "blue"},
                                                                    {290, "violet"}, {345, "magenta"}};
  for (const auto& [limit, name] : upper) {
    if (hue < limit) return name;
  }
  return "red";
}

/// "C7 (green dot)": how problems name a sticker.
std::string markerLabel(const SkinMarkerSpec& spec) {
  return spec.landmark + " (" + (spec.colour.empty() ? colourName(spec.hue_deg) : spec.colour) + " dot)";
}

/// |a - b| on the hue circle, degrees 0..180.
double hueDistance(double a, double b) {
  const double d = std::fmod(std::abs(a - b), 360.0);
  return std::min(d, 360.0 - d);
}

// --- The kit's checks

bool within(double v, double lo, double hi) { return std::isfinite(v) && v >= lo && v <= hi; }
bool positive(double v) { return std::isfinite(v) && v > 0.0; }

/// One sticker's problem, or an empty string.
std::string checkSpec(const SkinMarkerSpec& m, std::size_t index) {
  if (const std::string problem = checkGivenLandmarkName(m.landmark); !problem.empty())
    return "marker " + std::to_string(index + 1) + ": " + problem;
  const std::string at = m.landmark + ": ";
  if (!within(m.hue_deg, 0.0, 360.0)) return at + "hue_deg " + num(m.hue_deg) + " is not in 0..360";
  if (!(positive(m.hue_tolerance_deg) && m.hue_tolerance_deg < 90.0))
    return at + "hue_tolerance_deg " + num(m.hue_tolerance_deg) + " is not in (0, 90)";
  if (!within(m.min_saturation, 0.0, 1.0)) return at + "min_saturation " + num(m.min_saturation) + " is not in 0..1";
  if (!within(m.min_value, 0.0, 1.0)) return at + "min_value " + num(m.min_value) + " is not in 0..1";
  if (!positive(m.diameter_m)) return at + "diameter_m " + num(m.diameter_m) + " must be > 0";
  return {};
}

/// The stickers' problem (each, a landmark twice, overlapping hue ranges), or an empty string.
std::string checkKit(const std::vector<SkinMarkerSpec>& markers) {
  if (markers.empty()) return "no markers";
  std::set<std::string> seen;
  for (std::size_t i = 0; i < markers.size(); ++i) {
    if (const std::string problem = checkSpec(markers[i], i); !problem.empty()) return problem;
    if (!seen.insert(markers[i].landmark).second) return "landmark " + markers[i].landmark + " listed twice";
  }
  for (std::size_t i = 0; i < markers.size(); ++i) {
    for (std::size_t j = i + 1; j < markers.size(); ++j) {
      const SkinMarkerSpec &a = markers[i], &b = markers[j];
      if (hueDistance(a.hue_deg, b.hue_deg) <= a.hue_tolerance_deg + b.hue_tolerance_deg)
        return a.landmark + " and " + b.landmark + ": hue ranges overlap (" + num(a.hue_deg) + " +- " +
               num(a.hue_tolerance_deg) + " and " + num(b.hue_deg) + " +- " + num(b.hue_tolerance_deg) + " deg)";
    }
  }
  return {};
}

/// The search limits' problem, or an empty string.
std::string checkLimits(const SkinMarkerOptions& o) {
  if (!positive(o.min_diameter_px)) return "min_diameter_px " + num(o.min_diameter_px) + " must be > 0";
  if (!(std::isfinite(o.max_diameter_px) && o.max_diameter_px > o.min_diameter_px))
    return "min_diameter_px " + num(o.min_diameter_px) + " must be below max_diameter_px " + num(o.max_diameter_px);
  if (!(positive(o.min_fill) && o.min_fill <= 1.0)) return "min_fill " + num(o.min_fill) + " is not in (0, 1]";
  if (!positive(o.max_row_difference_px))
    return "max_row_difference_px " + num(o.max_row_difference_px) + " must be > 0";
  if (!within(o.max_area_ratio, 1.0, 1e9)) return "max_area_ratio " + num(o.max_area_ratio) + " must be >= 1";
  if (!within(o.mask_margin_px, 0.0, 1e4)) return "mask_margin_px " + num(o.mask_margin_px) + " must be >= 0";
  if (!(within(o.max_size_ratio, 1.0, 1e9) && o.max_size_ratio > 1.0))
    return "max_size_ratio " + num(o.max_size_ratio) + " must be > 1";
  return {};
}

// --- YAML: errors name the key.

template <typename T>
T as(const YAML::Node& value, const std::string& key, const std::string& where) {
  try {
    return value.as<T>();
  } catch (const YAML::Exception&) {
    throw std::runtime_error(where + ": key '" + key + "' has the wrong type");
  }
}

std::string keyList(const std::map<std::string, double*>& fields, const std::string& also) {
  std::string known = also;
  for (const auto& [name, ptr] : fields) known += (known.empty() ? "" : ", ") + name;
  return known;
}

SkinMarkerSpec readSpec(const YAML::Node& node, const std::string& at) {
  if (!node.IsMap()) throw std::runtime_error(at + ": expected a mapping");
  SkinMarkerSpec s;
  const std::map<std::string, double*> fields{{"hue_deg", &s.hue_deg},
                                              {"hue_tolerance_deg", &s.hue_tolerance_deg},
                                              {"min_saturation", &s.min_saturation},
                                              {"min_value", &s.min_value},
                                              {"diameter_m", &s.diameter_m}};
  bool has_landmark = false, has_hue = false;
  for (const auto& kv : node) {
    const std::string key = kv.first.as<std::string>();
    if (key == "landmark") {
      s.landmark = as<std::string>(kv.second, key, at);
      has_landmark = true;
      continue;
    }
    if (key == "colour") {
      s.colour = as<std::string>(kv.second, key, at);
      continue;
    }
    if (key == "optional") {
      s.optional = as<bool>(kv.second, key, at);
      continue;
    }
    const auto field = fields.find(key);
    if (field == fields.end())
      throw std::runtime_error(at + ": unknown key '" + key + "' (" + keyList(fields, "landmark, colour, optional") +
                               ")");
    *field->second = as<double>(kv.second, key, at);
    has_hue = has_hue || key == "hue_deg";
  }
  if (!has_landmark) throw std::runtime_error(at + ": missing key 'landmark'");
  if (!has_hue) throw std::runtime_error(at + ": missing key 'hue_deg'");
  return s;
}

SkinMarkerOptions skinMarkerOptions(const std::string& path) {
  const std::string where = "skin markers '" + path + "'";
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw std::runtime_error(where + ": cannot open the file");
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(where + ": not valid YAML: " + e.what());
  }
  if (!root.IsMap()) throw std::runtime_error(where + ": expected a mapping at the top level");
  SkinMarkerOptions o;
  const std::map<std::string, double*> fields{{"min_diameter_px", &o.min_diameter_px},
                                              {"max_diameter_px", &o.max_diameter_px},
                                              {"min_fill", &o.min_fill},
                                              {"max_row_difference_px", &o.max_row_difference_px},
                                              {"max_area_ratio", &o.max_area_ratio},
                                              {"mask_margin_px", &o.mask_margin_px},
                                              {"max_size_ratio", &o.max_size_ratio}};
  for (const auto& kv : root) {
    const std::string key = kv.first.as<std::string>();
    if (key == "markers") continue;
    const auto field = fields.find(key);
    if (field == fields.end())
      throw std::runtime_error(where + ": unknown key '" + key + "' (" + keyList(fields, "markers") + ")");
    *field->second = as<double>(kv.second, key, where);
  }
  const YAML::Node markers = root["markers"];
  if (!markers || !markers.IsSequence()) throw std::runtime_error(where + ": missing sequence 'markers'");
  for (std::size_t i = 0; i < markers.size(); ++i)
    o.markers.push_back(readSpec(markers[i], where + ", markers[" + std::to_string(i) + "]"));
  if (const std::string problem = checkSkinMarkerOptions(o); !problem.empty())
    throw std::runtime_error(where + ": " + problem);
  return o;
}

// --- Colour

/// HSV of a BGR image: hue in degrees 0..360, saturation and value 0..1.
cv::Mat3f toHsv(const cv::Mat& bgr) {
  cv::Mat scaled, hsv;
  bgr.convertTo(scaled, CV_32F, 1.0 / 255.0);
  cv::cvtColor(scaled, hsv, cv::COLOR_BGR2HSV);
  return hsv;
}

/// A sticker's pixels: `binary` within all three thresholds (then opened), `membership` a soft 0..1 version (1 well
/// inside them, 0.5 at about a threshold, 0 well outside) that weighs the centroid.
struct ColourMask {
  cv::Mat1b binary;
  cv::Mat1f membership;
};

double ramp(double x) { return std::clamp(x, 0.0, 1.0); }

ColourMask colourMask(const cv::Mat3f& hsv, const SkinMarkerSpec& spec) {
  ColourMask c{cv::Mat1b(hsv.size()), cv::Mat1f(hsv.size())};
  const double tol = spec.hue_tolerance_deg;
  const double s_soft = std::max(spec.min_saturation, 0.05), v_soft = std::max(spec.min_value, 0.02);
  for (int y = 0; y < hsv.rows; ++y) {
    const cv::Vec3f* p = hsv.ptr<cv::Vec3f>(y);
    std::uint8_t* b = c.binary.ptr<std::uint8_t>(y);
    float* m = c.membership.ptr<float>(y);
    for (int x = 0; x < hsv.cols; ++x) {
      const double d = hueDistance(p[x][0], spec.hue_deg), s = p[x][1], v = p[x][2];
      b[x] = d <= tol && s >= spec.min_saturation && v >= spec.min_value ? 255 : 0;
      m[x] = static_cast<float>(ramp((1.5 * tol - d) / tol) * ramp((s - 0.5 * spec.min_saturation) / s_soft) *
                                ramp((v - 0.5 * spec.min_value) / v_soft));
    }
  }
  // Isolated pixels and one-pixel lines (noise, the blended rims between other colours) are no dot.
  cv::morphologyEx(c.binary, c.binary, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_CROSS, {3, 3}));
  return c;
}

/// The back's mask dilated by `margin` px (empty: the whole image).
cv::Mat1b dilatedMask(const cv::Mat& mask, double margin) {
  if (mask.empty()) return {};
  cv::Mat1b out = mask != 0;
  const int r = static_cast<int>(std::lround(margin));
  if (r > 0) cv::dilate(out, out, cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * r + 1, 2 * r + 1}));
  return out;
}

// --- Blobs

struct Blob {
  cv::Point2f centre;    ///< membership-weighted centroid
  double area = 0;       ///< pixels, holes filled
  double diameter = 0;   ///< equivalent diameter
  double fill = 0;       ///< area / its minimum enclosing circle's
  double on_back = 1.0;  ///< fraction of the ring around it in the dilated mask
};

/// The blobs of a colour that are round and of a dot's size, and how many were not.
struct BlobList {
  std::vector<Blob> kept;
  int too_small = 0, too_large = 0, not_round = 0;
};

/// The membership-weighted centroid over the blob grown by the ring (its anti-aliased rim), and the fraction of the
/// ring in `back`; `filled` is the blob in `crop` of the image.
void weighBlob(const cv::Mat1b& filled, const cv::Rect& crop, const ColourMask& colour, const cv::Mat1b& back,
               Blob* b) {
  cv::Mat1b grown;
  cv::dilate(filled, grown, cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * kRingPx + 1, 2 * kRingPx + 1}));
  double sum = 0, sx = 0, sy = 0, n = 0, nx = 0, ny = 0;
  int ring = 0, ring_on_back = 0;
  for (int y = 0; y < grown.rows; ++y) {
    for (int x = 0; x < grown.cols; ++x) {
      if (!grown(y, x)) continue;
      const double w = colour.membership(crop.y + y, crop.x + x);
      sum += w, sx += w * (crop.x + x), sy += w * (crop.y + y);
      if (filled(y, x)) {
        n += 1, nx += crop.x + x, ny += crop.y + y;
        continue;
      }
      ++ring;
      if (back.empty() || back(crop.y + y, crop.x + x)) ++ring_on_back;
    }
  }
  // A pixel of the binary mask weighs at least 1/8 unless a minimum is 0 (then grey or black pixels weigh nothing).
  b->centre = sum > 0 ? cv::Point2f(static_cast<float>(sx / sum), static_cast<float>(sy / sum))
                      : cv::Point2f(static_cast<float>(nx / n), static_cast<float>(ny / n));
  b->on_back = ring > 0 ? static_cast<double>(ring_on_back) / ring : 1.0;
}

/// Area, fill, centre and ring of component `label` (bounding box `box`) of `labels`.
Blob measureBlob(const cv::Mat1i& labels, int label, const cv::Rect& box, const ColourMask& colour,
                 const cv::Mat1b& back) {
  const cv::Rect crop = (box + cv::Size(2 * kRingPx, 2 * kRingPx) - cv::Point(kRingPx, kRingPx)) &
                        cv::Rect(0, 0, labels.cols, labels.rows);
  const cv::Mat1b own = labels(crop) == label;
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(own.clone(), contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  cv::Mat1b filled = cv::Mat1b::zeros(own.size());
  cv::drawContours(filled, contours, -1, 255, cv::FILLED);  // holes filled: a glossy dot's highlight is the dot
  std::vector<cv::Point> boundary;
  for (const auto& c : contours) boundary.insert(boundary.end(), c.begin(), c.end());
  cv::Point2f circle_centre;
  float radius = 0;
  cv::minEnclosingCircle(boundary, circle_centre, radius);
  Blob b;
  b.area = cv::countNonZero(filled);
  b.diameter = 2.0 * std::sqrt(b.area / CV_PI);
  b.fill = b.area / (CV_PI * (radius + 0.5) * (radius + 0.5));  // + 0.5: pixels, not their centres
  weighBlob(filled, crop, colour, back, &b);
  return b;
}

/// The colour's components within the diameter and fill limits (`back`: measures each one's ring in it).
BlobList findBlobs(const ColourMask& colour, const SkinMarkerOptions& o, const cv::Mat1b& back) {
  cv::Mat1i labels;
  cv::Mat stats, centroids;
  const int n = cv::connectedComponentsWithStats(colour.binary, labels, stats, centroids, 8, CV_32S);
  BlobList out;
  for (int label = 1; label < n; ++label) {
    const cv::Rect box(stats.at<int>(label, cv::CC_STAT_LEFT), stats.at<int>(label, cv::CC_STAT_TOP),
                       stats.at<int>(label, cv::CC_STAT_WIDTH), stats.at<int>(label, cv::CC_STAT_HEIGHT));
    // Wider than twice the largest dot: too large or not round either way (a sheet, a gown), not worth measuring.
    if (std::max(box.width, box.height) > 2.0 * o.max_diameter_px + 2.0) {
      ++out.too_large;
      continue;
    }
    const Blob b = measureBlob(labels, label, box, colour, back);
    if (b.diameter < o.min_diameter_px)
      ++out.too_small;
    else if (b.diameter > o.max_diameter_px)
      ++out.too_large;
    else if (b.fill < o.min_fill)
      ++out.not_round;
    else
      out.kept.push_back(b);
  }
  return out;
}

/// " (refused: 1 too small, 2 off the back)", or nothing when none was.
std::string refusals(const std::vector<std::pair<int, std::string>>& counts) {
  std::string text;
  for (const auto& [n, why] : counts) {
    if (n > 0) text += (text.empty() ? "" : ", ") + std::to_string(n) + " " + why;
  }
  return text.empty() ? text : " (refused: " + text + ")";
}

std::string positions(const std::vector<Blob>& blobs) {
  std::string text;
  for (const Blob& b : blobs) text += (text.empty() ? "" : ", ") + pixelText(b.centre);
  return text;
}

// --- Matching

/// The one left-view candidate on the back (and of the printed size when the scale is known); else the problem.
std::optional<Blob> pickLeft(const SkinMarkerSpec& spec, const BlobList& blobs, const SkinMarkerOptions& o,
                             const SkinMarkerScale& scale, std::string* problem, bool* none_on_back) {
  std::vector<Blob> candidates;
  int off_back = 0, wrong_size = 0;
  for (const Blob& b : blobs.kept) {
    if (b.on_back < kMinRingOnBack) {
      ++off_back;
      continue;
    }
    const double metres_per_px = scale ? scale(b.centre) : 0.0;
    if (positive(metres_per_px)) {
      const double ratio = b.diameter / (spec.diameter_m / metres_per_px);
      if (!(ratio <= o.max_size_ratio && ratio >= 1.0 / o.max_size_ratio)) {
        ++wrong_size;
        continue;
      }
    }
    candidates.push_back(b);
  }
  if (candidates.size() == 1) return candidates.front();
  *none_on_back = candidates.empty();
  if (candidates.empty()) {
    *problem =
        "not found in the left view" + refusals({{blobs.too_small, "too small"},
                                                 {blobs.too_large, "too large"},
                                                 {blobs.not_round, "not round"},
                                                 {off_back, "off the back"},
                                                 {wrong_size, "not " + num(spec.diameter_m * 1000.0) + " mm across"}});
  } else {
    *problem = std::to_string(candidates.size()) + " candidates in the left view, none taken (at " +
               positions(candidates) + ")";
  }
  return std::nullopt;
}

/// The one right-view blob on the left one's rows, within the disparities and the area ratio; else the problem.
std::optional<Blob> pickRight(const Blob& left, const BlobList& blobs, cv::Vec2d range, const SkinMarkerOptions& o,
                              std::string* problem) {
  std::vector<Blob> matches;
  int area_refused = 0;
  for (const Blob& b : blobs.kept) {
    const double d = left.centre.x - b.centre.x;
    if (std::abs(b.centre.y - left.centre.y) > o.max_row_difference_px || d < range[0] || d > range[1]) continue;
    if (std::max(b.area, left.area) > o.max_area_ratio * std::min(b.area, left.area)) {
      ++area_refused;
      continue;
    }
    matches.push_back(b);
  }
  if (matches.size() == 1) return matches.front();
  const std::string where = " in the right view on rows " +
                            std::to_string(std::lround(left.centre.y - o.max_row_difference_px)) + ".." +
                            std::to_string(std::lround(left.centre.y + o.max_row_difference_px)) + " with disparity " +
                            num(range[0]) + ".." + num(range[1]);
  if (matches.empty())
    *problem = "no match" + where + refusals({{area_refused, "by the area ratio, limit " + num(o.max_area_ratio)}});
  else
    *problem = std::to_string(matches.size()) + " matches" + where + ", none taken (at " + positions(matches) + ")";
  return std::nullopt;
}

void checkInputs(const cv::Mat& left, const cv::Mat& right, const cv::Mat& mask, cv::Vec2d range,
                 const SkinMarkerOptions& options) {
  const std::string where = "detectSkinMarkers: ";
  if (left.empty() || left.type() != CV_8UC3 || right.type() != CV_8UC3)
    throw std::invalid_argument(where + "the images must be non-empty BGR CV_8UC3");
  if (left.size() != right.size()) throw std::invalid_argument(where + "the left and right images differ in size");
  if (!mask.empty() && (mask.type() != CV_8UC1 || mask.size() != left.size()))
    throw std::invalid_argument(where + "the mask must be empty or CV_8UC1 of the images' size");
  if (!(std::isfinite(range[0]) && std::isfinite(range[1]) && range[0] <= range[1]))
    throw std::invalid_argument(where + "the disparity range " + num(range[0]) + ".." + num(range[1]) +
                                " is not finite with min <= max");
  if (const std::string problem = checkSkinMarkerOptions(options); !problem.empty())
    throw std::invalid_argument(where + problem);
}

}  // namespace

std::string SkinMarkers::describe() const {
  std::string text;
  for (const SkinMarkerDetection& d : found) {
    std::ostringstream s;
    s.precision(1);
    s << std::fixed << d.landmark << " at " << pixelText(d.left) << " d " << d.disparity;
    text += (text.empty() ? "" : "; ") + s.str();
  }
  for (const std::string& p : problems) text += (text.empty() ? "" : "; ") + p;
  if (!absent.empty()) {
    std::string names;
    for (const std::string& a : absent) names += (names.empty() ? "" : ", ") + a;
    text += (text.empty() ? "" : "; ") + names + ": optional, not on the back";
  }
  return text.empty() ? "no markers" : text;
}

std::string checkSkinMarkerOptions(const SkinMarkerOptions& options) {
  if (const std::string problem = checkKit(options.markers); !problem.empty()) return problem;
  return checkLimits(options);
}

// A yaml-cpp error the field readers did not name still names the file and its line.
SkinMarkerOptions loadSkinMarkerOptions(const std::string& path) {
  try {
    return skinMarkerOptions(path);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error("skin markers '" + path + "': " + e.what());
  }
}

cv::Mat skinMarkerPixels(const cv::Mat& bgr, const SkinMarkerOptions& options) {
  if (bgr.empty() || bgr.type() != CV_8UC3) throw std::invalid_argument("skinMarkerPixels: expected a CV_8UC3 image");
  if (const std::string problem = checkSkinMarkerOptions(options); !problem.empty())
    throw std::invalid_argument("skinMarkerPixels: " + problem);
  const cv::Mat3f hsv = toHsv(bgr);
  cv::Mat1b out = cv::Mat1b::zeros(bgr.size());
  const double min_area = 0.25 * CV_PI * options.min_diameter_px * options.min_diameter_px;
  for (const SkinMarkerSpec& spec : options.markers) {
    const ColourMask colour = colourMask(hsv, spec);
    cv::Mat1i labels;
    cv::Mat stats, centroids;
    const int n = cv::connectedComponentsWithStats(colour.binary, labels, stats, centroids, 8, CV_32S);
    std::vector<std::uint8_t> dot(static_cast<std::size_t>(n), 0);
    for (int label = 1; label < n; ++label) {
      const int side = std::max(stats.at<int>(label, cv::CC_STAT_WIDTH), stats.at<int>(label, cv::CC_STAT_HEIGHT));
      dot[static_cast<std::size_t>(label)] =
          side <= options.max_diameter_px + 2.0 && stats.at<int>(label, cv::CC_STAT_AREA) >= min_area ? 255 : 0;
    }
    for (int y = 0; y < labels.rows; ++y) {
      const int* l = labels.ptr<int>(y);
      std::uint8_t* o = out.ptr<std::uint8_t>(y);
      for (int x = 0; x < labels.cols; ++x) o[x] = std::max(o[x], dot[static_cast<std::size_t>(l[x])]);
    }
  }
  cv::dilate(out, out, cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * kRingPx + 1, 2 * kRingPx + 1}));
  return out;
}

SkinMarkers detectSkinMarkers(const cv::Mat& left_bgr, const cv::Mat& right_bgr, const cv::Mat& left_mask,
                              cv::Vec2d disparity_range, const SkinMarkerOptions& options,
                              const SkinMarkerScale& metres_per_pixel) {
  checkInputs(left_bgr, right_bgr, left_mask, disparity_range, options);
  const cv::Mat3f hsv_left = toHsv(left_bgr), hsv_right = toHsv(right_bgr);
  const cv::Mat1b back = dilatedMask(left_mask, options.mask_margin_px);
  SkinMarkers out;
  for (const SkinMarkerSpec& spec : options.markers) {
    std::string problem;
    bool none_on_back = false;
    const std::optional<Blob> left = pickLeft(spec, findBlobs(colourMask(hsv_left, spec), options, back), options,
                                              metres_per_pixel, &problem, &none_on_back);
    if (!left && spec.optional && none_on_back) {
      out.absent.push_back(markerLabel(spec));  // not stuck on this back: no dot of its colour on it
      continue;
    }
    const std::optional<Blob> right =
        left ? pickRight(*left, findBlobs(colourMask(hsv_right, spec), options, {}), disparity_range, options, &problem)
             : std::nullopt;
    if (!right) {
      out.problems.push_back(markerLabel(spec) + ": " + problem);
      continue;
    }
    SkinMarkerDetection d;
    d.landmark = spec.landmark;
    d.left = left->centre;
    d.right = right->centre;
    d.disparity = left->centre.x - right->centre.x;
    d.diameter_px = left->diameter;
    out.found.push_back(d);
  }
  return out;
}

}  // namespace massage_cell::cect
