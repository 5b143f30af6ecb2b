// planar_eval: the piecewise-planar reconstruction against exact planes
// (the simulator's cube and stacked boxes) and against Merton College I's
// reference, the thesis's feature-point search beside Baillard's sweep in
// the same run (thesis Tables 4.1-4.4). See --help.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <string>
#include <vector>

#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>

#include "cli.h"
#include "massage_cell/planar/evaluation.h"
#include "massage_cell/planar/reconstruct.h"
#include "massage_cell/sim/multiview_set.h"
#include "package_paths.h"

namespace {

using namespace massage_cell;
using tools::require;

const char* const kUsage = R"(Usage: planar_eval [--sets cube,boxes,merton] [--views N] [--seed S] [--seeds K]
                   [--distance M] [--detector akaze|orb|sift] [--strip-width PX] [--min-ncc X]
                   [--delineate]
                   [--pictures DIR] [--data DIR]

Reconstructs each set with both half-plane searches from the same features and
tracks, and prints one row per set and search:
  planes      reference planes reconstructed / reference planes
  angle       error of the angle between every pair of reference planes at more
              than 5 degrees, mean / max (thesis Tables 4.1, 4.2)
  coverage    share of the reference planes' visible pixels covered (rendered
              sets only); `faces`: the same over the box / cube faces alone
              (without the table)
  vertices    distance of the model's vertices to their reference plane, mean /
              max, in % of the scene's depth
  half-plane  candidates scored and seconds of the half-plane search (thesis
              Tables 4.3, 4.4); `total` adds features, matching and extension
              (and with --delineate the per-pixel delineation, off by default)

Sets: cube (one textured cube, 3 rendered views), boxes (the simulator's stacked
boxes on the table, printed or textured, --views views --distance M away
(default 0.8 m), one set per seed from --seed, --seeds K sets: default 3), merton (Merton College I from
--data, default $MASSAGE_CELL_DATA or ../shared/data next to the package; the
reference planes are fitted to its 3D points). A missing data set is reported
and skipped. Exit status: 0 done, 1 bad data, 2 bad usage.
)";

struct Options {
  std::vector<std::string> sets{"cube", "boxes", "merton"};
  int views = 3;
  std::uint32_t seed = 1;
  int seeds = 3;
  double distance = 0.8;
  std::string pictures;
  std::string data;
  planar::ReconstructParams params;
};

struct EvalSet {
  std::string name;
  std::vector<planar::View> views;
  std::vector<planar::ReferencePlane> reference;
  double depth = 1.0;  ///< scene depth, world units
};

bool parse(int argc, char** argv, Options* o) {
  tools::OptionTable table;
  table.values["--sets"] = [o](const std::string& opt, const std::string& v) {
    o->sets = tools::splitList(v);
    for (const auto& s : o->sets) {
      require(s == "cube" || s == "boxes" || s == "merton", opt + ": unknown set '" + s + "' (cube, boxes, merton)");
    }
  };
  table.values["--views"] = [o](const std::string& opt, const std::string& v) {
    o->views = tools::parseInt(opt, v);
    require(o->views >= 2 && o->views <= 12, opt + ": expected 2 .. 12 views");
  };
  table.values["--seed"] = [o](const std::string& opt, const std::string& v) { o->seed = tools::parseSeed(opt, v); };
  table.values["--seeds"] = [o](const std::string& opt, const std::string& v) {
    o->seeds = tools::parseInt(opt, v);
    require(o->seeds >= 1 && o->seeds <= 100, opt + ": expected 1 .. 100");
  };
  table.values["--distance"] = [o](const std::string& opt, const std::string& v) {
    o->distance = tools::parseDouble(opt, v);
    require(o->distance >= 0.3 && o->distance <= 10.0, opt + ": expected 0.3 .. 10 m");
  };
  table.values["--detector"] = [o](const std::string& opt, const std::string& v) {
    require(v == "akaze" || v == "orb" || v == "sift", opt + ": expected akaze, orb or sift, got '" + v + "'");
    o->params.features.detector = v;
  };
  table.values["--strip-width"] = [o](const std::string& opt, const std::string& v) {
    o->params.half_planes.strip_width = tools::parseDouble(opt, v);
  };
  table.values["--min-ncc"] = [o](const std::string& opt, const std::string& v) {
    o->params.half_planes.min_ncc = tools::parseDouble(opt, v);
  };
  table.flags["--delineate"] = [o] { o->params.delineation.enabled = true; };
  table.values["--pictures"] = [o](const std::string&, const std::string& v) { o->pictures = v; };
  table.values["--data"] = [o](const std::string&, const std::string& v) { o->data = v; };
  if (!tools::parseArguments(argc, argv, table, kUsage)) return false;
  try {
    o->params.validate();
  } catch (const std::invalid_argument& e) {
    throw tools::UsageError(e.what());
  }
  return true;
}

std::string dataFolder(const Options& o) {
  if (!o.data.empty()) return o.data;
  return tools::sharedDataDir();
}

/// A rendered set's views and reference (planes, visible masks, points on them).
EvalSet fromRendered(const std::string& name, const sim::MultiViewSet& set) {
  EvalSet e;
  e.name = name;
  e.depth = set.scene_depth;
  for (std::size_t v = 0; v < set.images.size(); ++v) {
    planar::View view;
    view.name = name + std::to_string(v);
    view.image = set.images[v];
    view.P = planar::normalisedProjection(set.P[v]);
    e.views.push_back(view);
  }
  for (const sim::TruePlane& t : set.planes) {
    planar::ReferencePlane ref;
    ref.name = t.name;
    ref.plane.n = t.n;
    ref.plane.d = t.d;
    for (std::size_t v = 0; v < set.labels.size(); ++v) ref.visible.push_back(set.labels[v] == t.label);
    e.reference.push_back(ref);
  }
  return e;
}

EvalSet merton(const Options& o) {
  const std::string folder = dataFolder(o) + "/multiview/merton_college_1";
  EvalSet e;
  e.name = "merton";
  e.views = planar::loadVggViews(folder);
  std::vector<double> depths;
  for (const Eigen::Vector3d& X : planar::loadVggPoints(folder)) depths.push_back(planar::depthOf(e.views[0].P, X));
  std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
  e.depth = depths[depths.size() / 2];
  e.reference = planar::vggReferencePlanes(folder, 0.01 * e.depth, 40);
  return e;
}

/// Coverage of the reference planes other than the table (the faces), NaN without masks.
double facesCoverage(const EvalSet& set, const planar::Evaluation& ev) {
  double covered = 0.0, visible = 0.0;
  for (const planar::PlaneMatch& m : ev.matches) {
    const planar::ReferencePlane& ref = set.reference[static_cast<std::size_t>(m.reference)];
    if (ref.visible.empty() || ref.name == "table") continue;
    double pixels = 0.0;
    for (const cv::Mat& mask : ref.visible) pixels += cv::countNonZero(mask);
    covered += m.coverage * pixels;
    visible += pixels;
  }
  return visible > 0.0 ? covered / visible : std::nan("");
}

std::string percent(double share) {
  return std::isnan(share) ? std::string("-") : std::to_string(int(std::lround(100 * share))) + " %";
}

void printRow(const EvalSet& set, planar::HalfPlaneMethod method, const planar::Evaluation& ev,
              const planar::SearchStats& search, double total) {
  std::cout << std::left << std::setw(8) << set.name << std::setw(8) << planar::halfPlaneMethodName(method)
            << std::right << std::fixed << std::setprecision(2) << std::setw(4) << ev.reconstructed << "/" << std::left
            << std::setw(4) << set.reference.size() << std::right << std::setw(7) << ev.mean_pair_error_deg << " /"
            << std::setw(6) << ev.max_pair_error_deg << std::setw(7) << percent(ev.coverage) << std::setw(7)
            << percent(facesCoverage(set, ev)) << std::setw(8) << 100 * ev.vertex_distance_mean / set.depth << " /"
            << std::setw(6) << 100 * ev.vertex_distance_max / set.depth << std::setw(10) << search.candidates
            << std::setw(9) << std::setprecision(3) << search.seconds << std::setw(9) << total << "\n";
}

/// Both searches on one set, from the same features and tracks.
void evaluateSet(const EvalSet& set, const Options& o) {
  planar::Reconstruction base;
  auto t0 = std::chrono::steady_clock::now();
  for (const auto& view : set.views) base.features.push_back(planar::detectFeatures(view, o.params.features));
  base.points = planar::matchPoints(set.views, base.features, o.params.features);
  base.lines = planar::matchLines(set.views, base.features, o.params.features);
  const double front = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const planar::HalfPlaneSearch search(set.views, base.points, base.lines, o.params.half_planes);
  double seconds[2] = {0.0, 0.0};
  for (planar::HalfPlaneMethod method : {planar::HalfPlaneMethod::kFeaturePoints, planar::HalfPlaneMethod::kSweep}) {
    planar::SearchStats stats;
    const auto half_planes =
        method == planar::HalfPlaneMethod::kSweep ? search.bySweep(&stats) : search.byFeaturePoints(&stats);
    planar::ExtendStats ext;
    planar::DelineateStats del;
    const planar::PlanarModel model = planar::delineate(
        set.views, base.points,
        planar::extendAndMerge(set.views, base.points, base.lines, half_planes, o.params.extension, &ext),
        o.params.delineation, &del);
    const planar::Evaluation ev = planar::evaluateModel(model, set.views, set.reference, 10.0, 0.03 * set.depth);
    printRow(set, method, ev, stats, front + stats.seconds + ext.seconds + del.seconds);
    seconds[method == planar::HalfPlaneMethod::kSweep ? 1 : 0] = stats.seconds;
    if (!o.pictures.empty()) {
      std::filesystem::create_directories(o.pictures);
      const std::string path = o.pictures + "/" + set.name + "_" + planar::halfPlaneMethodName(method) + ".png";
      if (!cv::imwrite(path, planar::drawOverlay(set.views[0], model)))
        throw std::runtime_error("cannot write " + path);
    }
  }
  std::cout << "        " << base.points.size() << " point tracks, " << base.lines.size()
            << " line tracks; the sweep took " << std::setprecision(1) << seconds[1] / std::max(seconds[0], 1e-9)
            << "x the feature-point search's time\n";
}

void run(const Options& o) {
  std::cout << "set     search  planes   angle error deg    all  faces  vertices %depth  candidates  half-plane s"
               "  total s\n";
  for (const std::string& name : o.sets) {
    sim::MultiViewOptions mv;
    mv.views = o.views;
    mv.seed = o.seed;
    if (name == "cube") {
      evaluateSet(fromRendered("cube", sim::renderCubeViews(0.3, mv)), o);
    } else if (name == "boxes") {
      mv.distance = o.distance;
      for (int k = 0; k < o.seeds; ++k) {
        mv.seed = o.seed + static_cast<std::uint32_t>(k);
        evaluateSet(fromRendered("boxes" + std::to_string(mv.seed), sim::renderBoxesViews(3, mv)), o);
      }
    } else {
      EvalSet set;
      try {
        set = merton(o);
      } catch (const std::runtime_error& e) {
        std::cout << "merton  skipped: " << e.what() << "\n";
        continue;
      }
      evaluateSet(set, o);
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_WARNING);
  Options options;
  return tools::runTool(
      "planar_eval", [&] { return parse(argc, argv, &options); }, [&] { run(options); });
}
