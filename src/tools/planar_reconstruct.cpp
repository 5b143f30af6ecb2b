// planar_reconstruct: a piecewise-planar model of a set of calibrated views
// (thesis Ch. 4). See --help.
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <string>
#include <vector>

#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgcodecs.hpp>

#include "cli.h"
#include "massage_cell/planar/camera_views.h"
#include "massage_cell/planar/reconstruct.h"

namespace {

using namespace massage_cell;
using tools::require;

const char* const kUsage = R"(Usage: planar_reconstruct --views PATH [--out DIR] [--method points|sweep]
                          [--detector akaze|orb|sift] [--min-ncc X] [--strip-width PX]
                          [--delineate]

Reconstructs the planes of a scene seen by >= 2 calibrated views: features and
line segments per view, their matches in 3D, the half-planes about each 3D line
verified by the homography they induce (the thesis's search over the feature
points beside the line, or Baillard's sweep of every degree), each extended to
the fixed lines it shares with its neighbours and over its coplanar points, and
the coplanar ones merged.

--views PATH     a VGG multi-view folder (images/NNN.jpg + 2D/NNN.P, e.g.
                 ../shared/data/multiview/merton_college_1), a folder with
                 views.yaml, or a views YAML file (each view: image,
                 camera_info, position [x y z], orientation [qx qy qz qw] of
                 its optical frame in the world)
--out DIR        writes DIR/model.obj, DIR/model.ply (vertex colours) and
                 DIR/overlay_<view>.png (the planes drawn on each view)
--method         points (default: the thesis) or sweep (Baillard)
--delineate      also extend each plane over the pixels its homographies carry
                 consistently into the other views, with planes through
                 left-over coplanar points (off by default: see docs/planar.md)

Prints the counts of each stage, its time, and one line per plane (unit normal,
offset, area in world units, supporting points, verification score).
Exit status: 0 done (also when no plane is found: the counts say why),
1 bad data, 2 bad usage.
)";

struct Options {
  std::string views;
  std::string out;
  planar::ReconstructParams params;
};

bool parse(int argc, char** argv, Options* o) {
  tools::OptionTable table;
  table.values["--views"] = [o](const std::string&, const std::string& v) { o->views = v; };
  table.values["--out"] = [o](const std::string&, const std::string& v) { o->out = v; };
  table.values["--method"] = [o](const std::string& opt, const std::string& v) {
    try {
      o->params.method = planar::halfPlaneMethod(v);
    } catch (const std::invalid_argument& e) {
      throw tools::UsageError(opt + ": " + e.what());
    }
  };
  table.values["--detector"] = [o](const std::string& opt, const std::string& v) {
    require(v == "akaze" || v == "orb" || v == "sift", opt + ": expected akaze, orb or sift, got '" + v + "'");
    o->params.features.detector = v;
  };
  table.values["--min-ncc"] = [o](const std::string& opt, const std::string& v) {
    o->params.half_planes.min_ncc = tools::parseDouble(opt, v);
  };
  table.values["--strip-width"] = [o](const std::string& opt, const std::string& v) {
    o->params.half_planes.strip_width = tools::parseDouble(opt, v);
  };
  table.flags["--delineate"] = [o] { o->params.delineation.enabled = true; };
  if (!tools::parseArguments(argc, argv, table, kUsage)) return false;
  require(!o->views.empty(), "--views is required");
  try {
    o->params.validate();
  } catch (const std::invalid_argument& e) {
    throw tools::UsageError(e.what());
  }
  return true;
}

void printSummary(const std::vector<planar::View>& views, const planar::Reconstruction& r, planar::HalfPlaneMethod m) {
  std::size_t keypoints = 0, segments = 0;
  for (const auto& f : r.features) {
    keypoints += f.keypoints.size();
    segments += f.segments.size();
  }
  std::cout << std::fixed << std::setprecision(3);
  std::cout << "views " << views.size() << ": " << keypoints << " keypoints, " << segments << " segments ("
            << r.times.features << " s)\n"
            << "tracks: " << r.points.size() << " points, " << r.lines.size() << " lines (" << r.times.matching
            << " s)\n"
            << "half-planes (" << planar::halfPlaneMethodName(m) << "): " << r.half_planes.size() << " verified of "
            << r.search.candidates << " candidates scored (" << r.times.half_planes << " s)\n"
            << "extension: " << r.extension.extended << " extended, " << r.extension.facets << " planes ("
            << r.times.extension << " s)\n"
            << (r.delineation.labelling_view >= 0
                    ? "delineation: " + std::to_string(r.delineation.point_planes) + " planes from left-over points, " +
                          std::to_string(r.delineation.dropped) + " dropped, " + std::to_string(r.model.facets.size()) +
                          " planes\n"
                    : std::string())
            << "total " << r.times.total() << " s\n";
  for (std::size_t i = 0; i < r.model.facets.size(); ++i) {
    const planar::Facet& f = r.model.facets[i];
    planar::PlanarModel one;
    one.facets = {f};
    std::cout << "plane " << i << ": n = (" << f.plane.n.x() << ", " << f.plane.n.y() << ", " << f.plane.n.z()
              << "), d = " << f.plane.d << ", area " << one.area() << ", " << f.support_points << " points, ncc "
              << f.score << "\n";
  }
}

void writeOutputs(const std::string& dir, const std::vector<planar::View>& views, const planar::PlanarModel& model) {
  std::filesystem::create_directories(dir);
  const planar::TriangleMesh mesh = planar::toMesh(model, views);
  planar::writeObj(mesh, dir + "/model.obj");
  planar::writePly(mesh, dir + "/model.ply");
  for (std::size_t i = 0; i < views.size(); ++i) {
    const std::string name = std::filesystem::path(views[i].name).stem().string();
    const std::string path = dir + "/overlay_" + (name.empty() ? std::to_string(i) : name) + ".png";
    if (!cv::imwrite(path, planar::drawOverlay(views[i], model))) throw std::runtime_error("cannot write " + path);
  }
  std::cout << "wrote " << dir << "/model.obj, model.ply and " << views.size() << " overlays\n";
}

}  // namespace

int main(int argc, char** argv) {
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_WARNING);
  Options options;
  return tools::runTool(
      "planar_reconstruct", [&] { return parse(argc, argv, &options); },
      [&] {
        const std::vector<planar::View> views = planar::loadViewSet(options.views);
        const planar::Reconstruction r = planar::reconstruct(views, options.params);
        printSummary(views, r, options.params.method);
        if (!options.out.empty()) writeOutputs(options.out, views, r.model);
      });
}
