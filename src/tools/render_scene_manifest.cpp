#include "render_scene_manifest.h"

namespace massage_cell::tools::render_scene {
namespace {

void emitMatrix(YAML::Emitter& out, const Eigen::MatrixXd& m) {
  out << YAML::Flow << YAML::BeginSeq;
  for (int r = 0; r < m.rows(); ++r) {
    out << YAML::Flow << YAML::BeginSeq;
    for (int c = 0; c < m.cols(); ++c) out << m(r, c);
    out << YAML::EndSeq;
  }
  out << YAML::EndSeq;
}

}  // namespace

void beginManifest(YAML::Emitter& m, const Options& o) {
  m << YAML::BeginMap;
  m << YAML::Key << "preset" << YAML::Value << o.preset;
  m << YAML::Key << "frame" << YAML::Value
    << "world frame 'table': x toward the head, y to the subject's left, z up, origin on the table top under C7";
  m << YAML::Key << "seed" << YAML::Value << o.seed;
  m << YAML::Key << "supersample" << YAML::Value << o.supersample;
  m << YAML::Key << "noise_sigma" << YAML::Value << o.noise;
  m << YAML::Key << "exposure" << YAML::Value << o.exposure;
}

void emitCamera(YAML::Emitter& out, const std::string& name, const sim::CameraModel& c) {
  out << YAML::Key << name << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "width" << YAML::Value << c.width << YAML::Key << "height" << YAML::Value << c.height;
  out << YAML::Key << "K" << YAML::Value;
  emitMatrix(out, c.K);
  out << YAML::Key << "D" << YAML::Value << YAML::Flow << c.D;
  out << YAML::Key << "world_from_camera" << YAML::Value;
  emitMatrix(out, c.world_from_camera.matrix());
  out << YAML::Key << "projection" << YAML::Value;  // world -> undistorted pixels
  emitMatrix(out, c.projectionMatrix());
  out << YAML::EndMap;
}

void emitStereoCameras(YAML::Emitter& m, const sim::StereoPairModel& pair) {
  m << YAML::Key << "rectified" << YAML::Value << pair.rectified;
  m << YAML::Key << "baseline" << YAML::Value << pair.baseline();
  m << YAML::Key << "cameras" << YAML::Value << YAML::BeginMap;
  emitCamera(m, "left", pair.left);
  emitCamera(m, "right", pair.right);
  m << YAML::EndMap;
}

void emitBody(YAML::Emitter& m, const Options& o, const sim::BodyParameters& b) {
  m << YAML::Key << "subject" << YAML::Value << YAML::BeginMap;
  m << YAML::Key << "index" << YAML::Value << o.subject << YAML::Key << "body_seed" << YAML::Value << o.body_seed;
  if (o.varied > 0) m << YAML::Key << "varied" << YAML::Value << o.varied;
  if (!o.build.empty()) {
    m << YAML::Key << "build" << YAML::Value << o.build << YAML::Key << "bmi" << YAML::Value << o.bmi;
    m << YAML::Key << "stature" << YAML::Value << o.stature;
  }
  if (o.skin_type > 0) m << YAML::Key << "skin_type" << YAML::Value << o.skin_type;
  m << YAML::Key << "shoulder_width" << YAML::Value << b.shoulder_width;
  m << YAML::Key << "waist_width" << YAML::Value << b.waist_width;
  m << YAML::Key << "hip_width" << YAML::Value << b.hip_width;
  m << YAML::Key << "torso_length" << YAML::Value << b.torso_length;
  m << YAML::Key << "back_height" << YAML::Value << b.back_height;
  m << YAML::Key << "spine_depth" << YAML::Value << b.spine_depth;
  m << YAML::Key << "scapula_medial_offset" << YAML::Value << b.scapula_medial_offset;
  m << YAML::Key << "shoulder_slope" << YAML::Value << b.shoulder_slope;
  m << YAML::Key << "lateral_rounding" << YAML::Value << b.lateral_rounding;
  m << YAML::Key << "scapula_prominence" << YAML::Value << b.scapula_prominence;
  m << YAML::Key << "spinous_prominence" << YAML::Value << b.spinous_prominence;
  m << YAML::Key << "skin_albedo" << YAML::Value << YAML::Flow
    << std::vector<float>{b.skin_albedo.x(), b.skin_albedo.y(), b.skin_albedo.z()};
  m << YAML::EndMap;
  m << YAML::Key << "light" << YAML::Value << o.light;
  m << YAML::Key << "camera_shift" << YAML::Value << o.shift;
  m << YAML::Key << "breathing_amplitude" << YAML::Value << o.breathing_amplitude;
}

void emitDressing(YAML::Emitter& m, const Options& o, const sim::Dressing& d) {
  m << YAML::Key << "dressing" << YAML::Value << YAML::BeginMap;
  m << YAML::Key << "arms" << YAML::Value << o.arms;
  m << YAML::Key << "arm_abduction" << YAML::Value << YAML::Flow
    << std::vector<double>{d.arm_abduction_left, d.arm_abduction_right};
  m << YAML::Key << "head" << YAML::Value << d.head;
  if (d.head)
    m << YAML::Key << "hair" << YAML::Value << o.hair << YAML::Key << "hair_colour" << YAML::Value << o.hair_colour;
  m << YAML::Key << "lower_body" << YAML::Value << d.lower_body;
  m << YAML::Key << "towel" << YAML::Value << (o.towel.empty() ? "none" : o.towel);
  if (d.towel) {
    m << YAML::Key << "towel_weave" << YAML::Value << o.towel_weave;
    m << YAML::Key << "towel_edge_x" << YAML::Value << d.towel_edge_x;
  }
  m << YAML::Key << "sheet" << YAML::Value << (o.sheet.empty() ? "default_sheet" : o.sheet);
  if (!o.stickers.empty()) {
    m << YAML::Key << "stickers" << YAML::Value << YAML::Flow << o.stickers;
    m << YAML::Key << "sticker_diameter" << YAML::Value << o.sticker_size;
  }
  m << YAML::Key << "toe_in_degrees" << YAML::Value << o.toe_in;
  if (!o.frame_top.empty()) {
    m << YAML::Key << "frame_top" << YAML::Value << o.frame_top << YAML::Key << "frame_bottom" << YAML::Value
      << o.frame_bottom;
  }
  m << YAML::EndMap;
}

void endManifest(YAML::Emitter& m, const std::vector<std::string>& files, const fs::path& dir) {
  m << YAML::Key << "files" << YAML::Value << files << YAML::EndMap;
  writeYaml(dir / "manifest.yaml", m);
}

}  // namespace massage_cell::tools::render_scene
