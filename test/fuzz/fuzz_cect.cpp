// Fuzz target: the CECT chain as the node runs it — a camera_info pair
// (plausible rigs of any size, focal length, baseline, distortion model,
// with NaN / Inf / zero / wrong-length fields mixed in) decimated to a width,
// the pair geometry, CectFrame::analyse on small images (the input's bytes,
// flat colours, or a skin-coloured blob seen by both cameras), and
// locateAcupoints with the package's acupoint model. A bad calibration or
// pair must be refused with std::invalid_argument; image content never
// throws; every acupoint it calls valid has a finite position and
// covariance and a pixel inside the image.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <iostream>
#include <map>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

#include "fuzz_input.h"
#include "massage_cell/camera/calibration.h"
#include "massage_cell/camera/stereo_model.h"
#include "massage_cell/cect/acupoint_model.h"
#include "massage_cell/cect/cect.h"
#include "massage_cell/cect/locate.h"

using namespace massage_cell;

namespace {

// With FUZZ_STATS set: how many pairs were analysed, gave acupoints, and the refusals by reason.
struct Stats {
  long analysed = 0, located = 0;
  std::map<std::string, long> refused;
  ~Stats() {
    if (!std::getenv("FUZZ_STATS")) return;
    std::cerr << "analysed " << analysed << ", with acupoints " << located << "\n";
    for (const auto& [why, n] : refused) std::cerr << n << "  " << why << "\n";
  }
} stats;

[[noreturn]] void broken(const std::string& what) {
  std::cerr << "fuzz_cect: " << what << "\n";
  std::abort();
}

const cect::AcupointModel& model() {
  static const cect::AcupointModel m = cect::loadAcupointModel(MASSAGE_CELL_CONFIG_DIR "/acupoints.yaml");
  return m;
}

// One camera of a rectified-on-the-fly rig: K, D, R, P of a plausible camera,
// then maybe one field broken.
camera::CameraCalibration makeCamera(fuzz::FuzzInput& in, cv::Size size, double f, double tx, bool right,
                                     cv::Point2d rectified_centre) {
  camera::CameraCalibration c;
  c.width = size.width;
  c.height = size.height;
  // (Reads of an exhausted input are 0: a valid plumb_bob camera.)
  static const char* const kModels[] = {"plumb_bob", "rational_polynomial", "equidistant"};
  const long model = in.range(0, 9);
  c.distortion_model = model < 3 ? kModels[model] : model == 9 ? "unknown_model" : "plumb_bob";
  const std::size_t n = c.distortion_model == "rational_polynomial" ? 8 : c.distortion_model == "equidistant" ? 4 : 5;
  c.D.assign(in.byte() % 16 == 15 ? static_cast<std::size_t>(in.range(0, 9)) : n, 0.0);
  for (double& d : c.D) d = in.real(-0.3, 0.3);
  const double cx = (size.width - 1) / 2.0 + in.real(-5, 5), cy = (size.height - 1) / 2.0 + in.real(-5, 5);
  c.K = {f, 0, cx, 0, f, cy, 0, 0, 1};
  const double a = in.real(-0.05, 0.05);  // a small rectifying rotation about y
  c.R = {std::cos(a), 0, std::sin(a), 0, 1, 0, -std::sin(a), 0, std::cos(a)};
  const cv::Point2d& r = rectified_centre;  // shared by the pair's projections
  c.P = {f, 0, r.x, right ? -f * tx : 0.0, 0, f, r.y, 0, 0, 0, 1, 0};
  const std::uint8_t breakage = in.byte();
  if (breakage % 8 == 7) {  // one field of K, D, R or P made NaN / Inf / 0 / huge
    const double v = in.real(0, 0, true);
    switch (breakage / 4 % 4) {
      case 0:
        c.K[in.range(0, 8)] = v;
        break;
      case 1:
        if (!c.D.empty()) c.D[in.range(0, static_cast<long>(c.D.size()) - 1)] = v;
        break;
      case 2:
        c.R[in.range(0, 8)] = v;
        break;
      default:
        c.P[in.range(0, 11)] = v;
        break;
    }
  }
  if (breakage == 255) c.width += 1;  // the calibration's size is not the images'
  return c;
}

cv::Mat view(fuzz::FuzzInput& in, cv::Size size, int kind, double shift, std::uint32_t seed) {
  cv::Mat m(size, CV_8UC3, cv::Scalar(40, 40, 45));
  if (kind == 0) {
    for (auto it = m.begin<cv::Vec3b>(); it != m.end<cv::Vec3b>(); ++it)
      *it = cv::Vec3b(in.byte(), in.byte(), in.byte());
  } else if (kind == 1) {
    m.setTo(cv::Scalar(in.byte(), in.byte(), in.byte()));
  } else {  // a skin-coloured torso, textured, `shift` pixels to the left in the right view
    cv::RNG rng(seed);
    const cv::Point centre(static_cast<int>(size.width / 2 - shift), size.height / 2);
    cv::ellipse(m, centre, cv::Size(size.width / 4, size.height * 2 / 5), 0, 0, 360, cv::Scalar(120, 150, 205), -1);
    cv::Mat noise(size, CV_8UC3);
    rng.fill(noise, cv::RNG::NORMAL, 0, 6);
    m += noise;
  }
  return m;
}

void checkLocated(const cect::LocatedAcupoints& located, cv::Size size) {
  for (const auto& p : located.points) {
    if (!p.valid) {
      if (p.reason.empty()) broken("acupoint " + p.name + " is not valid and gives no reason");
      continue;
    }
    if (!p.point.position.allFinite() || !p.covariance.allFinite())
      broken("acupoint " + p.name + " is valid with a non-finite position or covariance");
    if (!(p.raw.x >= -0.5f && p.raw.y >= -0.5f && p.raw.x <= size.width - 0.5f && p.raw.y <= size.height - 0.5f))
      broken("acupoint " + p.name + " is valid at a pixel outside the image");
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  (void)model();  // load once, outside the timed inputs
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  fuzz::FuzzInput in(data, size);
  const cv::Size full(static_cast<int>(in.range(8, 160)), static_cast<int>(in.range(6, 120)));
  const double f = in.real(20, 400), baseline = in.real(0.01, 0.3);
  const cv::Point2d centre((full.width - 1) / 2.0 + in.real(-3, 3), (full.height - 1) / 2.0 + in.real(-3, 3));
  const camera::CameraCalibration left_info = makeCamera(in, full, f, baseline, false, centre);
  const camera::CameraCalibration right_info = makeCamera(in, full, f, baseline, true, centre);
  // Mostly none or a factor of 2-3, sometimes any width (too small to decimate to: refused).
  const std::uint8_t decimate = in.byte();
  const int max_width = decimate % 16 == 15 ? static_cast<int>(in.range(1, 200))
                        : decimate % 4 == 3 ? full.width / static_cast<int>(in.range(2, 3))
                                            : 0;
  camera::Decimation decimation;
  camera::StereoModel geometry;
  try {  // as the node does: a size it cannot decimate or a bad calibration skips the pair
    decimation = camera::Decimation::toWidth(full, max_width);
    geometry = camera::StereoModel(decimation.apply(left_info), decimation.apply(right_info));
  } catch (const std::invalid_argument& e) {
    if (std::string(e.what()).empty()) broken("a calibration refused without a message");
    ++stats.refused[std::string(e.what()).substr(0, 60)];
    return 0;
  }
  for (const auto* c : {&left_info, &right_info}) {
    const auto finite = [](const auto& values) {
      return std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v); });
    };
    if (!finite(c->K) || !finite(c->D) || !finite(c->R) || !finite(c->P))
      broken("a non-finite calibration was accepted");
  }
  const int kind = static_cast<int>(in.range(0, 2));
  const std::uint32_t seed = in.bits<std::uint32_t>();
  const double shift = in.real(0, 30);
  cv::Mat left = decimation.apply(view(in, full, kind, 0.0, seed));
  cv::Mat right = decimation.apply(view(in, full, kind, shift, seed));
  const std::uint8_t damage = in.byte();
  if (damage == 253) right = right.rowRange(0, right.rows - 1).clone();  // the pair's sizes differ
  if (damage == 254) cv::cvtColor(left, left, cv::COLOR_BGR2GRAY);       // mono
  if (damage == 255) left = cv::Mat();
  const bool malformed = damage >= 253;

  cect::CectParams params;
  params.seed_step = static_cast<int>(in.range(0, 24));
  params.sample_spacing = in.real(1, 8);
  params.ncc_radius = static_cast<int>(in.range(2, 13));
  cect::CectFrame frame;
  try {
    frame = cect::CectFrame::analyse(left, right, geometry, params);
  } catch (const std::invalid_argument& e) {
    if (!malformed) broken(std::string("a well-formed pair was refused: ") + e.what());
    return 0;
  }
  if (malformed) broken("a malformed pair was accepted");
  if (!frame.valid() && frame.reason().empty()) broken("an invalid frame without a reason");
  ++stats.analysed;
  const cect::LocatedAcupoints located = cect::locateAcupoints(frame, model());
  if (located.valid) ++stats.located;
  checkLocated(located, left.size());
  return 0;
}
