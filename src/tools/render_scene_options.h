// render_scene's command line: the preset, the subject and its dressing, the
// rig and the rendering (render_scene_options.cpp: the help, the parsing and
// the checks).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace massage_cell::tools::render_scene {

struct Options {
  std::string preset;
  std::string out;
  int subject = 0;
  std::uint32_t body_seed = 2024;
  std::string light = "top_centre";
  double shift = 0.0;
  double camera_height = 0.95;
  int width = 640, height = 480;
  double fx = 500.0;
  double baseline = 0.10;
  bool raw = false;
  int supersample = 2;
  double noise = 1.0;
  double exposure = 1.0;
  std::uint32_t seed = 1;
  double breathing_phase = 0.0;
  double breathing_amplitude = 0.004;
  int frames = 1;
  double rate = 10.0;
  int views = 3;
  int boxes = 3;
  // Subject variety.
  int varied = 0;
  std::string build;
  double bmi = 24.0, stature = 1.75;
  int skin_type = 0;
  // Dressing.
  std::string arms = "none";
  double arm_angle = 0.0, arm_angle_right = -1.0;
  bool head = false, lower_body = false;
  std::string hair = "short", hair_colour = "brown", cradle_cover;
  std::string towel, towel_weave = "terry", towel_edge = "L4-0.03";
  double towel_tilt = 0.0;
  std::string sheet, sheet_weave = "fine";
  std::vector<std::string> stickers;  ///< --sticker LANDMARK=COLOUR
  double sticker_size = 0.025;
  // Rig.
  double toe_in = 0.0;
  std::string frame_top, frame_bottom;
  std::vector<std::string> given;  ///< options given on the command line
};

/// Parses the command line into `o` and checks it (the back preset's subject, dressing and rig built once); prints
/// the help and returns false on --help / -h. Throws UsageError.
bool parseOptions(int argc, char** argv, Options& o);

}  // namespace massage_cell::tools::render_scene
