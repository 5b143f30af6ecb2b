// stereo_bag_eval: the hbds node's acupoint depth on recorded sessions (rosbags/*.bag with their
// *.ground_truth.yaml), the figure of the target "acupoint depth on the bundled recording: median <= 4 mm, >= 95 %
// within 1 cm". Every stereo pair of a bag is prepared as the node prepares it (src/nodes/hbds_views.h: the node's
// own code), matched with the library's parameters and the node's range (config/hbds.yaml), turned into depth as
// the node publishes it (REP 118), and each acupoint of the pair's ground-truth frame is scored as the node's rostest
// does (test/ros/test_hbds_node.cpp): the median depth of its 5x5 neighbourhood against the truth, no depth counting
// as 1 m off.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <yaml-cpp/yaml.h>
#include <Eigen/Core>

#include "../nodes/hbds_views.h"
#include "../nodes/stereo_messages.h"
#include "../nodes/stereo_pair_input.h"
#include "massage_cell/stereo/memory.h"
#include "package_paths.h"
#include "stereo_params.h"

namespace {

namespace stereo = massage_cell::stereo;
namespace camera = massage_cell::camera;
namespace nodes = massage_cell::nodes;
namespace fs = std::filesystem;
using namespace massage_cell::tools;

constexpr double kTargetMedianMm = 4.0;    // the issue's target: median |error| <= 4 mm ...
constexpr double kTargetWithinPct = 95.0;  // ... and >= 95 % of the acupoints within
constexpr double kWithinMm = 10.0;         // 10 mm
constexpr double kNoDepthError = 1.0;      // m: an acupoint without depth in its 5x5 neighbourhood

const char* const kUsageHead = R"(Usage: stereo_bag_eval [--recordings back_session,dressed_session,markers_session]
                       [--ground-truth FILE] [--config FILE] [--min-disparity D] [--disparity-range N]
                       [--downsample 1|2|4] [--method hbds|sgbm|wta] [--no-lr-fill] [--stereo-ns NS]
                       [--max-pairs N] [--csv] [stereo options]

The hbds node's acupoint depth on recorded sessions. Every stereo pair of a
bag (NS/left/image_raw + camera_info, NS/right/..., exact stamps) is prepared
as the node prepares it (rectified from its camera_info, shrunk at
--downsample), matched with the options below and the node's disparity range
(full-resolution pixels, from --config), and turned into depth as the node
publishes it. Each acupoint of the pair's ground-truth frame (frame
round((stamp - first camera_info stamp) * rate)) is projected into the depth
image; its error is the median depth of its 5x5 neighbourhood minus the
truth's depth (no depth there: 1 m off). One row per recording: pairs,
acupoints, median / p90 |error| (mm), % within 10 mm, acupoints without depth,
median signed error (measured - truth, over those with depth) and the mean
time a pair (preparing, matching, depth); then whether the target (median
<= 4 mm and >= 95 % within 10 mm) is met per recording. Exit status 0 whether
met or not; 2 for a bad option, 1 for bad input (named).

  --recordings LIST  comma-separated: names of the bundled recordings in the
                     package's rosbags/ (default back_session,dressed_session,
                     markers_session), or paths to .bag files; the ground truth
                     is next to each bag as NAME.ground_truth.yaml
  --ground-truth FILE  this ground truth instead (one recording only)
  --config FILE      the node's parameters: min_disparity, disparity_range and
                     rectify, max_pixels, downsample, method, lr_fill when set
                     (default the package's config/hbds.yaml)
  --min-disparity D  overrides the config's (full-resolution pixels)
  --disparity-range N  overrides the config's (levels)
  --downsample F     process at 1/F resolution, 1, 2 or 4 (default the config's, else 1)
  --method M         hbds, sgbm or wta (default the config's, else hbds)
  --no-lr-fill       with the left-right check, unconfirmed pixels have no depth
                     (the node's lr_fill false; default: filled, as the node)
  --stereo-ns NS     the pairs' namespace in the bag (default /stereo)
  --max-pairs N      only the first N pairs of each bag (0: all; default 0)
  --csv              print CSV (with a target_met column) instead of the table
  --worst N          also list, per recording, the N acupoints with the largest median |error| over
                     the pairs (name, median |error| and signed error in mm) (default 0: none)
)";

struct Options {
  std::vector<std::string> recordings{"back_session", "dressed_session", "markers_session"};
  std::string ground_truth, config;
  std::optional<int> min_disparity, disparity_range, downsample;
  std::optional<std::string> method;
  bool no_lr_fill = false;
  std::string ns = "/stereo";
  int max_pairs = 0;
  int worst = 0;
  bool csv = false;
  stereo::StereoParams params;
};

bool parse(int argc, char** argv, Options& o) {
  OptionTable t;
  t.values["--recordings"] = [&](const std::string&, const std::string& v) { o.recordings = splitList(v); };
  t.values["--ground-truth"] = [&](const std::string&, const std::string& v) { o.ground_truth = v; };
  t.values["--config"] = [&](const std::string&, const std::string& v) { o.config = v; };
  t.values["--min-disparity"] = [&](const std::string& opt, const std::string& v) {
    o.min_disparity = parseInt(opt, v);
  };
  t.values["--disparity-range"] = [&](const std::string& opt, const std::string& v) {
    o.disparity_range = parseInt(opt, v);
  };
  t.values["--downsample"] = [&](const std::string& opt, const std::string& v) { o.downsample = parseInt(opt, v); };
  t.values["--method"] = [&](const std::string&, const std::string& v) { o.method = v; };
  t.flags["--no-lr-fill"] = [&] { o.no_lr_fill = true; };
  t.values["--stereo-ns"] = [&](const std::string&, const std::string& v) { o.ns = v; };
  t.values["--max-pairs"] = [&](const std::string& opt, const std::string& v) { o.max_pairs = parseInt(opt, v); };
  t.flags["--csv"] = [&] { o.csv = true; };
  t.values["--worst"] = [&](const std::string& opt, const std::string& v) { o.worst = parseInt(opt, v); };
  addStereoParams(t, o.params);
  const std::string text =
      std::string(kUsageHead) + "\nStereo options (the library's defaults, as the node's):\n" + stereoParamsHelp();
  if (!parseArguments(argc, argv, t, text.c_str())) return false;
  require(!o.recordings.empty(), "--recordings needs at least one recording");
  require(o.ground_truth.empty() || o.recordings.size() == 1,
          "--ground-truth needs exactly one recording (--recordings NAME)");
  require(o.max_pairs >= 0, "--max-pairs must be >= 0 (0: all)");
  require(o.worst >= 0, "--worst must be >= 0");
  require(!o.ns.empty(), "--stereo-ns must not be empty");
  if (o.downsample)
    require(*o.downsample == 1 || *o.downsample == 2 || *o.downsample == 4, "--downsample must be 1, 2 or 4");
  if (o.method)
    require(*o.method == "hbds" || *o.method == "sgbm" || *o.method == "wta", "--method must be hbds, sgbm or wta");
  if (o.min_disparity) require(*o.min_disparity >= 0, "--min-disparity must be >= 0");
  if (o.disparity_range) require(*o.disparity_range >= 2, "--disparity-range must be >= 2");
  checkStereoParams(o.params);
  return true;
}

// ------------------------------------------------------------ inputs --

/// The node's parameters the tool applies: config/hbds.yaml, then the options.
struct NodeSettings {
  int min_disparity = 16, disparity_range = 32, downsample = 1, max_pixels = 1200000;
  bool rectify = true, lr_fill = true;
  std::string method = "hbds";
};

NodeSettings readSettings(const Options& o) {
  NodeSettings s;
  const std::string path = o.config.empty() ? packageFile("config/hbds.yaml") : o.config;
  if (!fs::is_regular_file(path)) throw std::runtime_error("config '" + path + "' not found");
  try {
    const YAML::Node yaml = YAML::LoadFile(path);
    if (!yaml.IsMap()) throw std::runtime_error("not a map of parameters");
    for (const auto& entry : yaml) {
      const std::string key = entry.first.as<std::string>();
      const YAML::Node& value = entry.second;
      if (key == "min_disparity") {
        s.min_disparity = value.as<int>();
      } else if (key == "disparity_range") {
        s.disparity_range = value.as<int>();
      } else if (key == "downsample") {
        s.downsample = value.as<int>();
      } else if (key == "max_pixels") {
        s.max_pixels = value.as<int>();
      } else if (key == "rectify") {
        s.rectify = value.as<bool>();
      } else if (key == "lr_fill") {
        s.lr_fill = value.as<bool>();
      } else if (key == "method") {
        s.method = value.as<std::string>();
      } else if (key != "approximate_sync" && key != "queue_size") {  // the synchroniser's: no matter here
        std::fprintf(stderr, "stereo_bag_eval: %s: '%s' is not applied here (set it with the tool's option)\n",
                     path.c_str(), key.c_str());
      }
    }
  } catch (const YAML::Exception& e) {
    throw std::runtime_error("config '" + path + "': " + e.what());
  } catch (const std::runtime_error& e) {
    throw std::runtime_error("config '" + path + "': " + e.what());
  }
  if (o.min_disparity) s.min_disparity = *o.min_disparity;
  if (o.disparity_range) s.disparity_range = *o.disparity_range;
  if (o.downsample) s.downsample = *o.downsample;
  if (o.method) s.method = *o.method;
  if (o.no_lr_fill) s.lr_fill = false;
  require(s.min_disparity >= 0, "min_disparity must be >= 0, got " + std::to_string(s.min_disparity));
  require(s.disparity_range >= 2, "disparity_range must be >= 2, got " + std::to_string(s.disparity_range));
  require(s.downsample == 1 || s.downsample == 2 || s.downsample == 4,
          "downsample must be 1, 2 or 4 (the node's), got " + std::to_string(s.downsample));
  require(s.method == "hbds" || s.method == "sgbm" || s.method == "wta",
          "method must be hbds, sgbm or wta (the node's), got '" + s.method + "'");
  return s;
}

/// The acupoints of every frame (the left optical frame, metres); frame i at i / rate s after the first pair.
struct GroundTruth {
  double rate = 0.0;
  std::vector<std::vector<std::pair<std::string, Eigen::Vector3d>>> frames;
};

GroundTruth loadGroundTruth(const std::string& path) {
  GroundTruth gt;
  try {
    const YAML::Node yaml = YAML::LoadFile(path);
    if (!yaml.IsMap() || !yaml["rate"]) throw std::runtime_error("no 'rate' (frames a second)");
    gt.rate = yaml["rate"].as<double>();
    if (!(gt.rate > 0.0) || !std::isfinite(gt.rate)) throw std::runtime_error("'rate' must be > 0");
    const YAML::Node frames = yaml["frames"];
    if (!frames || !frames.IsSequence() || frames.size() == 0) throw std::runtime_error("no frames");
    for (const auto& frame : frames) {
      gt.frames.emplace_back();
      const YAML::Node points = frame["acupoints"];
      if (!points) continue;
      for (const auto& point : points) {
        const YAML::Node& p = point.second;
        if (!p.IsSequence() || p.size() != 3) {
          throw std::runtime_error("frame " + std::to_string(gt.frames.size() - 1) + ", acupoint " +
                                   point.first.as<std::string>() + ": expected [x, y, z]");
        }
        gt.frames.back().emplace_back(point.first.as<std::string>(),
                                      Eigen::Vector3d(p[0].as<double>(), p[1].as<double>(), p[2].as<double>()));
      }
    }
  } catch (const YAML::Exception& e) {
    throw std::runtime_error("ground truth '" + path + "': " + e.what());
  } catch (const std::runtime_error& e) {
    throw std::runtime_error("ground truth '" + path + "': " + e.what());
  }
  return gt;
}

/// A recording: its bag and ground truth.
struct Recording {
  std::string name, bag, ground_truth;
  GroundTruth gt;
};

/// Every recording's files, checked and their ground truth read before the first pair is matched.
std::vector<Recording> resolveRecordings(const Options& o) {
  std::vector<Recording> out;
  for (const std::string& item : o.recordings) {
    Recording r;
    const bool path = item.find('/') != std::string::npos || fs::path(item).extension() == ".bag";
    r.bag = path ? item : packageFile("rosbags/" + item + ".bag");
    r.name = fs::path(r.bag).stem().string();
    r.ground_truth = o.ground_truth.empty() ? (fs::path(r.bag).parent_path() / (r.name + ".ground_truth.yaml")).string()
                                            : o.ground_truth;
    if (!fs::is_regular_file(r.bag)) {
      throw std::runtime_error("recording '" + item + "': bag '" + r.bag + "' not found" +
                               (path ? "" : " (a bundled recording's name, or a path to a .bag)"));
    }
    if (!fs::is_regular_file(r.ground_truth)) {
      throw std::runtime_error("recording '" + item + "': ground truth '" + r.ground_truth + "' not found" +
                               (o.ground_truth.empty() ? " (expected next to the bag as NAME.ground_truth.yaml)" : ""));
    }
    r.gt = loadGroundTruth(r.ground_truth);
    out.push_back(std::move(r));
  }
  return out;
}

// ----------------------------------------------------------- scoring --

double median(std::vector<double> v) {  // the upper median, as the rostest's
  if (v.empty()) return std::nan("");
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

double percentile(std::vector<double> v, double q) {  // nearest rank
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  const auto rank = static_cast<std::size_t>(std::ceil(q * v.size()));
  return v[std::clamp<std::size_t>(rank, 1, v.size()) - 1];
}

/// The depth errors of one recording (metres).
struct Scores {
  std::vector<double> errors;         // |measured - truth|, kNoDepthError where no depth
  std::vector<double> signed_errors;  // measured - truth, where depth
  long no_depth = 0;
  std::map<std::string, std::vector<double>> signed_of;  // per acupoint, measured - truth (kNoDepthError: none)
};

/// Each acupoint against the median depth of its 5x5 neighbourhood in `depth` (the processed images' model).
void score(const cv::Mat& depth, const camera::StereoModel& model,
           const std::vector<std::pair<std::string, Eigen::Vector3d>>& acupoints, Scores* s) {
  for (const auto& [name, p] : acupoints) {
    std::vector<double> patch;
    double truth = std::nan("");
    if (p.z() > 0.0) {
      const Eigen::Vector3d q = model.project(p);                        // rectified x, y and disparity
      truth = model.fx() * model.baseline() / (q.z() - model.offset());  // depth along the rectified axis
      const int u = static_cast<int>(std::lround(q.x())), v = static_cast<int>(std::lround(q.y()));
      for (int dv = -2; dv <= 2; ++dv) {
        for (int du = -2; du <= 2; ++du) {
          const int x = u + du, y = v + dv;
          if (x < 0 || y < 0 || x >= depth.cols || y >= depth.rows) continue;
          const float value = depth.at<float>(y, x);
          if (std::isfinite(value)) patch.push_back(value);
        }
      }
    }
    if (patch.empty()) {
      s->errors.push_back(kNoDepthError);
      s->signed_of[name].push_back(kNoDepthError);
      ++s->no_depth;
      continue;
    }
    const double e = median(patch) - truth;
    s->errors.push_back(std::abs(e));
    s->signed_errors.push_back(e);
    s->signed_of[name].push_back(e);
  }
}

// ------------------------------------------------------ one recording --

/// An acupoint whose depth is off the most: the median over the pairs of |error| and of the signed error (mm).
struct WorstPoint {
  std::string name;
  double median_mm = 0, signed_mm = 0;
};

/// The `n` acupoints with the largest median |error| (largest first).
std::vector<WorstPoint> worstPoints(const Scores& s, int n) {
  std::vector<WorstPoint> all;
  for (const auto& [name, errors] : s.signed_of) {
    std::vector<double> magnitude;
    for (double e : errors) magnitude.push_back(std::abs(e));
    all.push_back({name, median(magnitude) * 1000.0, median(errors) * 1000.0});
  }
  const auto larger = [](const WorstPoint& a, const WorstPoint& b) { return a.median_mm > b.median_mm; };
  std::sort(all.begin(), all.end(), larger);
  if (static_cast<int>(all.size()) > n) all.resize(static_cast<std::size_t>(n));
  return all;
}

struct Row {
  std::string recording;
  std::vector<WorstPoint> worst;
  long pairs = 0, acupoints = 0, no_depth = 0;
  double median_mm = 0, p90_mm = 0, within_pct = 0, signed_mm = 0, ms_per_pair = 0;
  bool met() const { return median_mm <= kTargetMedianMm && within_pct >= kTargetWithinPct; }
};

std::string stampText(const ros::Time& t) { return format("%u.%09u", t.sec, t.nsec); }

/// The hbds node's depth of one pair: its views, its range, the match and REP 118 depth (processed images' model).
struct PairDepth {
  cv::Mat depth;
  nodes::HbdsViews views;
};

PairDepth matchPair(const Options& o, const NodeSettings& settings, const nodes::StereoPair& pair,
                    const nodes::FullModel& model_of) {
  PairDepth out;
  out.views = nodes::prepareHbdsViews(pair, settings.downsample, settings.max_pixels, model_of);
  stereo::StereoParams params = o.params;
  nodes::setHbdsRange(&params, settings.min_disparity, settings.disparity_range, settings.downsample, out.views);
  const stereo::MatchResult result =
      stereo::match(out.views.images[0], out.views.images[1], stereo::parseMethod(settings.method), params);
  const nodes::ValidDisparity valid = nodes::validDisparity(result, params, settings.lr_fill);
  out.depth = out.views.model.depth(valid.disparity);
  return out;
}

/// The recording's row from its scores.
Row summarise(const Options& o, const std::string& recording, long pairs, double total_ms, const Scores& scores) {
  Row row;
  row.recording = recording;
  row.pairs = pairs;
  row.acupoints = static_cast<long>(scores.errors.size());
  if (row.acupoints == 0) throw std::runtime_error(recording + ": the matched ground-truth frames have no acupoints");
  row.no_depth = scores.no_depth;
  row.median_mm = median(scores.errors) * 1000.0;
  row.p90_mm = percentile(scores.errors, 0.9) * 1000.0;
  const long within =
      std::count_if(scores.errors.begin(), scores.errors.end(), [](double e) { return e * 1000.0 <= kWithinMm; });
  row.within_pct = 100.0 * within / row.acupoints;
  row.signed_mm = median(scores.signed_errors) * 1000.0;
  row.ms_per_pair = total_ms / pairs;
  row.worst = worstPoints(scores, o.worst);
  return row;
}

/// Gathers a bag's messages into stereo pairs by stamp, as the node's exact synchroniser does.
struct PairAssembler {
  explicit PairAssembler(std::string stereo_ns) : ns(std::move(stereo_ns)) {}
  std::string ns;
  std::optional<ros::Time> first_stamp;            // of the first left camera_info: ground-truth frame 0
  std::map<ros::Time, nodes::StereoPair> partial;  // pairs waiting for their other messages, by stamp

  /// left image, left camera_info, right image, right camera_info
  std::vector<std::string> topics() const {
    return {ns + "/left/image_raw", ns + "/left/camera_info", ns + "/right/image_raw", ns + "/right/camera_info"};
  }
  /// Adds one message; returns the stamp of the pair it completes, if any.
  std::optional<ros::Time> add(const rosbag::MessageInstance& m) {
    const std::vector<std::string> t = topics();
    const std::string& topic = m.getTopic();
    ros::Time stamp;
    nodes::StereoPair* pair = nullptr;
    if (topic == t[0] || topic == t[2]) {
      const sensor_msgs::ImageConstPtr image = m.instantiate<sensor_msgs::Image>();
      if (!image) throw std::runtime_error(topic + " is not sensor_msgs/Image but " + m.getDataType());
      stamp = image->header.stamp;
      pair = &partial[stamp];
      (topic == t[0] ? pair->left_image : pair->right_image) = image;
    } else {
      const sensor_msgs::CameraInfoConstPtr info = m.instantiate<sensor_msgs::CameraInfo>();
      if (!info) throw std::runtime_error(topic + " is not sensor_msgs/CameraInfo but " + m.getDataType());
      stamp = info->header.stamp;
      if (topic == t[1] && !first_stamp) first_stamp = stamp;
      pair = &partial[stamp];
      (topic == t[1] ? pair->left_info : pair->right_info) = info;
    }
    if (!pair->left_image || !pair->right_image || !pair->left_info || !pair->right_info) return std::nullopt;
    return stamp;
  }
  const nodes::StereoPair& pair(const ros::Time& stamp) const { return partial.at(stamp); }
  void done(const ros::Time& stamp) { partial.erase(stamp); }
};

/// Every pair of one recording, in the bag's order: scored against its ground-truth frame.
Row evaluate(const Options& o, const NodeSettings& settings, const Recording& rec) {
  const GroundTruth& gt = rec.gt;
  rosbag::Bag bag;
  try {
    bag.open(rec.bag, rosbag::bagmode::Read);
  } catch (const rosbag::BagException& e) {
    throw std::runtime_error("bag '" + rec.bag + "': " + e.what());
  }
  PairAssembler assembler(o.ns);
  rosbag::View view(bag, rosbag::TopicQuery(assembler.topics()));

  nodes::StereoModelCache cache;
  std::shared_ptr<const camera::StereoModel> full_model;
  const nodes::FullModel model_of = [&](const sensor_msgs::CameraInfo& l,
                                        const sensor_msgs::CameraInfo& r) -> const camera::StereoModel& {
    full_model = cache.get(l, r, settings.rectify ? 1.0 : 0.0,
                           [&](const camera::CameraCalibration& lc, const camera::CameraCalibration& rc) {
                             return nodes::hbdsModel(lc, rc, settings.rectify);
                           });
    return *full_model;
  };

  Scores scores;
  long pairs = 0;
  double total_ms = 0.0;
  try {
    for (const rosbag::MessageInstance& m : view) {
      const std::optional<ros::Time> complete = assembler.add(m);
      if (!complete) continue;
      const ros::Time stamp = *complete;
      const nodes::StereoPair& pair = assembler.pair(stamp);
      const std::optional<ros::Time>& first_stamp = assembler.first_stamp;
      const long index = std::lround((stamp - *first_stamp).toSec() * gt.rate);
      if (index < 0 || index >= static_cast<long>(gt.frames.size())) {
        throw std::runtime_error("the pair at " + stampText(stamp) + " (" +
                                 format("%.3f", (stamp - *first_stamp).toSec()) + " s) has no ground-truth frame (" +
                                 std::to_string(gt.frames.size()) + " frames at " + format("%g", gt.rate) + " Hz in '" +
                                 rec.ground_truth + "')");
      }
      const auto start = nodes::Clock::now();
      PairDepth result;
      try {
        result = matchPair(o, settings, pair, model_of);
      } catch (const std::exception& e) {  // BadInput, the library's std::invalid_argument, OpenCV
        throw std::runtime_error("the pair at " + stampText(stamp) + ": " + e.what());
      }
      total_ms += nodes::msSince(start);
      score(result.depth, result.views.model, gt.frames[index], &scores);
      assembler.done(stamp);
      if (++pairs == o.max_pairs) break;
    }
  } catch (const rosbag::BagException& e) {
    throw std::runtime_error(rec.name + ": bag '" + rec.bag + "': " + e.what());
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(rec.name + ": " + e.what());
  }
  if (pairs == 0) {
    const std::vector<std::string> t = assembler.topics();
    throw std::runtime_error(rec.name + ": bag '" + rec.bag + "' has no stereo pair on " + t[0] + ", " + t[1] + ", " +
                             t[2] + ", " + t[3] + " with equal stamps (rosbag info; --stereo-ns)");
  }
  return summarise(o, rec.name, pairs, total_ms, scores);
}

// ------------------------------------------------------------ output --

void printRow(const Options& o, const Row& r) {
  if (o.csv) {
    std::printf("%s,%ld,%ld,%.2f,%.2f,%.1f,%ld,%.2f,%.1f,%s\n", r.recording.c_str(), r.pairs, r.acupoints, r.median_mm,
                r.p90_mm, r.within_pct, r.no_depth, r.signed_mm, r.ms_per_pair, r.met() ? "yes" : "no");
  } else {
    std::printf("%-18s %6ld %9ld %10.2f %8.2f %11.1f %8ld %10.2f %9.1f\n", r.recording.c_str(), r.pairs, r.acupoints,
                r.median_mm, r.p90_mm, r.within_pct, r.no_depth, r.signed_mm, r.ms_per_pair);
  }
  std::fflush(stdout);
}

void run(const Options& o) {
  const NodeSettings s = readSettings(o);
  const std::vector<Recording> recordings = resolveRecordings(o);  // every file checked before the first match
  const stereo::StereoParams& p = o.params;
  if (o.csv) {
    std::printf(
        "recording,pairs,acupoints,median_mm,p90_mm,within_10mm_pct,no_depth,median_signed_mm,mean_ms_per_pair,"
        "target_met\n");
  } else {
    std::printf(
        "method %s, disparities %d..%d (full resolution), downsample %d, cost %s, refine %s, subpixel %s, "
        "lr_check %s (fill %s)%s\n",
        s.method.c_str(), s.min_disparity, s.min_disparity + s.disparity_range - 1, s.downsample,
        stereo::toString(p.cost.data_term).c_str(), stereo::toString(p.refine).c_str(),
        p.subpixel ? stereo::toString(p.subpixel_params.fit).c_str() : "none", p.lr_check ? "on" : "off",
        s.lr_fill ? "on" : "off", o.max_pairs > 0 ? (", first " + std::to_string(o.max_pairs) + " pairs").c_str() : "");
    std::printf("%-18s %6s %9s %10s %8s %11s %8s %10s %9s\n", "recording", "pairs", "acupoints", "median mm", "p90 mm",
                "% <= 10 mm", "no depth", "signed mm", "ms/pair");
  }
  std::vector<Row> rows;
  for (const Recording& r : recordings) {
    rows.push_back(evaluate(o, s, r));
    printRow(o, rows.back());
  }
  if (o.csv) return;
  for (const Row& r : rows) {
    if (r.worst.empty()) continue;
    std::printf("%s, the %zu acupoints off the most (median |error| / signed, mm):", r.recording.c_str(),
                r.worst.size());
    for (const WorstPoint& w : r.worst) std::printf(" %s %.1f / %+.1f;", w.name.c_str(), w.median_mm, w.signed_mm);
    std::printf("\n");
  }
  std::string verdict;
  for (const Row& r : rows) {
    verdict += (verdict.empty() ? "" : "; ") + r.recording + (r.met() ? " met" : " NOT met") +
               format(" (%.2f mm, %.1f %%)", r.median_mm, r.within_pct);
  }
  std::printf("target (median <= %g mm and >= %g %% within %g mm): %s\n", kTargetMedianMm, kTargetWithinPct, kWithinMm,
              verdict.c_str());
}

}  // namespace

int main(int argc, char** argv) {
  massage_cell::stereo::retainFreedMemory();
  Options options;
  return runTool(
      "stereo_bag_eval", [&] { return parse(argc, argv, options); }, [&] { run(options); });
}
