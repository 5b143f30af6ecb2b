// stereo_match: dense disparity of a rectified pair with HBDS, alpha-expansion,
// alpha-beta swap, winner-takes-all or OpenCV's StereoSGBM.
#include <cstdio>
#include <filesystem>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "massage_cell/stereo/colourise.h"
#include "massage_cell/stereo/memory.h"
#include "stereo_params.h"

namespace {

namespace stereo = massage_cell::stereo;
using namespace massage_cell::tools;

const char* const kUsageHead = R"(Usage: stereo_match LEFT RIGHT --dmax N [--dmin 0] [--method hbds] [options] -o OUT

Computes the disparity of the rectified pair LEFT / RIGHT (left = reference;
pixel x matches x - d in RIGHT) and writes OUT.pfm (float disparities, NaN =
none) and OUT.png (colourised). With OUT ending in .pfm, the PNG goes beside it.

  --method M         hbds | expansion | swap | wta | sgbm (default hbds)
  --dmin N --dmax N  disparity search range, inclusive
  -o OUT             output path (without extension, or ending in .pfm)
)";

struct Options {
  std::vector<std::string> images;
  std::string method = "hbds";
  int dmin = 0;
  int dmax = -1;
  std::string out;
  stereo::StereoParams params;
};

std::string usage() {
  return std::string(kUsageHead) + stereoParamsHelp() + "Exit status: 0 ok, 1 failure, 2 bad command line.\n";
}

bool parse(int argc, char** argv, Options& o) {
  // Positional LEFT RIGHT first, then options.
  std::vector<char*> rest{argv[0]};
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a.rfind("-", 0) != 0 && (rest.size() == 1 || std::string(rest.back()).rfind("-", 0) != 0) &&
        o.images.size() < 2) {
      o.images.push_back(a);
    } else {
      rest.push_back(argv[i]);
    }
  }
  OptionTable t;
  t.values["--method"] = [&](const std::string&, const std::string& v) { o.method = v; };
  t.values["--dmin"] = [&](const std::string& opt, const std::string& v) { o.dmin = parseInt(opt, v); };
  t.values["--dmax"] = [&](const std::string& opt, const std::string& v) { o.dmax = parseInt(opt, v); };
  t.values["-o"] = [&](const std::string&, const std::string& v) { o.out = v; };
  addStereoParams(t, o.params);
  const std::string text = usage();
  if (!parseArguments(static_cast<int>(rest.size()), rest.data(), t, text.c_str())) return false;
  require(o.images.size() == 2, "need the two images LEFT RIGHT");
  require(!o.out.empty(), "-o OUT is required");
  require(o.dmax >= 0, "--dmax is required");
  require(o.dmax > o.dmin, "--dmax must be greater than --dmin");
  require(o.dmin >= 0, "--dmin must be >= 0");
  try {
    stereo::parseMethod(o.method);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  checkStereoParams(o.params);
  o.params.cost.dmin = o.dmin;
  o.params.cost.dmax = o.dmax;
  return true;
}

cv::Mat load(const std::string& path) {
  if (!std::filesystem::exists(path)) throw std::runtime_error("missing image '" + path + "'");
  cv::Mat image = cv::imread(path, cv::IMREAD_UNCHANGED);
  if (image.empty()) throw std::runtime_error("cannot read image '" + path + "'");
  if (image.type() == CV_8UC4) cv::cvtColor(image, image, cv::COLOR_BGRA2BGR);
  return image;  // other types are rejected, with a message, by the matcher
}

void run(const Options& o) {
  const cv::Mat left = load(o.images[0]), right = load(o.images[1]);
  const stereo::Method method = stereo::parseMethod(o.method);
  const stereo::MatchResult r = stereo::match(left, right, method, o.params);
  std::filesystem::path pfm = o.out;
  if (pfm.extension() != ".pfm") pfm += ".pfm";
  std::filesystem::path png = pfm;
  png.replace_extension(".png");
  if (!cv::imwrite(pfm.string(), r.disparity)) throw std::runtime_error("cannot write '" + pfm.string() + "'");
  if (!cv::imwrite(png.string(), stereo::colourise(r.disparity, o.dmin, o.dmax))) {
    throw std::runtime_error("cannot write '" + png.string() + "'");
  }
  char refine[96] = "";
  if (o.params.refine != stereo::Refinement::kNone) {
    std::snprintf(refine, sizeof refine, " + %s %.1f ms (%d fattening pixels)",
                  stereo::toString(o.params.refine).c_str(), r.refine_ms,
                  r.fattening.empty() ? 0 : cv::countNonZero(r.fattening));
  }
  char subpixel[64] = "";
  if (r.subpixel_ms > 0.0) std::snprintf(subpixel, sizeof subpixel, " + sub-pixel %.1f ms", r.subpixel_ms);
  std::printf(
      "stereo_match: %s %dx%d, disparities %d..%d: cost %.1f ms + %s %.1f ms%s%s = %.1f ms, energy %.2f "
      "(data %.2f + smooth %.2f), %d cuts -> %s, %s\n",
      o.method.c_str(), left.cols, left.rows, o.dmin, o.dmax, r.cost_ms, o.method.c_str(), r.optimize_ms, refine,
      subpixel, r.total_ms(), r.energy.total(), r.energy.data, r.energy.smooth, r.cuts, pfm.string().c_str(),
      png.string().c_str());
}

}  // namespace

int main(int argc, char** argv) {
  massage_cell::stereo::retainFreedMemory();
  Options options;
  return runTool(
      "stereo_match", [&] { return parse(argc, argv, options); }, [&] { run(options); });
}
