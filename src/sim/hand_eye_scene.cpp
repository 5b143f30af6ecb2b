// The simulated hand-eye cell: marker geometry from the board drawing, pose
// selection over the gantry's workspace and rendering of the marker poses.
#include "massage_cell/sim/hand_eye_scene.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "massage_cell/sim/scene_builder.h"

namespace massage_cell::sim {
namespace {

struct Rect {
  int u0, v0, u1, v1;  ///< pixel range [u0, u1) x [v0, v1)
};

/// Black pixels of a binary drawing as rectangles: runs along each row,
/// merged with the run of the same columns on the rows above.
std::vector<Rect> blackRectangles(const cv::Mat& drawing) {
  std::vector<Rect> done;
  std::map<std::pair<int, int>, int> open;  // (u0, u1) -> first row
  for (int v = 0; v <= drawing.rows; ++v) {
    std::map<std::pair<int, int>, int> next;
    if (v < drawing.rows) {
      const auto* row = drawing.ptr<std::uint8_t>(v);
      for (int u = 0; u < drawing.cols;) {
        if (row[u] >= 128) {
          ++u;
          continue;
        }
        const int start = u;
        while (u < drawing.cols && row[u] < 128) ++u;
        const auto key = std::make_pair(start, u);
        const auto it = open.find(key);
        next[key] = it == open.end() ? v : it->second;
      }
    }
    for (const auto& [key, first] : open) {
      if (!next.count(key) || next[key] != first) done.push_back({key.first, first, key.second, v});
    }
    open = std::move(next);
  }
  return done;
}

Eigen::Vector3f toTable(const Eigen::Isometry3d& table_from_board, double x, double y, double z) {
  return (table_from_board * Eigen::Vector3d(x, y, z)).cast<float>();
}

/// Pixel rectangle (clipped to the image) holding the board and its rim, plus `pad` pixels.
cv::Rect boardRect(const CameraModel& camera, const Eigen::Isometry3d& table_from_board, const MarkerMount& mount,
                   int pad) {
  const double w = mount.spec.width(), h = mount.spec.height(), rim = 0.01;
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const auto& [x, y] : {std::make_pair(-rim, -rim), {w + rim, -rim}, {w + rim, h + rim}, {-rim, h + rim}}) {
    Eigen::Vector2d px;
    if (!camera.project(table_from_board * Eigen::Vector3d(x, y, 0.0), &px)) return {};
    lo = lo.cwiseMin(px);
    hi = hi.cwiseMax(px);
  }
  const cv::Point first(static_cast<int>(std::floor(lo.x())) - pad, static_cast<int>(std::floor(lo.y())) - pad);
  const cv::Point last(static_cast<int>(std::ceil(hi.x())) + pad + 1, static_cast<int>(std::ceil(hi.y())) + pad + 1);
  const cv::Rect r(first, last);
  return r & cv::Rect(0, 0, camera.width, camera.height);
}

/// The view at the options' supersampling, with the board's pixels rendered
/// again at 8 x 8 rays per pixel: a regular 3 x 3 grid puts a straight edge
/// on the pixel grid to 1/6 pixel, too coarse for sub-pixel corners. The crop
/// is a camera with the same rays (pinhole only: shifted principal point).
cv::Mat renderWithMarkerDetail(const Renderer& renderer, const CameraModel& camera,
                               const Eigen::Isometry3d& table_from_board, const MarkerMount& mount,
                               const RenderOptions& options) {
  cv::Mat image = renderer.render(camera, Lighting{}, options).image;
  const cv::Rect roi = boardRect(camera, table_from_board, mount, 4);
  const bool pinhole = std::all_of(camera.D.begin(), camera.D.end(), [](double d) { return d == 0.0; });
  if (roi.empty() || !pinhole) return image;
  CameraModel crop = camera;
  crop.width = roi.width;
  crop.height = roi.height;
  crop.K(0, 2) -= roi.x;
  crop.K(1, 2) -= roi.y;
  RenderOptions fine = options;
  fine.supersample = 8;
  renderer.render(crop, Lighting{}, fine).image.copyTo(image(roi));
  return image;
}

}  // namespace

Eigen::Isometry3d tableFromArmBase() {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.translation() = Eigen::Vector3d(0.15, 0.25, 0.0);
  t.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return t;
}

Eigen::Isometry3d boardPose(const Eigen::Vector3d& tip_in_base, const MarkerMount& mount) {
  Eigen::Matrix3d base_from_board;
  base_from_board.col(0) = Eigen::Vector3d::UnitY();   // drawing x along the base's y
  base_from_board.col(1) = Eigen::Vector3d::UnitX();   // drawing y along the base's x
  base_from_board.col(2) = -Eigen::Vector3d::UnitZ();  // into the board: down
  Eigen::Isometry3d b = Eigen::Isometry3d::Identity();
  b.linear() = base_from_board;
  b.translation() = tip_in_base + mount.offset - base_from_board * calib::referencePointInBoard(mount.spec);
  return tableFromArmBase() * b;
}

std::vector<Mesh> makeMarkerMeshes(const MarkerMount& mount, const Eigen::Isometry3d& table_from_board) {
  const cv::Mat drawing = calib::drawBoard(mount.spec, mount.pixels_per_metre);
  const double w = mount.spec.width(), h = mount.spec.height();
  const double px_x = w / drawing.cols, px_y = h / drawing.rows;

  Material paper;
  paper.albedo = Eigen::Vector3f(0.80f, 0.80f, 0.78f);
  Material ink;
  ink.albedo = Eigen::Vector3f(0.03f, 0.03f, 0.03f);

  // Backing plate: its top 0.05 mm below the face, 3 mm thick, 5 mm white rim.
  const double rim = 0.005, top = 5e-5, thick = 0.003;
  Mesh plate = makeBox("marker_plate", Eigen::Vector3f(-rim, -rim, top), Eigen::Vector3f(w + rim, h + rim, top + thick),
                       paper, kLabelPlane);
  transform(plate, table_from_board.linear().cast<float>(), table_from_board.translation().cast<float>());

  Mesh ink_mesh;
  ink_mesh.name = "marker_ink";
  ink_mesh.material = ink;
  ink_mesh.label = kLabelPlane;
  for (const Rect& r : blackRectangles(drawing)) {
    // Counter-clockwise seen from -z (the viewer), so the normal points out of the face.
    const Mesh q = makeQuad("ink", toTable(table_from_board, r.u0 * px_x, r.v1 * px_y, 0.0),
                            toTable(table_from_board, r.u1 * px_x, r.v1 * px_y, 0.0),
                            toTable(table_from_board, r.u1 * px_x, r.v0 * px_y, 0.0),
                            toTable(table_from_board, r.u0 * px_x, r.v0 * px_y, 0.0), ink, kLabelPlane);
    const int base = static_cast<int>(ink_mesh.vertices.size());
    ink_mesh.vertices.insert(ink_mesh.vertices.end(), q.vertices.begin(), q.vertices.end());
    ink_mesh.normals.insert(ink_mesh.normals.end(), q.normals.begin(), q.normals.end());
    ink_mesh.uv.insert(ink_mesh.uv.end(), q.uv.begin(), q.uv.end());
    for (const Eigen::Vector3i& t : q.triangles) ink_mesh.triangles.push_back(t + Eigen::Vector3i::Constant(base));
  }
  return {std::move(plate), std::move(ink_mesh)};
}

Scene makeEmptyTableScene(std::uint32_t seed) {
  Scene scene;
  Material cloth;
  cloth.pattern = Material::Pattern::kCloth;
  cloth.albedo = Eigen::Vector3f(0.55f, 0.62f, 0.70f);
  cloth.feature_size = 0.002f;
  cloth.contrast = 0.25f;
  cloth.seed = seed;
  scene.meshes.push_back(makeBox("table", Eigen::Vector3f(kTableFootX, -kTableHalfWidth, -kTableThickness),
                                 Eigen::Vector3f(kTableHeadX, kTableHalfWidth, 0.0f), cloth, kLabelTable));
  Material floor;
  floor.pattern = Material::Pattern::kTexture;
  floor.albedo = Eigen::Vector3f(0.35f, 0.3f, 0.25f);
  floor.feature_size = 0.05f;
  floor.contrast = 0.3f;
  floor.seed = seed + 1;
  scene.meshes.push_back(makeQuad("floor", Eigen::Vector3f(-4, -4, kFloorZ), Eigen::Vector3f(4, -4, kFloorZ),
                                  Eigen::Vector3f(4, 4, kFloorZ), Eigen::Vector3f(-4, 4, kFloorZ), floor, kLabelFloor));
  return scene;
}

bool markerInView(const StereoPairModel& pair, const Eigen::Vector3d& tip_in_base, const MarkerMount& mount,
                  double margin) {
  const Eigen::Isometry3d table_from_board = boardPose(tip_in_base, mount);
  const double w = mount.spec.width(), h = mount.spec.height();
  for (const CameraModel* cam : {&pair.left, &pair.right}) {
    for (const auto& [x, y] : {std::make_pair(0.0, 0.0), {w, 0.0}, {w, h}, {0.0, h}}) {
      Eigen::Vector2d px;
      if (!cam->project(table_from_board * Eigen::Vector3d(x, y, 0.0), &px)) return false;
      if (px.x() < margin || px.y() < margin || px.x() > cam->width - 1 - margin || px.y() > cam->height - 1 - margin) {
        return false;
      }
    }
  }
  return true;
}

std::vector<Eigen::Vector3d> spreadTipPositions(int count, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                                                const StereoPairModel& pair, const MarkerMount& mount) {
  if (count < 1) throw std::invalid_argument("spreadTipPositions: count must be >= 1");
  if (!(lo.array() <= hi.array()).all()) throw std::invalid_argument("spreadTipPositions: lo must be <= hi");
  const int steps[3] = {6, 6, 4};
  std::vector<Eigen::Vector3d> candidates;
  for (int i = 0; i < steps[0]; ++i) {
    for (int j = 0; j < steps[1]; ++j) {
      for (int k = 0; k < steps[2]; ++k) {
        const Eigen::Vector3d f(i / (steps[0] - 1.0), j / (steps[1] - 1.0), k / (steps[2] - 1.0));
        const Eigen::Vector3d p = lo + f.cwiseProduct(hi - lo);
        if (markerInView(pair, p, mount)) candidates.push_back(p);
      }
    }
  }
  if (static_cast<int>(candidates.size()) < count) {
    throw std::invalid_argument("spreadTipPositions: only " + std::to_string(candidates.size()) +
                                " workspace positions show the whole marker to both cameras, " + std::to_string(count) +
                                " asked for");
  }
  const Eigen::Vector3d centre = 0.5 * (lo + hi);
  std::vector<double> distance(candidates.size(), std::numeric_limits<double>::infinity());
  std::vector<Eigen::Vector3d> chosen;
  std::size_t pick = 0;
  for (std::size_t c = 1; c < candidates.size(); ++c) {
    if ((candidates[c] - centre).norm() < (candidates[pick] - centre).norm()) pick = c;
  }
  while (static_cast<int>(chosen.size()) < count) {
    chosen.push_back(candidates[pick]);
    for (std::size_t c = 0; c < candidates.size(); ++c) {
      distance[c] = std::min(distance[c], (candidates[c] - candidates[pick]).norm());
    }
    pick = static_cast<std::size_t>(std::max_element(distance.begin(), distance.end()) - distance.begin());
  }
  return chosen;
}

MarkerPose renderMarkerPose(const StereoPairModel& pair, const Eigen::Vector3d& tip_in_base, const MarkerMount& mount,
                            const RenderOptions& options, std::uint32_t seed, double blur_sigma) {
  if (!(blur_sigma >= 0.0) || blur_sigma > 5.0) {
    throw std::invalid_argument("renderMarkerPose: blur_sigma must be in 0..5 px");
  }
  Scene scene = makeEmptyTableScene(seed);
  const Eigen::Isometry3d table_from_board = boardPose(tip_in_base, mount);
  for (Mesh& m : makeMarkerMeshes(mount, table_from_board)) scene.meshes.push_back(std::move(m));
  const Renderer renderer(scene);
  MarkerPose pose;
  pose.tip_in_base = tip_in_base;
  pose.marker_in_camera =
      pair.left.world_from_camera.inverse() * table_from_board * calib::referencePointInBoard(mount.spec);
  RenderOptions clean = options;
  clean.noise_sigma = 0.0f;
  cv::RNG rng(static_cast<std::uint64_t>(options.noise_seed) * 7919u + seed);
  auto finish = [&](const cv::Mat& image) {
    // The lens's blur, then the sensor's noise (as the renderer adds it).
    cv::Mat f;
    image.convertTo(f, CV_32FC3);
    if (blur_sigma > 0.0) cv::GaussianBlur(f, f, cv::Size(), blur_sigma);
    if (options.noise_sigma > 0.0f) {
      cv::Mat noise(f.size(), CV_32FC3);
      rng.fill(noise, cv::RNG::NORMAL, cv::Scalar::all(0.0), cv::Scalar::all(options.noise_sigma));
      f += noise;
    }
    cv::Mat out;
    f.convertTo(out, CV_8UC3);
    return out;
  };
  pose.left = finish(renderWithMarkerDetail(renderer, pair.left, table_from_board, mount, clean));
  pose.right = finish(renderWithMarkerDetail(renderer, pair.right, table_from_board, mount, clean));
  return pose;
}

Eigen::Isometry3d trueCameraFromBase(const StereoPairModel& pair) {
  return pair.left.world_from_camera.inverse() * tableFromArmBase();
}

}  // namespace massage_cell::sim
