// cect_eval's command line: what a run measures, on which subjects and rig,
// and how CECT is set up (cect_eval_options.cpp: the help, the parsing).
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "massage_cell/cect/skin_markers.h"

namespace massage_cell::tools::cect_eval {

struct Options {
  std::vector<std::string> experiments{"ideal", "lighting", "shift"};
  std::vector<std::string> conditions;  ///< --conditions: the realistic ones to run (empty: all)
  int subjects = 28;
  int condition_subjects = 8;
  int random_points = 100;
  int width = 640, height = 480;
  double fx = 500.0, baseline = 0.10, camera_height = 0.95;
  double yaw_deg = 0.0;  ///< the subject turned on the table
  bool raw = false;
  bool csv = false;
  bool per_point = false;
  bool by_border = false;  ///< --by-border
  double given_mm = -1.0;  ///< --given-landmarks: C7 and L4 clicked within this many mm (< 0: none given)
  std::vector<std::string> given_levels{"C7", "L4"};  ///< --given-levels: which ones are clicked
  bool confirm_given = false;      ///< --confirm-given: the clicks confirmed over the pair's own landmarks
  int first_subject = 1;           ///< --first-subject (the realistic conditions)
  bool layout_check = true;        ///< --no-layout-check: false
  bool trust_c7_at_top = false;    ///< --trust-c7-at-top
  bool trust_inferred_l4 = false;  ///< --trust-inferred-l4
  std::string marker_kit;          ///< --marker-kit (empty: the package's config/skin_markers.yaml)
  std::optional<cect::SkinMarkerOptions> markers;  ///< --skin-markers: the kit, rendered and looked for
  bool parallax = true;                            ///< the model's midline corrected for the silhouette's parallax (3D)
  bool levels_3d = true;                           ///< the levels spaced along the body's axis in 3D
  std::string acupoints;
  std::string pictures;  ///< --pictures: a folder for every pair's picture
  int seed_step = -1;
  double query_search = -1.0;
  std::vector<std::pair<std::string, double>> params;  ///< --param
};

/// Parses the command line into `o`; prints the help and returns false on --help / -h. Throws UsageError.
bool parseOptions(int argc, char** argv, Options& o);

}  // namespace massage_cell::tools::cect_eval
