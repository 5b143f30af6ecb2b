#include "render_scene_options.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <stdexcept>

#include "cli.h"
#include "massage_cell/sim/cell_scene.h"
#include "render_scene_setup.h"

namespace massage_cell::tools::render_scene {
namespace {

const char* const kUsage = R"(Usage: render_scene --preset PRESET --out DIR [options]

Renders a scene of the massage cell by ray tracing (Embree) and writes the
images with their exact ground truth into DIR (created if missing).

Presets:
  back                 a subject lying prone on the massage table under the stereo camera
  boxes                textured boxes stacked on the table (planar reconstruction)
  efficiency_layers    thesis Fig. 2.9: fronto-parallel layers; left view and right
                       views R1..R8 spanning 8, 16, ..., 64 disparity levels
  efficiency_gradient  thesis Fig. 2.10: one slanted plane; same views
  multiview            --views calibrated views of the boxes scene

Options:
  --out DIR                output folder (required)
  --subject N              0 = the mean subject, 1..28 = the thesis's 28 subjects (default 0)
  --body-seed S            seed the 28 subjects (and the varied population) are drawn from (default 2024)
  --varied N               instead of --subject: subject N >= 1 of a wide population (male/female,
                           BMI 18..38, every Fitzpatrick skin type; BodyParameters::varied)
  --build SEX              instead of --subject: a male | female build, with --bmi B (default 24)
                           and --stature M (metres, default 1.75)
  --skin-type T            Fitzpatrick skin type 1..6: overrides the subject's skin colour

Dressing of the back preset (default: none of it, the bare back):
  --arms POSE              none | along (along the trunk) | raised (beside the head) (default none)
  --arm-angle DEG          along: abduction of both arms about the shoulders, 0 (touching the
                           flank) .. 20 degrees (default 0)
  --arm-angle-right DEG    the right arm's abduction if it differs (default: --arm-angle)
  --head                   the neck and the head face-down in a face cradle (the table then
                           ends at the shoulders)
  --hair LENGTH            with --head: none | short | nape | long (default short)
  --hair-colour C          black | brown | blond | grey | red (default brown)
  --cradle-cover COLOUR    a cloth cover on the cradle's pad (default: dark vinyl)
  --lower-body             the buttocks down to the gluteal fold and the upper thighs
  --towel COLOUR           a towel over the buttocks / lower back (implies --lower-body)
  --towel-weave W          fine | terry | waffle | stripes | checks (default terry)
  --towel-edge POS         the towel's cranial edge (default L4-0.03)
  --towel-tilt DEG         turn of the towel's edge about the vertical (default 0)
  --sheet COLOUR           the table's sheet colour (default: the standard blue-grey sheet)
  --sheet-weave W          fine | terry | waffle | stripes | checks (default fine)
  --sticker LANDMARK=C     a coloured skin marker on a landmark of the back (C7, T1..L5,
                           scapula_inferior_angle_L, iliac_crest_R, ...), repeatable; C: green,
                           blue, orange, magenta, yellow; e.g. --sticker C7=green --sticker L4=blue
  --sticker-size M         the stickers' diameter, metres (default 0.025)
  Colours: white, light_blue, green, grey, beige, peach, pink, dark_blue, black, default_sheet.
  POS: a world x in metres (x toward the head, 0 at C7), or a vertebral level with an
  optional offset in metres toward the head (+) or feet (-), e.g. C7+0.05, L4-0.18.

Camera:
  --light L                top_left | top_centre | top_right (default top_centre)
  --shift M                camera shift along the table, metres (thesis: 0, 0.04, 0.07, 0.14; default 0)
  --camera-height Z        height of the cameras above the table top, metres (default 0.95)
  --width W --height H     image size (default 640 x 480)
  --fx F                   focal length, pixels (default 500)
  --baseline B             stereo baseline, metres (default 0.10)
  --raw                    unrectified pair with lens distortion (default: rectified, ideal)
  --toe-in DEG             raw pairs: each camera turned toward the other by DEG (default 0)
  --frame-top POS          place the cameras so that the left image's top edge meets the back's
  --frame-bottom POS       height at POS and its bottom edge at the other POS (both needed;
                           replaces --shift / --camera-height), e.g. C7+0.06 and L4-0.2

Rendering:
  --supersample N          rays per pixel N x N (default 2)
  --noise SIGMA            sensor noise, grey levels (default 1.0)
  --exposure E             exposure factor (default 1.0)
  --seed S                 seed of textures and noise (default 1)
  --breathing-phase P      0..1, phase of the breath (default 0)
  --breathing-amplitude A  metres (default 0.004)
  --frames N               back preset: a session of N frames of the breathing subject (default 1)
  --rate HZ                frames per second of a session (default 10; a breath lasts 4 s)
  --views N                multiview: number of views (default 3)
  --boxes N                boxes / multiview: number of stacked boxes (default 3)
  -h, --help               print this help

Output (stereo presets, one frame): left.png right.png, left_depth.pfm right_depth.pfm
(metres, z in each optical frame), left_points.pfm right_points.pfm (XYZ in each optical
frame), left_disparity.pfm right_disparity.pfm (pixels; rectified pairs only),
left_labels.png right_labels.png (labels below), left_visible.png (255: seen by the right camera too),
left_camera_info.yaml right_camera_info.yaml (ROS calibration), acupoints.yaml and
landmarks.yaml (back: name -> [x, y, z] in the left optical frame, metres; landmarks.yaml
also holds the spine midline), acupoints_truth.yaml (back: per acupoint and landmark its
left optical position, raw left and right pixels, the label at its left pixel, in_view and
the reason when not in view), preview.png (left | right | GT disparity | acupoints in view
green, not in view red, landmarks blue), manifest.yaml.
Labels: 0 background, 1 back (and buttocks), 2 table, 3 floor, 4 arm, 5 neck, 6 head,
7 hair, 8 towel, 9 plane, 10+ box faces, 250 face cradle.
A session (--frames > 1) writes left_NNNN.png / right_NNNN.png, the calibrations,
ground_truth.yaml (per frame: time, breathing phase, acupoints, the acupoints in view) and
manifest.yaml.
Exit status: 0 success, 1 rendering or writing failed (or the back is not in view),
2 bad command line.
)";

bool given(const Options& o, const std::string& option) {
  return std::find(o.given.begin(), o.given.end(), option) != o.given.end();
}

/// The subject, dressing and rig options: names known, ranges, combinations.
void checkCellOptions(const Options& o) {
  auto known = [](auto parse, const std::string& value) {
    try {
      parse(value);
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
  };
  require(o.varied >= 0, "--varied must be >= 1");
  require(o.build.empty() || o.build == "male" || o.build == "female",
          "--build must be male or female, got '" + o.build + "'");
  require(!(given(o, "--subject") + given(o, "--varied") + !o.build.empty() > 1),
          "--subject, --varied and --build are exclusive");
  require((!given(o, "--bmi") && !given(o, "--stature")) || !o.build.empty(), "--bmi and --stature need --build");
  require(o.skin_type == 0 || (o.skin_type >= 1 && o.skin_type <= 6), "--skin-type must be in 1..6");
  known(sim::armPoseFromName, o.arms);
  require(o.arm_angle >= 0.0 && o.arm_angle <= 20.0, "--arm-angle must be in 0..20 degrees");
  require(o.arm_angle_right < 0.0 || o.arm_angle_right <= 20.0, "--arm-angle-right must be in 0..20 degrees");
  known(sim::hairLengthFromName, o.hair);
  known(sim::hairColourFromName, o.hair_colour);
  for (const std::string* c : {&o.cradle_cover, &o.towel, &o.sheet}) {
    if (!c->empty()) known(sim::clothColour, *c);
  }
  known(sim::weaveFromName, o.towel_weave);
  known(sim::weaveFromName, o.sheet_weave);
  require(std::abs(o.towel_tilt) <= 15.0, "--towel-tilt must be in -15..15 degrees");
  require(o.toe_in >= 0.0 && o.toe_in <= 15.0, "--toe-in must be in 0..15 degrees");
  require(o.toe_in == 0.0 || o.raw, "--toe-in needs --raw (a toe-in pair is not rectified)");
  require(o.frame_top.empty() == o.frame_bottom.empty(), "--frame-top and --frame-bottom go together");
  const bool cell = o.arms != "none" || o.head || o.lower_body || !o.towel.empty() || !o.sheet.empty() ||
                    !o.stickers.empty() || o.varied > 0 || !o.build.empty() || o.skin_type > 0 || !o.frame_top.empty();
  require(!cell || o.preset == "back", "subject, dressing and framing options are for the back preset");
}

using Setter = std::function<void(const std::string& option, const std::string& value)>;

Setter text(std::string& field) {
  return [&field](const std::string&, const std::string& v) { field = v; };
}
Setter integer(int& field) {
  return [&field](const std::string& opt, const std::string& v) { field = parseInt(opt, v); };
}
Setter number(double& field) {
  return [&field](const std::string& opt, const std::string& v) { field = parseDouble(opt, v); };
}
Setter seed(std::uint32_t& field) {
  return [&field](const std::string& opt, const std::string& v) { field = parseSeed(opt, v); };
}

/// Every option, each value option noting in Options::given that it was given.
OptionTable optionTable(Options& o) {
  OptionTable t;
  t.values = {{"--preset", text(o.preset)},
              {"--out", text(o.out)},
              {"--subject", integer(o.subject)},
              {"--body-seed", seed(o.body_seed)},
              {"--light", text(o.light)},
              {"--shift", number(o.shift)},
              {"--camera-height", number(o.camera_height)},
              {"--width", integer(o.width)},
              {"--height", integer(o.height)},
              {"--fx", number(o.fx)},
              {"--baseline", number(o.baseline)},
              {"--supersample", integer(o.supersample)},
              {"--noise", number(o.noise)},
              {"--exposure", number(o.exposure)},
              {"--seed", seed(o.seed)},
              {"--breathing-phase", number(o.breathing_phase)},
              {"--breathing-amplitude", number(o.breathing_amplitude)},
              {"--frames", integer(o.frames)},
              {"--rate", number(o.rate)},
              {"--views", integer(o.views)},
              {"--boxes", integer(o.boxes)},
              {"--varied", integer(o.varied)},
              {"--build", text(o.build)},
              {"--bmi", number(o.bmi)},
              {"--stature", number(o.stature)},
              {"--skin-type", integer(o.skin_type)},
              {"--arms", text(o.arms)},
              {"--arm-angle", number(o.arm_angle)},
              {"--arm-angle-right", number(o.arm_angle_right)},
              {"--hair", text(o.hair)},
              {"--hair-colour", text(o.hair_colour)},
              {"--cradle-cover", text(o.cradle_cover)},
              {"--towel", text(o.towel)},
              {"--towel-weave", text(o.towel_weave)},
              {"--towel-edge", text(o.towel_edge)},
              {"--towel-tilt", number(o.towel_tilt)},
              {"--sheet", text(o.sheet)},
              {"--sheet-weave", text(o.sheet_weave)},
              {"--sticker", [&o](const std::string&, const std::string& v) { o.stickers.push_back(v); }},
              {"--sticker-size", number(o.sticker_size)},
              {"--toe-in", number(o.toe_in)},
              {"--frame-top", text(o.frame_top)},
              {"--frame-bottom", text(o.frame_bottom)}};
  t.flags = {{"--raw", [&o] { o.raw = true; }}, {"--head", [&o] { o.head = true; }}, {"--lower-body", [&o] {
                                                                                        o.lower_body = true;
                                                                                      }}};
  for (auto& [name, setter] : t.values) {
    setter = [&o, name = name, inner = setter](const std::string& opt, const std::string& v) {
      o.given.push_back(name);
      inner(opt, v);
    };
  }
  return t;
}

/// The preset, the output folder and the ranges of the numbers.
void checkRanges(const Options& o) {
  static const std::vector<std::string> presets{"back", "boxes", "efficiency_layers", "efficiency_gradient",
                                                "multiview"};
  require(!o.preset.empty(), "--preset is required (back, boxes, efficiency_layers, efficiency_gradient, multiview)");
  require(std::find(presets.begin(), presets.end(), o.preset) != presets.end(),
          "unknown preset '" + o.preset + "' (back, boxes, efficiency_layers, efficiency_gradient, multiview)");
  require(!o.out.empty(), "--out: an output folder is required");
  require(o.subject >= 0 && o.subject <= 28, "unknown subject " + std::to_string(o.subject) + " (0 = mean, 1..28)");
  require(o.light == "top_left" || o.light == "top_centre" || o.light == "top_right",
          "--light must be top_left, top_centre or top_right, got '" + o.light + "'");
  require(o.width >= 1 && o.width <= 16384 && o.height >= 1 && o.height <= 16384,
          "--width / --height must be in 1..16384, got " + std::to_string(o.width) + "x" + std::to_string(o.height));
  require(o.fx > 0.0, "--fx must be > 0");
  require(o.baseline > 0.0 && o.baseline < 2.0, "--baseline must be in (0, 2) metres");
  require(o.camera_height > 0.0, "--camera-height must be > 0");
  require(o.supersample >= 1 && o.supersample <= 8, "--supersample must be in 1..8");
  require(o.noise >= 0.0, "--noise must be >= 0");
  require(o.exposure > 0.0, "--exposure must be > 0");
  require(o.breathing_phase >= 0.0 && o.breathing_phase <= 1.0, "--breathing-phase must be in [0, 1]");
  require(o.breathing_amplitude >= 0.0 && o.breathing_amplitude <= 0.03,
          "--breathing-amplitude must be in [0, 0.03] m");
  require(o.frames >= 1 && o.frames <= 10000, "--frames must be in 1..10000");
  require(o.frames == 1 || o.preset == "back", "--frames > 1 is for the back preset");
  require(o.rate > 0.0 && o.rate <= 1000.0, "--rate must be in (0, 1000] Hz");
  require(o.views >= 1 && o.views <= 64, "--views must be in 1..64");
  require(o.boxes >= 1 && o.boxes <= 40, "--boxes must be in 1..40");
}

}  // namespace

bool parseOptions(int argc, char** argv, Options& o) {
  const OptionTable t = optionTable(o);
  if (!parseArguments(argc, argv, t, kUsage)) return false;
  checkRanges(o);
  checkCellOptions(o);
  if (o.preset == "back") checkBackSetup(o);
  return true;
}

}  // namespace massage_cell::tools::render_scene
