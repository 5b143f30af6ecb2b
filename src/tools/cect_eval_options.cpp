#include "cect_eval_options.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <system_error>
#include <vector>

#include "cect_params.h"
#include "cect_scenes.h"
#include "cli.h"
#include "massage_cell/sim/cell_scene.h"
#include "package_paths.h"

namespace massage_cell::tools::cect_eval {
namespace {

const char* kUsage = R"(Usage: cect_eval [--experiments ideal,lighting,shift] [--subjects N] [--condition-subjects K]
                 [--random-points N] [--width W --height H --fx F --baseline B --camera-height Z]
                 [--yaw DEG] [--raw] [--acupoints FILE] [--seed-step N] [--query-search PX]
                 [--param NAME=VALUE,...] [--csv] [--per-point] [--no-parallax-correction]
                 [--no-3d-levels] [--pictures DIR] [--by-border] [--given-landmarks MM] [--given-levels LIST]
                 [--confirm-given] [--conditions LIST] [--first-subject N] [--no-layout-check] [--trust-c7-at-top]
                 [--trust-inferred-l4]

Renders prone subjects with the scene simulator and localises points on their
backs with CECT (segmentation -> contour correspondences -> barycentric
transfer -> constraints -> 3D) and, at the same left pixels, with dense
StereoSGBM on the same rectified pair. Errors are 3D distances to the exact
surface point seen at that pixel (the simulator's ground truth), in mm.
Experiments (the thesis's Sec. 3.3):
  ideal      subjects 1..N (default 28), light top-centre, no camera shift
  lighting   subjects 1..K (default 8) under lights top-left / top-centre / top-right
  shift      subjects 1..K with the camera shifted 0 / 4 / 7 / 14 cm along the table
  real       the cell as it is (not in the default set): subjects 1..K of a wide
             population (BodyParameters::varied: both sexes, BMI 18-38, six skin
             types) with arms, head in a face cradle, hair, buttocks, sheets of
             several colours, the neck and hips framed in or out of view, under
             the conditions arms_touching, arms_apart (8-20 degrees), arms_raised,
             neck_cut (the image's top edge 1-5 cm above C7), hips_cut (the view
             ending between L2 and mid-buttocks), towel (over the buttocks, many
             colours and weaves), dark_skin (Fitzpatrick V-VI), toe_in (raw
             toe-in rigs, 1-4 degrees, baselines 6-12 cm), mixed (all drawn
             at random), skin_marks (paper tags on acupoints, a strap or a seam
             across the back, tattoos, moles; printed sheets) and photo (colour
             casts, vignetting, motion blur, JPEG; src/tools/cect_scenes.cpp)
Point sets: `acupoints` (every point of the acupoint model, placed by the model
from the left view) and `random` (N random back pixels seen by both cameras,
at least 8 px inside the back's border; default 100 per pair).
p95: the 95th percentile of the localised points' errors.
acc_rate: share of the queried points localised with an error < 10 mm (a point
a method cannot localise counts as a miss). `model` reports how far the model's
placed acupoints lie from the anatomical ones (independent of the matching).
CECT ms: segmentation to 3D acupoints per pair (2 cores).
  --yaw DEG    the subject lies turned by DEG degrees on the table (about the
               vertical through the back's centre; + turns the head toward the
               image right, clockwise on screen): every condition, the ground
               truth turned with it
  --param      set CECT parameters by their CectParams names, e.g.
               --param ncc_radius=9,smooth_radius=2 (see cect.h)
  --csv        print CSV: condition,subject,method,points,mean_mm,max_mm,acc_rate
               (method "model", points "layout": the placed acupoints' layout error)
  --pictures DIR  write every pair's picture to DIR/<condition>_s<subject>.png:
               the rectified left view, the back's contour (magenta), the model's
               midline (yellow), each placed acupoint coloured by CECT's 3D error
               there (green < 5 mm, orange < 10 mm, red >= 10 mm or not
               localised) and the anatomical acupoints (white crosses)
  --no-3d-levels  the waist and the vertebral levels in image rows only (the
               default moves the waist to the spine's height and spaces the
               levels along the body's axis in CECT's 3D: correctWaistParallax,
               measureLevelsIn3D)
  --no-parallax-correction  place the acupoints from the silhouette's centre
               line as it is (the default moves it onto the skin's midline in 3D:
               correctMidlineParallax)
  --given-landmarks MM  the therapist's landmarks: C7 and L4 given to the
               chain as a palpating therapist would click them, each up to MM mm
               (uniform over a disc on the skin, seeded per subject) from the
               simulator's true C7 and iliac-crest line (cect/given_landmarks.h)
  --given-levels LIST  which landmarks --given-landmarks gives, of C7, T7
               (the scapulae's inferior angles' line), L4 (default C7,L4)
  --confirm-given  the clicks confirmed (~set_landmark's confirm): a pair whose
               own C7 or L4 disagrees with them is not refused for it
  --skin-markers  the kit's coloured skin markers (config/skin_markers.yaml, or
               --marker-kit FILE) stuck on each subject's landmarks, rendered, and
               found by the chain in both views (cect/skin_markers.h)
  --marker-kit FILE  the skin-marker kit for --skin-markers
  --no-layout-check  publish every layout the chain finds (the default refuses
               one that fails the plausibility checks: cect/layout_check.h)
  --trust-c7-at-top  trust a C7 taken from the back's top where no neck is in
               view (the default refuses it: the thesis's armless torso, the
               ideal / lighting / shift experiments, has no neck, its back ends
               at the neck's base)
  --trust-inferred-l4  trust an L4 inferred from C7 and the shoulder width where
               no waist is seen (the default refuses it)
  --conditions LIST  the realistic conditions to run, comma-separated (default:
               all of them, in the order above)
  --first-subject N  the realistic conditions' subjects start at N (default 1;
               the figures of docs/ were tuned on 1..28: 29.. are unseen)
  --per-point  also print, per condition, every acupoint's CECT figures over the
               subjects and the commonest reason it was not localised
  --by-border  also print, per condition, both methods' figures on every 4th
               back pixel (seen by both cameras) by its distance to the back's
               border in the left view (bands 0-8, 8-15, 15-30, 30-45, >= 45 px,
               scaled by the width / 640): what a caller of ~localize_pixels
               gets near the flanks and the shoulders' top, and how well CECT's
               uncertainty covers it (median disparity sigma; share of the
               disparity errors within 2 sigma, 95 % when calibrated)
)";

/// --experiments, --conditions and the subjects and points each runs on.
void addExperimentOptions(OptionTable& t, Options& o) {
  t.values["--experiments"] = [&o](const std::string& opt, const std::string& v) {
    o.experiments = splitList(v);
    require(!o.experiments.empty(), opt + ": empty list");
    for (const auto& e : o.experiments)
      require(e == "ideal" || e == "lighting" || e == "shift" || e == "real",
              opt + ": unknown experiment '" + e + "' (ideal, lighting, shift, real)");
  };
  t.values["--conditions"] = [&o](const std::string& opt, const std::string& v) {
    o.conditions = splitList(v);
    const auto& known = realConditions();
    for (const auto& c : o.conditions)
      require(std::find(known.begin(), known.end(), c) != known.end(),
              opt + ": unknown realistic condition '" + c + "'");
    require(!o.conditions.empty(), opt + ": empty list");
  };
  t.values["--subjects"] = [&o](const std::string& opt, const std::string& v) {
    o.subjects = parseInt(opt, v);
    require(o.subjects >= 1 && o.subjects <= 28, opt + " must be in 1..28");
  };
  t.values["--condition-subjects"] = [&o](const std::string& opt, const std::string& v) {
    o.condition_subjects = parseInt(opt, v);
    require(o.condition_subjects >= 1 && o.condition_subjects <= 28, opt + " must be in 1..28");
  };
  t.values["--first-subject"] = [&o](const std::string& opt, const std::string& v) {
    o.first_subject = parseInt(opt, v);
    require(o.first_subject >= 1 && o.first_subject <= 10000, opt + " must be in 1..10000");
  };
  t.values["--random-points"] = [&o](const std::string& opt, const std::string& v) {
    o.random_points = parseInt(opt, v);
    require(o.random_points >= 0, opt + " must be >= 0");
  };
}

/// The rig and the subject's pose: --width, --height, --fx, --baseline, --camera-height, --yaw, --raw.
void addRigOptions(OptionTable& t, Options& o) {
  t.values["--width"] = [&o](const std::string& opt, const std::string& v) { o.width = parseInt(opt, v); };
  t.values["--height"] = [&o](const std::string& opt, const std::string& v) { o.height = parseInt(opt, v); };
  t.values["--fx"] = [&o](const std::string& opt, const std::string& v) { o.fx = parseDouble(opt, v); };
  t.values["--baseline"] = [&o](const std::string& opt, const std::string& v) { o.baseline = parseDouble(opt, v); };
  t.values["--camera-height"] = [&o](const std::string& opt, const std::string& v) {
    o.camera_height = parseDouble(opt, v);
  };
  t.values["--yaw"] = [&o](const std::string& opt, const std::string& v) {
    o.yaw_deg = parseDouble(opt, v);
    require(std::abs(o.yaw_deg) <= 45.0, opt + " must be within +-45 degrees");
  };
  t.flags["--raw"] = [&o] { o.raw = true; };
}

/// CECT's set-up: --acupoints, --seed-step, --query-search, --param and the chain's switches.
void addCectOptions(OptionTable& t, Options& o) {
  t.values["--acupoints"] = [&o](const std::string&, const std::string& v) { o.acupoints = v; };
  t.values["--seed-step"] = [&o](const std::string& opt, const std::string& v) {
    o.seed_step = parseInt(opt, v);
    require(o.seed_step >= 0, opt + " must be >= 0");
  };
  t.values["--query-search"] = [&o](const std::string& opt, const std::string& v) {
    o.query_search = parseDouble(opt, v);
    require(o.query_search >= 0, opt + " must be >= 0");
  };
  t.values["--param"] = [&o](const std::string& opt, const std::string& v) {
    for (const std::string& kv : splitList(v)) {
      const auto eq = kv.find('=');
      require(eq != std::string::npos, opt + ": expected NAME=VALUE, got '" + kv + "'");
      const std::string name = kv.substr(0, eq);
      require(paramSetters().count(name) > 0, opt + ": unknown CECT parameter '" + name + "'");
      o.params.emplace_back(name, parseDouble(opt + " " + name, kv.substr(eq + 1)));
    }
  };
  t.flags["--no-layout-check"] = [&o] { o.layout_check = false; };
  t.flags["--trust-c7-at-top"] = [&o] { o.trust_c7_at_top = true; };
  t.flags["--trust-inferred-l4"] = [&o] { o.trust_inferred_l4 = true; };
  t.flags["--no-parallax-correction"] = [&o] { o.parallax = false; };
  t.flags["--no-3d-levels"] = [&o] { o.levels_3d = false; };
}

/// The therapist's landmarks: --given-landmarks, --given-levels, --confirm-given; --skin-markers, --marker-kit.
void addLandmarkOptions(OptionTable& t, Options& o, bool& skin_markers) {
  t.values["--given-landmarks"] = [&o](const std::string& opt, const std::string& v) {
    o.given_mm = parseDouble(opt, v);
    require(o.given_mm >= 0.0 && o.given_mm <= 100.0, opt + " must be in 0..100 mm");
  };
  t.values["--given-levels"] = [&o](const std::string& opt, const std::string& v) {
    o.given_levels = splitList(v);
    require(!o.given_levels.empty(), opt + ": empty list");
    for (const auto& n : o.given_levels)
      require(n == "C7" || n == "T7" || n == "L4", opt + ": unknown landmark '" + n + "' (C7, T7, L4)");
  };
  t.flags["--confirm-given"] = [&o] { o.confirm_given = true; };
  t.flags["--skin-markers"] = [&skin_markers] { skin_markers = true; };
  t.values["--marker-kit"] = [&o](const std::string&, const std::string& v) { o.marker_kit = v; };
}

/// What is reported: --csv, --per-point, --by-border, --pictures.
void addReportOptions(OptionTable& t, Options& o) {
  t.flags["--csv"] = [&o] { o.csv = true; };
  t.flags["--per-point"] = [&o] { o.per_point = true; };
  t.flags["--by-border"] = [&o] { o.by_border = true; };
  t.values["--pictures"] = [&o](const std::string& opt, const std::string& v) {
    require(!v.empty(), opt + " needs a folder");
    std::error_code ec;
    std::filesystem::create_directories(v, ec);
    require(!ec && std::filesystem::is_directory(v), opt + ": cannot create the folder '" + v + "'");
    o.pictures = v;
  };
}

/// --skin-markers: the kit, every sticker in a colour the simulator has.
cect::SkinMarkerOptions loadKit(const std::string& path) {
  const std::string file = path.empty() ? tools::packageFile("config/skin_markers.yaml") : path;
  cect::SkinMarkerOptions kit;
  try {
    kit = cect::loadSkinMarkerOptions(file);
    for (const cect::SkinMarkerSpec& m : kit.markers) (void)sim::stickerColour(m.colour);
  } catch (const std::exception& e) {
    tools::require(false, std::string("--skin-markers: ") + e.what());
  }
  return kit;
}

}  // namespace

bool parseOptions(int argc, char** argv, Options& o) {
  OptionTable t;
  bool skin_markers = false;
  addExperimentOptions(t, o);
  addRigOptions(t, o);
  addCectOptions(t, o);
  addLandmarkOptions(t, o, skin_markers);
  addReportOptions(t, o);
  if (!parseArguments(argc, argv, t, kUsage)) return false;
  require(o.width >= 64 && o.height >= 48, "--width/--height too small");
  require(o.fx > 0 && o.baseline > 0 && o.camera_height > 0.3,
          "--fx, --baseline must be > 0 and --camera-height > 0.3 m");
  require(skin_markers || o.marker_kit.empty(), "--marker-kit needs --skin-markers");
  if (skin_markers) o.markers = loadKit(o.marker_kit);
  return true;
}

}  // namespace massage_cell::tools::cect_eval
