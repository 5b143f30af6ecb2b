// Tests of the parametric prone back: subjects, validation, vertebral levels,
// the height field (outline, smoothness, spine groove, scapulae, breathing),
// acupoints and landmarks on the surface, and the skin mesh.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <map>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "massage_cell/sim/body_model.h"

namespace {

using massage_cell::sim::BackModel;
using massage_cell::sim::BodyParameters;
using massage_cell::sim::kLabelBack;
using massage_cell::sim::Material;
using massage_cell::sim::Mesh;
using massage_cell::sim::vertebralLevels;

bool sameParameters(const BodyParameters& a, const BodyParameters& b) {
  return a.shoulder_width == b.shoulder_width && a.waist_width == b.waist_width && a.hip_width == b.hip_width &&
         a.torso_length == b.torso_length && a.neck_width == b.neck_width && a.back_height == b.back_height &&
         a.lateral_rounding == b.lateral_rounding && a.thoracic_curvature == b.thoracic_curvature &&
         a.lumbar_curvature == b.lumbar_curvature && a.spine_depth == b.spine_depth &&
         a.paraspinal_width == b.paraspinal_width && a.scapula_prominence == b.scapula_prominence &&
         a.scapula_medial_offset == b.scapula_medial_offset && a.shoulder_slope == b.shoulder_slope &&
         a.buttock_height == b.buttock_height && a.skin_albedo == b.skin_albedo && a.moles == b.moles &&
         a.skin_seed == b.skin_seed;
}

double luminance(const Eigen::Vector3f& c) { return 0.2126 * c.x() + 0.7152 * c.y() + 0.0722 * c.z(); }

/// Finds, for a point (x, y), the mesh triangle above it (in the xy projection)
/// and the mesh height there. A uniform bucket grid over the triangles' boxes.
class MeshLocator {
 public:
  explicit MeshLocator(const Mesh& mesh, double cell = 0.01) : mesh_(mesh), cell_(cell) {
    Eigen::Vector2d lo(1e9, 1e9), hi(-1e9, -1e9);
    for (const auto& v : mesh.vertices) {
      lo = lo.cwiseMin(v.head<2>().cast<double>());
      hi = hi.cwiseMax(v.head<2>().cast<double>());
    }
    lo_ = lo;
    nx_ = static_cast<int>((hi.x() - lo.x()) / cell) + 1;
    ny_ = static_cast<int>((hi.y() - lo.y()) / cell) + 1;
    buckets_.resize(static_cast<std::size_t>(nx_ * ny_));
    for (int t = 0; t < static_cast<int>(mesh.triangles.size()); ++t) {
      Eigen::Vector2d tlo(1e9, 1e9), thi(-1e9, -1e9);
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector2d p =
            mesh.vertices[static_cast<std::size_t>(mesh.triangles[static_cast<std::size_t>(t)][k])]
                .head<2>()
                .cast<double>();
        tlo = tlo.cwiseMin(p);
        thi = thi.cwiseMax(p);
      }
      for (int i = index(tlo.x(), lo_.x(), nx_); i <= index(thi.x(), lo_.x(), nx_); ++i) {
        for (int j = index(tlo.y(), lo_.y(), ny_); j <= index(thi.y(), lo_.y(), ny_); ++j) {
          buckets_[static_cast<std::size_t>(i * ny_ + j)].push_back(t);
        }
      }
    }
  }

  /// Mesh height above (x, y); false when no triangle covers the point.
  bool heightAt(double x, double y, double* z) const {
    const int i = static_cast<int>(std::floor((x - lo_.x()) / cell_));
    const int j = static_cast<int>(std::floor((y - lo_.y()) / cell_));
    if (i < 0 || j < 0 || i >= nx_ || j >= ny_) return false;
    for (int t : buckets_[static_cast<std::size_t>(i * ny_ + j)]) {
      const Eigen::Vector3i& tri = mesh_.triangles[static_cast<std::size_t>(t)];
      const Eigen::Vector3d a = mesh_.vertices[static_cast<std::size_t>(tri[0])].cast<double>();
      const Eigen::Vector3d b = mesh_.vertices[static_cast<std::size_t>(tri[1])].cast<double>();
      const Eigen::Vector3d c = mesh_.vertices[static_cast<std::size_t>(tri[2])].cast<double>();
      const double d = (b.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (b.y() - a.y());
      if (d == 0.0) continue;
      const double l1 = ((x - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (y - a.y())) / d;
      const double l2 = ((b.x() - a.x()) * (y - a.y()) - (x - a.x()) * (b.y() - a.y())) / d;
      if (l1 >= -1e-9 && l2 >= -1e-9 && l1 + l2 <= 1.0 + 1e-9) {
        *z = a.z() + l1 * (b.z() - a.z()) + l2 * (c.z() - a.z());
        return true;
      }
    }
    return false;
  }

 private:
  int index(double v, double lo, int n) const {
    return std::clamp(static_cast<int>(std::floor((v - lo) / cell_)), 0, n - 1);
  }
  const Mesh& mesh_;
  double cell_;
  Eigen::Vector2d lo_;
  int nx_ = 0, ny_ = 0;
  std::vector<std::vector<int>> buckets_;
};

/// Maximum vertical distance between mesh and height() at random points inside
/// the outline. Points the mesh does not cover must lie within 0.1 mm of the
/// outline or of the ends (the mesh border is a polygon on the outline).
double maxMeshError(const BackModel& back, const Mesh& mesh, int samples, std::uint32_t seed, int* uncovered_far) {
  const MeshLocator locator(mesh);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(back.extent()[0], back.extent()[1]), uy(-0.35, 0.35);
  double worst = 0.0;
  *uncovered_far = 0;
  for (int k = 0; k < samples; ++k) {
    const double x = ux(rng), y = uy(rng);
    const double h = back.height(x, y);
    if (!std::isfinite(h)) continue;
    double z = 0.0;
    if (!locator.heightAt(x, y, &z)) {
      const double to_outline = back.halfWidth(x) - std::abs(y);
      const double to_end = std::min(x - back.extent()[0], back.extent()[1] - x);
      if (to_outline > 1e-4 && to_end > 1e-4) ++*uncovered_far;
      continue;
    }
    worst = std::max(worst, std::abs(z - h));
  }
  return worst;
}

const std::vector<std::string>& expectedAcupoints() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n = {"GV14", "GV13", "GV12", "GV11", "GV10", "GV9",
                                  "GV8",  "GV7",  "GV6",  "GV5",  "GV4",  "GV3"};
    for (const char* bilateral :
         {"BL11", "BL12", "BL13", "BL14", "BL15", "BL16", "BL17", "BL18", "BL19", "BL20", "BL21",
          "BL22", "BL23", "BL24", "BL25", "BL26", "SI14", "BL41", "BL42", "BL43", "BL44", "BL45",
          "BL46", "BL47", "BL48", "BL49", "BL50", "BL51", "BL52", "SI15", "GB21"}) {
      n.push_back(std::string(bilateral) + "_L");
      n.push_back(std::string(bilateral) + "_R");
    }
    for (std::size_t i = 1; i < vertebralLevels().size(); ++i) {
      n.push_back("EX_B2_" + vertebralLevels()[i] + "_L");
      n.push_back("EX_B2_" + vertebralLevels()[i] + "_R");
    }
    return n;
  }();
  return names;
}

// ---------------------------------------------------------------------------
// Parameters

TEST(BodyParameters, MeanIsTheDefaultsAndSubjectZero) {
  const BodyParameters m = BodyParameters::mean();
  EXPECT_TRUE(sameParameters(m, BodyParameters{}));
  EXPECT_TRUE(sameParameters(BodyParameters::subject(0), m));
  EXPECT_TRUE(sameParameters(BodyParameters::subject(0, 77), m));
  EXPECT_NO_THROW(m.validate());
}

TEST(BodyParameters, SubjectsAreDeterministic) {
  for (int i = 1; i <= 28; ++i) {
    EXPECT_TRUE(sameParameters(BodyParameters::subject(i, 2024), BodyParameters::subject(i, 2024))) << i;
    EXPECT_TRUE(sameParameters(BodyParameters::subject(i), BodyParameters::subject(i, 2024))) << i;
    EXPECT_FALSE(sameParameters(BodyParameters::subject(i, 2024), BodyParameters::subject(i, 99))) << i;
  }
}

TEST(BodyParameters, SubjectsArePairwiseDistinctAndPlausible) {
  const BodyParameters m = BodyParameters::mean();
  std::vector<BodyParameters> s;
  for (int i = 1; i <= 28; ++i) s.push_back(BodyParameters::subject(i));
  std::set<std::uint32_t> skin_seeds;
  std::set<int> moles;
  double darkest = 1.0, lightest = 0.0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const BodyParameters& p = s[i];
    EXPECT_NO_THROW(p.validate()) << i + 1;
    EXPECT_FALSE(sameParameters(p, m)) << i + 1;
    for (std::size_t j = 0; j < i; ++j) {
      EXPECT_NE(p.shoulder_width, s[j].shoulder_width) << i + 1 << " vs " << j + 1;
      EXPECT_NE(p.torso_length, s[j].torso_length) << i + 1 << " vs " << j + 1;
      EXPECT_GT((p.skin_albedo - s[j].skin_albedo).norm(), 1e-4) << i + 1 << " vs " << j + 1;
    }
    EXPECT_NEAR(p.shoulder_width, m.shoulder_width, 0.12 * m.shoulder_width + 1e-12);
    EXPECT_NEAR(p.hip_width, m.hip_width, 0.12 * m.hip_width + 1e-12);
    EXPECT_LE(p.waist_width, 1.12 * m.waist_width + 1e-12);
    EXPECT_LT(p.waist_width, p.hip_width);
    EXPECT_NEAR(p.torso_length, m.torso_length, 0.10 * m.torso_length + 1e-12);
    EXPECT_NEAR(p.back_height, m.back_height, 0.15 * m.back_height + 1e-12);
    EXPECT_GE(p.moles, 0);
    EXPECT_LE(p.moles, 8);
    skin_seeds.insert(p.skin_seed);
    moles.insert(p.moles);
    const double l = luminance(p.skin_albedo);
    darkest = std::min(darkest, l);
    lightest = std::max(lightest, l);
    // Skin: red > green > blue, in [0, 1].
    EXPECT_GT(p.skin_albedo.x(), p.skin_albedo.y()) << i + 1;
    EXPECT_GT(p.skin_albedo.y(), p.skin_albedo.z()) << i + 1;
    EXPECT_GT(p.skin_albedo.minCoeff(), 0.0f);
    EXPECT_LT(p.skin_albedo.maxCoeff(), 1.0f);
  }
  EXPECT_EQ(skin_seeds.size(), s.size());
  EXPECT_GE(moles.size(), 4u);
  // From very dark to light skin.
  EXPECT_LT(darkest, 0.12);
  EXPECT_GT(lightest, 0.55);
}

TEST(BodyParameters, SubjectIndexOutOfRangeThrows) {
  EXPECT_THROW(BodyParameters::subject(29), std::invalid_argument);
  EXPECT_THROW(BodyParameters::subject(-1), std::invalid_argument);
  try {
    BodyParameters::subject(29);
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), "subject index 29 is not in 0..28");
  }
}

TEST(BodyParameters, ValidateRejectsImplausibleValues) {
  const std::vector<std::pair<std::string, std::function<void(BodyParameters&)>>> cases = {
      {"shoulder_width", [](BodyParameters& p) { p.shoulder_width = 0.0; }},
      {"shoulder_width", [](BodyParameters& p) { p.shoulder_width = -0.4; }},
      {"waist_width", [](BodyParameters& p) { p.waist_width = std::nan(""); }},
      {"waist_width", [](BodyParameters& p) { p.waist_width = 0.5; }},  // wider than the shoulders
      {"hip_width", [](BodyParameters& p) { p.hip_width = 1.2; }},
      {"torso_length", [](BodyParameters& p) { p.torso_length = 0.0; }},
      {"torso_length", [](BodyParameters& p) { p.torso_length = 3.0; }},
      {"neck_width", [](BodyParameters& p) { p.neck_width = -0.1; }},
      {"back_height", [](BodyParameters& p) { p.back_height = 0.0; }},
      {"back_height", [](BodyParameters& p) { p.back_height = 2.0; }},
      {"lateral_rounding", [](BodyParameters& p) { p.lateral_rounding = 0.0; }},
      {"thoracic_curvature", [](BodyParameters& p) { p.thoracic_curvature = -0.01; }},
      {"lumbar_curvature", [](BodyParameters& p) { p.lumbar_curvature = 0.5; }},
      {"spine_depth", [](BodyParameters& p) { p.spine_depth = -0.001; }},
      {"paraspinal_width", [](BodyParameters& p) { p.paraspinal_width = 0.0; }},
      {"scapula_prominence", [](BodyParameters& p) { p.scapula_prominence = -0.002; }},
      {"scapula_medial_offset", [](BodyParameters& p) { p.scapula_medial_offset = 0.0; }},
      {"scapula_medial_offset", [](BodyParameters& p) { p.scapula_medial_offset = 0.14; }},  // off the waist
      {"shoulder_slope", [](BodyParameters& p) { p.shoulder_slope = 2.0; }},
      {"buttock_height", [](BodyParameters& p) { p.buttock_height = -0.01; }},
      {"skin_albedo", [](BodyParameters& p) { p.skin_albedo.x() = 1.5f; }},
      {"moles", [](BodyParameters& p) { p.moles = -1; }},
  };
  for (const auto& [name, mutate] : cases) {
    BodyParameters p = BodyParameters::mean();
    mutate(p);
    try {
      p.validate();
      ADD_FAILURE() << name << ": no exception";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
    EXPECT_THROW(BackModel{p}, std::invalid_argument) << name;
  }
  EXPECT_THROW(BackModel(BodyParameters::mean(), 0.0, -0.01), std::invalid_argument);
}

// ---------------------------------------------------------------------------
// Vertebral levels

TEST(VertebralLevels, NamesInOrder) {
  const auto& v = vertebralLevels();
  ASSERT_EQ(v.size(), 18u);
  EXPECT_EQ(v.front(), "C7");
  for (int i = 1; i <= 12; ++i) EXPECT_EQ(v[static_cast<std::size_t>(i)], "T" + std::to_string(i));
  for (int i = 1; i <= 5; ++i) EXPECT_EQ(v[static_cast<std::size_t>(12 + i)], "L" + std::to_string(i));
}

TEST(VertebralLevels, MonotonicAnchoredAndPlausiblySpaced) {
  for (int index : {0, 1, 7, 19, 28}) {
    const BackModel back(BodyParameters::subject(index));
    const double L = back.body().torso_length;
    EXPECT_DOUBLE_EQ(back.levelX("C7"), 0.0);
    EXPECT_DOUBLE_EQ(back.levelX("L4"), -L);
    const auto& v = vertebralLevels();
    double thoracic = 0.0, lumbar = 0.0;
    for (std::size_t i = 1; i < v.size(); ++i) {
      const double step = back.levelX(v[i - 1]) - back.levelX(v[i]);
      EXPECT_GT(step, 0.015) << v[i];
      EXPECT_LT(step, 0.05) << v[i];
      if (v[i][0] == 'T' && i >= 2) thoracic = std::max(thoracic, step);
      if (v[i][0] == 'L' && v[i - 1][0] == 'L') lumbar = std::max(lumbar, step);
    }
    EXPECT_GT(lumbar, thoracic);
    // The scapula's inferior angle (T7) lies roughly 35-42 % of the way down to L4.
    EXPECT_GT(-back.levelX("T7") / L, 0.33);
    EXPECT_LT(-back.levelX("T7") / L, 0.45);
    EXPECT_LT(back.levelX("L5"), -L);
    EXPECT_GT(back.levelX("L5"), back.extent()[0]);
  }
  const BackModel back(BodyParameters::mean());
  EXPECT_THROW(back.levelX("T13"), std::invalid_argument);
  EXPECT_THROW(back.levelX("c7"), std::invalid_argument);
  EXPECT_THROW(back.levelX(""), std::invalid_argument);
}

// ---------------------------------------------------------------------------
// Height field

TEST(BackModel, ExtentAndOutlineShape) {
  const BackModel back(BodyParameters::mean());
  const BodyParameters& b = back.body();
  const Eigen::Vector2d e = back.extent();
  EXPECT_NEAR(e[1], 0.03, 0.01);
  EXPECT_NEAR(e[0], -(b.torso_length + 0.12), 1e-12);
  EXPECT_EQ(back.halfWidth(e[1] + 0.01), 0.0);
  EXPECT_EQ(back.halfWidth(e[0] - 0.01), 0.0);
  EXPECT_NEAR(back.halfWidth(e[1]), 0.5 * b.neck_width, 0.01);
  const double waist = back.halfWidth(back.levelX("L2"));
  EXPECT_NEAR(waist, 0.5 * b.waist_width, 0.005);
  // The waist is the narrowest part between the shoulders and the hips.
  for (double x = back.levelX("T1"); x > back.levelX("L5"); x -= 0.005) {
    EXPECT_GE(back.halfWidth(x), waist - 1e-9) << x;
  }
  EXPECT_GT(back.halfWidth(back.levelX("T1")), 0.5 * b.shoulder_width);
  EXPECT_NEAR(back.halfWidth(back.levelX("L4")), 0.5 * b.hip_width, 0.02);
  EXPECT_GT(back.halfWidth(back.levelX("T1")), back.halfWidth(back.levelX("T8")));
  EXPECT_GT(back.halfWidth(back.levelX("T8")), waist);
}

TEST(BackModel, HeightIsNanOutsideAndFiniteInside) {
  for (int index : {0, 3, 17}) {
    const BackModel back(BodyParameters::subject(index));
    const Eigen::Vector2d e = back.extent();
    EXPECT_TRUE(std::isnan(back.height(e[1] + 1e-4, 0.0)));
    EXPECT_TRUE(std::isnan(back.height(e[0] - 1e-4, 0.0)));
    EXPECT_TRUE(std::isnan(back.height(0.5, 0.0)));
    EXPECT_TRUE(std::isnan(back.height(std::nan(""), 0.0)));
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> ux(e[0], e[1]), us(-1.2, 1.2);
    for (int k = 0; k < 5000; ++k) {
      const double x = ux(rng), s = us(rng);
      const double hw = back.halfWidth(x);
      ASSERT_GT(hw, 0.0);
      const double z = back.height(x, s * hw);
      if (std::abs(s) > 1.0 + 1e-12) {
        EXPECT_TRUE(std::isnan(z)) << x << " " << s;
      } else {
        ASSERT_TRUE(std::isfinite(z)) << x << " " << s;
        EXPECT_GE(z, 0.0);
        EXPECT_LT(z, 0.4);
        if (std::abs(s) < 0.9 && x < e[1] - 0.02 && x > e[0] + 0.03) {
          EXPECT_GT(z, 0.02) << x << " " << s;
        }
      }
    }
    // The outline meets the table.
    for (double x = e[0]; x <= e[1]; x += 0.01) {
      EXPECT_NEAR(back.height(x, back.halfWidth(x)), 0.0, 1e-12);
      EXPECT_NEAR(back.height(x, -back.halfWidth(x)), 0.0, 1e-12);
    }
    // Plausible heights: mid-back near back_height, the lumbar region lower.
    const BodyParameters& b = back.body();
    EXPECT_NEAR(back.height(back.levelX("T7"), 0.04), b.back_height, 0.02);
    EXPECT_LT(back.height(back.levelX("L3"), 0.04), back.height(back.levelX("T6"), 0.04));
    EXPECT_GT(back.height(e[0] + 0.035, 0.06), back.height(back.levelX("L3"), 0.06));  // buttocks rise
  }
}

TEST(BackModel, SurfaceIsSmooth) {
  for (int index = 0; index <= 28; index += 7) {
    const BackModel back(BodyParameters::subject(index));
    const Eigen::Vector2d e = back.extent();
    auto second = [&](double x, double y, double h, bool along_x) {
      const double dx = along_x ? h : 0.0, dy = along_x ? 0.0 : h;
      return (back.height(x + dx, y + dy) - 2.0 * back.height(x, y) + back.height(x - dx, y - dy)) / (h * h);
    };
    // The back proper (below the shoulders, away from the flanks).
    double d2_coarse = 0.0, d2_fine = 0.0, slope = 0.0;
    for (double x = e[0] + 0.035; x < back.levelX("T2"); x += 0.0017) {
      const double hw = back.halfWidth(x);
      for (int k = -60; k <= 60; ++k) {  // includes the midline, where |y| could crease
        const double y = k * 0.0125 * hw;
        for (bool along_x : {true, false}) {
          d2_coarse = std::max(d2_coarse, std::abs(second(x, y, 2e-3, along_x)));
          d2_fine = std::max(d2_fine, std::abs(second(x, y, 2.5e-4, along_x)));
        }
        slope = std::max(slope, std::abs(back.height(x + 1e-4, y) - back.height(x, y)) / 1e-4);
        slope = std::max(slope, std::abs(back.height(x, y + 1e-4) - back.height(x, y)) / 1e-4);
      }
    }
    // Bounded curvature (radius > 4 mm: the rounded shoulders and scapular
    // borders) that does not grow at finer steps (a crease would make the
    // second difference grow like 1/h), bounded slope.
    EXPECT_LT(d2_coarse, 250.0) << index;
    EXPECT_LT(d2_fine, 250.0) << index;
    EXPECT_LT(d2_fine, 1.3 * d2_coarse + 5.0) << index;
    EXPECT_LT(slope, 4.0) << index;
    // No jumps anywhere inside the outline (incl. neck, shoulders, ends): the
    // height changes by at most slope * h for tiny steps, at two step sizes.
    double worst = 0.0;
    for (double x = e[0] + 1e-3; x < e[1] - 1e-3; x += 0.0023) {
      const double hw = back.halfWidth(x);
      for (double s = -0.97; s <= 0.97; s += 0.0191) {
        const double y = s * hw;
        const double z = back.height(x, y);
        for (double h : {1e-5, 1e-6}) {
          const double jump = std::max(std::abs(back.height(x + h, y) - z), std::abs(back.height(x, y + h) - z));
          worst = std::max(worst, jump / h);
        }
      }
    }
    EXPECT_LT(worst, 100.0) << index;
  }
}

TEST(BackModel, SpineGrooveBetweenParaspinalRidges) {
  for (int index : {0, 2, 9, 26}) {
    const BackModel back(BodyParameters::subject(index));
    const BodyParameters& b = back.body();
    for (const char* level : {"T4", "T10", "L3"}) {
      const double x = back.levelX(level);
      const double mid = back.height(x, 0.0);
      EXPECT_LT(mid, back.height(x, b.paraspinal_width) - 0.5 * b.spine_depth) << level;
      EXPECT_LT(mid, back.height(x, -b.paraspinal_width) - 0.5 * b.spine_depth) << level;
    }
    // Without a groove the midline is not lower than the ridges.
    BodyParameters flat = b;
    flat.spine_depth = 0.0;
    const BackModel no_groove(flat);
    const double x = back.levelX("T10");
    EXPECT_GT(no_groove.height(x, 0.0), no_groove.height(x, b.paraspinal_width) - 1e-4);
  }
}

TEST(BackModel, ScapulaeStandOut) {
  for (int index : {0, 4, 12}) {
    const BodyParameters b = BodyParameters::subject(index);
    BodyParameters flat = b;
    flat.scapula_prominence = 0.0;
    const BackModel back(b), no_scapulae(flat);
    const double x = back.levelX("T5");
    for (double side : {1.0, -1.0}) {
      const double y = side * (b.scapula_medial_offset + 0.01);
      EXPECT_GT(back.height(x, y), no_scapulae.height(x, y) + 0.6 * b.scapula_prominence) << index;
    }
    // Not on the spine, nor below the inferior angle.
    EXPECT_NEAR(back.height(x, 0.0), no_scapulae.height(x, 0.0), 1e-9);
    const double below = back.levelX("T9");
    EXPECT_NEAR(back.height(below, b.scapula_medial_offset + 0.01),
                no_scapulae.height(below, b.scapula_medial_offset + 0.01), 1e-6);
  }
}

TEST(BackModel, ShoulderSlopeLowersTheShoulders) {
  BodyParameters b = BodyParameters::mean();
  BodyParameters level = b;
  level.shoulder_slope = 0.0;
  const BackModel back(b), flat(level);
  const double x = back.levelX("T1"), y = 0.16;
  EXPECT_LT(back.height(x, y), flat.height(x, y) - 0.01);
  EXPECT_NEAR(back.height(back.levelX("T9"), y), flat.height(back.levelX("T9"), y), 1e-9);
}

TEST(BackModel, BreathingRaisesTheUpperBackOnly) {
  const BodyParameters b = BodyParameters::mean();
  const double amplitude = 0.008;
  const BackModel rest(b), exhaled(b, 0.0, amplitude), inhaled(b, 0.5, amplitude), mid(b, 0.25, amplitude);
  for (const char* level : {"T5", "T6"}) {
    const double x = rest.levelX(level);
    EXPECT_NEAR(inhaled.height(x, 0.0) - rest.height(x, 0.0), amplitude, 0.1 * amplitude) << level;
    EXPECT_NEAR(mid.height(x, 0.0) - rest.height(x, 0.0), 0.5 * amplitude, 0.05 * amplitude) << level;
    EXPECT_NEAR(exhaled.height(x, 0.0), rest.height(x, 0.0), 1e-12);
  }
  for (const char* level : {"L3", "L4", "L5"}) {
    const double x = rest.levelX(level);
    for (double y : {0.0, 0.05, -0.1}) EXPECT_NEAR(inhaled.height(x, y), rest.height(x, y), 1e-9) << level;
  }
  // Fades out toward the outline; the outline itself does not move.
  const double x = rest.levelX("T6");
  const double hw = rest.halfWidth(x);
  EXPECT_EQ(inhaled.halfWidth(x), hw);
  EXPECT_LT(inhaled.height(x, 0.97 * hw) - rest.height(x, 0.97 * hw), 0.1 * amplitude);
  EXPECT_EQ(inhaled.height(x, hw), 0.0);
  // Acupoints move with the breath.
  EXPECT_GT(inhaled.acupoints().at("BL15_L").z(), rest.acupoints().at("BL15_L").z() + 0.5 * amplitude);
  EXPECT_NEAR(inhaled.acupoints().at("BL25_L").z(), rest.acupoints().at("BL25_L").z(), 1e-9);
}

// ---------------------------------------------------------------------------
// Acupoints and landmarks

TEST(Acupoints, AllExistAndLieOnTheSurface) {
  for (int index : {0, 1, 8, 14, 23, 28}) {
    const BackModel back(BodyParameters::subject(index));
    const auto points = back.acupoints();
    EXPECT_EQ(points.size(), expectedAcupoints().size());
    for (const std::string& name : expectedAcupoints()) {
      ASSERT_TRUE(points.count(name)) << name << " missing for subject " << index;
      const Eigen::Vector3d& p = points.at(name);
      const double h = back.height(p.x(), p.y());
      ASSERT_TRUE(std::isfinite(h)) << name;
      EXPECT_LT(std::abs(p.z() - h), 1e-9) << name;
      EXPECT_GT(p.z(), 0.05) << name;
      EXPECT_LT(std::abs(p.y()), 0.85 * back.halfWidth(p.x())) << name;
    }
  }
}

TEST(Acupoints, LateralDistancesAndLevels) {
  const BackModel back(BodyParameters::mean());
  const auto p = back.acupoints();
  const double cun = back.cun();
  EXPECT_DOUBLE_EQ(cun, back.body().scapula_medial_offset / 3.0);
  auto check = [&](const std::string& name, const std::string& level, double lateral_cun) {
    ASSERT_TRUE(p.count(name)) << name;
    EXPECT_NEAR(p.at(name).x(), back.levelX(level), 1e-12) << name;
    EXPECT_NEAR(p.at(name).y(), lateral_cun * cun, 1e-12) << name;
  };
  check("GV14", "C7", 0.0);
  check("GV4", "L2", 0.0);
  check("GV3", "L4", 0.0);
  check("GV8", "T9", 0.0);
  check("BL11_L", "T1", 1.5);
  check("BL23_L", "L2", 1.5);
  check("BL23_R", "L2", -1.5);
  check("BL26_R", "L5", -1.5);
  check("BL43_L", "T4", 3.0);
  check("BL43_R", "T4", -3.0);
  check("BL52_L", "L2", 3.0);
  check("SI14_R", "T1", -3.0);
  check("SI15_L", "C7", 2.0);
  check("EX_B2_T1_L", "T1", 0.5);
  check("EX_B2_L5_L", "L5", 0.5);
  check("EX_B2_L5_R", "L5", -0.5);
  // Every BL point of the inner line at 1.5 cun, of the outer line at 3 cun.
  for (const auto& [name, q] : p) {
    if (name.rfind("BL", 0) != 0) continue;
    const int number = std::stoi(name.substr(2));
    const double expected = number <= 26 ? 1.5 : 3.0;
    EXPECT_NEAR(std::abs(q.y()), expected * cun, 1e-12) << name;
    EXPECT_EQ(q.y() > 0.0, name.back() == 'L') << name;
  }
  for (const auto& [name, q] : p) {
    if (name.rfind("GV", 0) == 0) {
      EXPECT_EQ(q.y(), 0.0) << name;
    }
  }
  // GB21: midway between GV14 and the acromion.
  const auto l = back.landmarks();
  for (const char* side : {"L", "R"}) {
    const Eigen::Vector3d a = l.at(std::string("acromion_") + side), g = p.at(std::string("GB21_") + side);
    EXPECT_NEAR(g.x(), 0.5 * (p.at("GV14").x() + a.x()), 1e-12);
    EXPECT_NEAR(g.y(), 0.5 * (p.at("GV14").y() + a.y()), 1e-12);
    EXPECT_NEAR(g.z(), back.height(g.x(), g.y()), 1e-12);
  }
  // surfacePoint agrees.
  const Eigen::Vector3d sp = back.surfacePoint("L2", 1.5);
  EXPECT_NEAR((sp - p.at("BL23_L")).norm(), 0.0, 1e-12);
  EXPECT_THROW(back.surfacePoint("L2", 40.0), std::invalid_argument);
  EXPECT_THROW(back.surfacePoint("S1", 0.0), std::invalid_argument);
}

TEST(Acupoints, LeftRightSymmetricForTheSymmetricBody) {
  for (int index : {0, 6}) {
    const BackModel back(BodyParameters::subject(index), 0.3, 0.006);
    const auto p = back.acupoints();
    int pairs = 0;
    for (const auto& [name, q] : p) {
      if (name.size() < 2 || name.substr(name.size() - 2) != "_L") continue;
      const std::string mirror = name.substr(0, name.size() - 2) + "_R";
      ASSERT_TRUE(p.count(mirror)) << mirror;
      const Eigen::Vector3d& r = p.at(mirror);
      EXPECT_EQ(q.x(), r.x()) << name;
      EXPECT_EQ(q.y(), -r.y()) << name;
      EXPECT_NEAR(q.z(), r.z(), 1e-12) << name;
      EXPECT_GT(q.y(), 0.0) << name;
      ++pairs;
    }
    EXPECT_EQ(pairs, 48);
  }
}

TEST(Acupoints, LieOnTheMesh) {
  for (int index : {0, 11, 25}) {
    const BackModel back(BodyParameters::subject(index), 0.5, 0.005);
    const Mesh mesh = back.mesh(0.004);
    const MeshLocator locator(mesh);
    auto points = back.acupoints();
    for (const auto& [name, p] : back.landmarks()) points["landmark_" + name] = p;
    for (const auto& [name, p] : points) {
      double z = 0.0;
      ASSERT_TRUE(locator.heightAt(p.x(), p.y(), &z)) << name;
      EXPECT_LT(std::abs(z - p.z()), 0.0005) << name << " subject " << index;
    }
  }
}

TEST(Landmarks, NamesPositionsAndOnTheSurface) {
  const BackModel back(BodyParameters::mean());
  const BodyParameters& b = back.body();
  const auto l = back.landmarks();
  EXPECT_EQ(l.size(), vertebralLevels().size() + 6);
  for (const std::string& level : vertebralLevels()) {
    ASSERT_TRUE(l.count(level)) << level;
    EXPECT_EQ(l.at(level).x(), back.levelX(level));
    EXPECT_EQ(l.at(level).y(), 0.0);
  }
  EXPECT_EQ(l.at("scapula_inferior_angle_L").x(), back.levelX("T7"));
  EXPECT_NEAR(l.at("scapula_inferior_angle_L").y(), b.scapula_medial_offset + 0.01, 0.003);
  EXPECT_NEAR(l.at("scapula_inferior_angle_R").y(), -(b.scapula_medial_offset + 0.01), 0.003);
  EXPECT_EQ(l.at("iliac_crest_L").x(), back.levelX("L4"));
  EXPECT_NEAR(l.at("iliac_crest_L").y(), 0.8 * back.halfWidth(back.levelX("L4")), 1e-12);
  EXPECT_NEAR(l.at("iliac_crest_R").y(), -0.8 * back.halfWidth(back.levelX("L4")), 1e-12);
  EXPECT_NEAR(l.at("acromion_L").y(), 0.5 * b.shoulder_width - 0.01, 1e-12);
  EXPECT_NEAR(l.at("acromion_R").y(), -(0.5 * b.shoulder_width - 0.01), 1e-12);
  EXPECT_LE(l.at("acromion_L").x(), back.levelX("C7"));
  EXPECT_GE(l.at("acromion_L").x(), back.levelX("T2"));
  for (const auto& [name, p] : l) {
    const double h = back.height(p.x(), p.y());
    ASSERT_TRUE(std::isfinite(h)) << name;
    EXPECT_LT(std::abs(p.z() - h), 1e-9) << name;
    EXPECT_GT(p.z(), 0.04) << name;
  }
  // The shoulders drop toward the acromion; C7 is a local bump on the midline.
  EXPECT_LT(l.at("acromion_L").z(), l.at("C7").z() - 0.03);
  EXPECT_GT(l.at("C7").z(), back.height(0.0, 0.03));
}

TEST(Midline, FromC7ToL5OnTheSurface) {
  const BackModel back(BodyParameters::subject(4));
  const auto m = back.midline(37);
  ASSERT_EQ(m.size(), 37u);
  EXPECT_EQ(m.front().x(), back.levelX("C7"));
  EXPECT_NEAR(m.back().x(), back.levelX("L5"), 1e-12);
  for (std::size_t i = 0; i < m.size(); ++i) {
    EXPECT_EQ(m[i].y(), 0.0);
    EXPECT_LT(std::abs(m[i].z() - back.height(m[i].x(), 0.0)), 1e-12);
    if (i > 0) {
      EXPECT_LT(m[i].x(), m[i - 1].x());
    }
  }
  EXPECT_EQ(back.midline().size(), 50u);
  EXPECT_THROW(back.midline(1), std::invalid_argument);
}

// ---------------------------------------------------------------------------
// Mesh

TEST(Mesh, TopologyOrientationNormalsAndBorder) {
  const BackModel back(BodyParameters::subject(9));
  const Mesh mesh = back.mesh(0.004);
  EXPECT_EQ(mesh.name, "back");
  EXPECT_EQ(mesh.label, kLabelBack);
  ASSERT_GT(mesh.vertices.size(), 10000u);
  ASSERT_EQ(mesh.normals.size(), mesh.vertices.size());
  ASSERT_EQ(mesh.uv.size(), mesh.vertices.size());
  EXPECT_TRUE(mesh.triangle_labels.empty());

  // Boundary edges (used by one triangle) and the orientation of every triangle.
  std::map<std::pair<int, int>, int> edges;
  for (const auto& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      ASSERT_GE(t[k], 0);
      ASSERT_LT(t[k], static_cast<int>(mesh.vertices.size()));
    }
    const Eigen::Vector3f a = mesh.vertices[static_cast<std::size_t>(t[0])];
    const Eigen::Vector3f b = mesh.vertices[static_cast<std::size_t>(t[1])];
    const Eigen::Vector3f c = mesh.vertices[static_cast<std::size_t>(t[2])];
    const Eigen::Vector3f n = (b - a).cross(c - a);
    EXPECT_GT(n.norm(), 1e-12f) << "degenerate triangle";
    EXPECT_GT(n.z(), 0.0f) << "clockwise seen from above";
    for (int k = 0; k < 3; ++k) {
      const int u = t[k], v = t[(k + 1) % 3];
      ++edges[{std::min(u, v), std::max(u, v)}];
    }
  }
  std::set<int> border;
  for (const auto& [e, count] : edges) {
    EXPECT_LE(count, 2);
    if (count == 1) {
      border.insert(e.first);
      border.insert(e.second);
    }
  }
  ASSERT_GT(border.size(), 400u);
  for (int v : border) EXPECT_EQ(mesh.vertices[static_cast<std::size_t>(v)].z(), 0.0f) << "border vertex off the table";

  // Vertices on the surface, uv = (x, y), unit normals pointing up/out.
  int upward = 0;
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    const Eigen::Vector3f& v = mesh.vertices[i];
    EXPECT_EQ(mesh.uv[i], v.head<2>());
    EXPECT_NEAR(mesh.normals[i].norm(), 1.0f, 1e-4f);
    if (border.count(static_cast<int>(i))) continue;
    EXPECT_GT(mesh.normals[i].z(), 0.0f) << i;
    const double h = back.height(v.x(), v.y());
    if (std::isfinite(h)) {
      EXPECT_NEAR(v.z(), h, 2e-6) << i;
    }
    if (std::abs(v.y()) < 0.6 * back.halfWidth(v.x()) && v.x() < back.levelX("T1") && v.x() > back.levelX("L5")) {
      EXPECT_GT(mesh.normals[i].z(), 0.5f) << i;
      ++upward;
    }
  }
  EXPECT_GT(upward, 5000);
  // The normal on top of the back is vertical-ish; on the left flank it points left.
  const double x = back.levelX("T9");
  std::size_t top = 0, left = 0;
  double best_top = 1e9, best_left = 1e9;
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    const Eigen::Vector2d p = mesh.vertices[i].head<2>().cast<double>();
    const double dt = (p - Eigen::Vector2d(x, 0.05)).norm(),
                 dl = (p - Eigen::Vector2d(x, 0.9 * back.halfWidth(x))).norm();
    if (dt < best_top) best_top = dt, top = i;
    if (dl < best_left) best_left = dl, left = i;
  }
  EXPECT_GT(mesh.normals[top].z(), 0.95f);
  EXPECT_GT(mesh.normals[left].y(), 0.5f);
}

TEST(Mesh, ApproximatesTheHeightField) {
  for (int index : {0, 3, 8, 16, 27}) {
    const BackModel back(BodyParameters::subject(index), 0.5, 0.006);
    const Mesh mesh = back.mesh(0.004);
    int uncovered = 0;
    const double err = maxMeshError(back, mesh, 60000, 100u + static_cast<std::uint32_t>(index), &uncovered);
    EXPECT_LT(err, 0.0005) << "subject " << index;
    EXPECT_EQ(uncovered, 0) << "subject " << index;
  }
  // Coarser meshes follow the surface less closely but still reach the outline.
  const BackModel back(BodyParameters::mean());
  const Mesh coarse = back.mesh(0.02);
  int uncovered = 0;
  EXPECT_LT(maxMeshError(back, coarse, 20000, 5, &uncovered), 0.005);
  EXPECT_EQ(uncovered, 0);
  EXPECT_LT(coarse.vertices.size(), back.mesh(0.004).vertices.size());
}

TEST(Mesh, MaterialAndMoles) {
  for (int index : {0, 2, 13}) {
    const BackModel back(BodyParameters::subject(index));
    const BodyParameters& b = back.body();
    const Mesh mesh = back.mesh();
    const Material& m = mesh.material;
    EXPECT_EQ(m.pattern, Material::Pattern::kSkin);
    EXPECT_EQ(m.albedo, b.skin_albedo);
    EXPECT_NEAR(m.specular, 0.08f, 1e-6f);
    EXPECT_NEAR(m.shininess, 25.0f, 1e-6f);
    EXPECT_NEAR(m.feature_size, 0.02f, 1e-6f);
    EXPECT_NEAR(m.contrast, 0.03f, 1e-6f);
    EXPECT_EQ(m.seed, b.skin_seed);
    ASSERT_EQ(m.spots.size(), static_cast<std::size_t>(b.moles));
    for (const auto& spot : m.spots) {
      EXPECT_GE(spot.radius, 0.0015f);
      EXPECT_LE(spot.radius, 0.003f);
      EXPECT_TRUE(std::isfinite(back.height(spot.centre.x(), spot.centre.y())));
      EXPECT_NEAR((spot.albedo - 0.45f * b.skin_albedo).norm(), 0.0f, 1e-6f);
    }
    // Deterministic.
    const Mesh again = back.mesh();
    ASSERT_EQ(again.vertices.size(), mesh.vertices.size());
    EXPECT_EQ(again.vertices, mesh.vertices);
    ASSERT_EQ(again.material.spots.size(), m.spots.size());
    for (std::size_t i = 0; i < m.spots.size(); ++i) EXPECT_EQ(again.material.spots[i].centre, m.spots[i].centre);
  }
  EXPECT_THROW(BackModel(BodyParameters::mean()).mesh(0.0), std::invalid_argument);
  EXPECT_THROW(BackModel(BodyParameters::mean()).mesh(-1.0), std::invalid_argument);
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
