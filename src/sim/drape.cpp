// The towel over the buttocks / lower back (cell_scene.h).
//
// The towel is a height field over (u, y), u metres caudal of its cranial
// edge, over the body's height S (the trunk; the table top 0; far below
// beyond the table's sides):
//   T = max(closing of S by a paraboloid of radius kSpan,
//           max over q within kReach of S(q) - hangDrop(|p - q|)),
// the closing bridging grooves and gaps (spine, intergluteal cleft, between
// the thighs) with a little sag, the cone letting it hang steeply over the
// flanks down to the table and over the table's edges; then a few mm of gap
// and folds where it hangs free. Only body under the towel (u >= 0) lifts
// it: its edge lies on the skin.
// Arms either lie on the towel (it is pinned to the table under their
// footprint and rises from there at most by the same drop, never below the
// skin: tucked between trunk and arm) or under it (they count as body).
#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <vector>

#include "cell_scene_parts.h"
#include "massage_cell/sim/scene_builder.h"
#include "shape_math.h"

namespace massage_cell::sim {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kSpacing = 0.004;
constexpr double kReach = 0.08;
constexpr double kSpan = 0.04;        // bridging: a gap of width w sags by w^2 / (8 kSpan)
constexpr double kSpanWindow = 0.06;  // widest gap bridged
constexpr double kHangSlope = 2.2;
constexpr double kHangStart = 0.005;
constexpr double kGap = 0.003;
constexpr double kOffTable = -0.35;  // "body height" beyond the table's sides: the towel hangs down there
constexpr double kOverhang = 0.08;   // the towel reaches this far beyond the table's sides

double thickness(Weave w) {
  switch (w) {
    case Weave::kTerry:
      return 0.005;
    case Weave::kWaffle:
      return 0.003;
    case Weave::kFine:
    case Weave::kStripes:
    case Weave::kChecks:
      return 0.0015;
  }
  return 0.002;
}

/// The towel's cells (i along u, j along y) and a raster of the body under
/// them extended by `pad` cells on every side (indices -pad .. n + pad - 1).
struct Grid {
  int rows = 0, cols = 0;
  int pad = 0;
  double y0 = 0.0, edge_x = 0.0, tan_tilt = 0.0;
  double x(int i, int j) const { return edge_x + tan_tilt * y(j) - i * kSpacing; }
  double y(int j) const { return y0 + j * kSpacing; }
  int width() const { return cols + 2 * pad; }
  int height() const { return rows + 2 * pad; }
  bool inRaster(int i, int j) const { return i >= -pad && i < rows + pad && j >= -pad && j < cols + pad; }
  std::size_t at(int i, int j) const { return static_cast<std::size_t>((i + pad) * width() + (j + pad)); }
  std::size_t cell(int i, int j) const { return static_cast<std::size_t>(i * cols + j); }
};

using Arms = std::vector<std::vector<TubeRing>>;

/// Height of whatever the towel lies on at (i, j): the trunk, the arms too
/// when they lie under the towel, far below beyond the table.
double support(const Grid& g, const TrunkSurface& trunk, const Arms* arms_under, int i, int j) {
  const double x = g.x(i, j), y = g.y(j);
  if (std::abs(y) > kTableHalfWidth) return kOffTable;
  double h = trunk.height(x, y);
  if (arms_under) {
    for (const auto& arm : *arms_under) h = std::max(h, tubeTopAt(arm, x, y));
  }
  return h;
}

std::vector<double> bodyRaster(const Grid& g, const TrunkSurface& trunk, const Arms* arms_under) {
  std::vector<double> s(static_cast<std::size_t>(g.width() * g.height()));
  for (int i = -g.pad; i < g.rows + g.pad; ++i) {
    for (int j = -g.pad; j < g.cols + g.pad; ++j) s[g.at(i, j)] = support(g, trunk, arms_under, i, j);
  }
  return s;
}

/// 1 on the raster under an arm lying on the towel (its rings' discs, the end cap included).
std::vector<unsigned char> armFootprint(const Grid& g, const Arms& arms) {
  std::vector<unsigned char> mask(static_cast<std::size_t>(g.width() * g.height()), 0);
  auto stamp = [&](const Eigen::Vector2d& c, double radius) {
    for (int j = -g.pad; j < g.cols + g.pad; ++j) {
      const double dy = g.y(j) - c.y();
      if (std::abs(dy) > radius) continue;
      const double i_centre = (g.x(0, j) - c.x()) / kSpacing, di = std::sqrt(radius * radius - dy * dy) / kSpacing;
      const int i0 = std::max(-g.pad, static_cast<int>(std::ceil(i_centre - di)));
      const int i1 = std::min(g.rows + g.pad - 1, static_cast<int>(std::floor(i_centre + di)));
      for (int i = i0; i <= i1; ++i) mask[g.at(i, j)] = 1;
    }
  };
  for (const auto& arm : arms) {
    for (const TubeRing& ring : arm) stamp(ring.centre.head<2>(), ring.a + 0.004);
    if (arm.size() < 2) continue;
    const TubeRing& last = arm.back();
    const Eigen::Vector2d t = (last.centre - arm[arm.size() - 2].centre).head<2>().normalized();
    for (double e = 0.01; e <= 0.45 * (last.a + last.b) + 1e-9; e += 0.01) stamp(last.centre.head<2>() + e * t, last.a);
  }
  return mask;
}

/// Drop of the hanging cloth at distance d: parabolic over the first
/// kHangStart (a soft fold over an edge), then straight at kHangSlope.
double hangDrop(double d) {
  return d < kHangStart ? kHangSlope * d * d / (2.0 * kHangStart) : kHangSlope * (d - 0.5 * kHangStart);
}

/// One separable pass of a parabolic dilation (sign +1) or erosion (-1) of
/// a w x h raster along rows (along_rows) or columns.
std::vector<double> parabolicPass(const std::vector<double>& in, int w, int h, bool along_rows, int sign) {
  const int r = static_cast<int>(std::ceil(kSpanWindow / kSpacing));
  std::vector<double> out(in.size());
  for (int i = 0; i < h; ++i) {
    for (int j = 0; j < w; ++j) {
      double best = sign * -1e9;
      for (int k = -r; k <= r; ++k) {
        const int ii = along_rows ? i : i + k, jj = along_rows ? j + k : j;
        if (ii < 0 || ii >= h || jj < 0 || jj >= w) continue;
        const double d = k * kSpacing;
        const double v = in[static_cast<std::size_t>(ii * w + jj)] - sign * d * d / (2.0 * kSpan);
        best = sign > 0 ? std::max(best, v) : std::min(best, v);
      }
      out[static_cast<std::size_t>(i * w + j)] = best;
    }
  }
  return out;
}

/// Morphological closing of the body raster by the paraboloid of radius kSpan.
std::vector<double> closing(const Grid& g, const std::vector<double>& body) {
  const int w = g.width(), h = g.height();
  const std::vector<double> z = parabolicPass(parabolicPass(body, w, h, true, 1), w, h, false, 1);
  return parabolicPass(parabolicPass(z, w, h, true, -1), w, h, false, -1);
}

struct Offset {
  int di, dj;
  double drop;
};

std::vector<Offset> reachOffsets() {
  std::vector<Offset> offsets;
  const int r = static_cast<int>(std::ceil(kReach / kSpacing));
  for (int di = -r; di <= r; ++di) {
    for (int dj = -r; dj <= r; ++dj) {
      const double d = kSpacing * std::hypot(di, dj);
      if (d <= kReach) offsets.push_back({di, dj, hangDrop(d)});
    }
  }
  return offsets;
}

/// Per towel cell: the bridged body (closing), the towel's height (the
/// closing, or hanging by the cone from body under the towel) and, with a
/// footprint, the ceiling a cloth pinned under the arms can rise to.
struct Drape {
  std::vector<double> closed, top, ceiling;
};

Drape drape(const Grid& g, const std::vector<double>& body, const std::vector<unsigned char>* pinned) {
  const std::vector<Offset> offsets = reachOffsets();
  const std::vector<double> closed = closing(g, body);
  Drape d;
  const std::size_t n = static_cast<std::size_t>(g.rows * g.cols);
  d.closed.resize(n);
  d.top.resize(n);
  d.ceiling.assign(n, 1e9);
  for (int i = 0; i < g.rows; ++i) {
    for (int j = 0; j < g.cols; ++j) {
      double best = closed[g.at(i, j)], low = 1e9;
      for (const Offset& o : offsets) {
        const int ii = i + o.di, jj = j + o.dj;
        if (!g.inRaster(ii, jj)) continue;
        if (ii >= 0) best = std::max(best, body[g.at(ii, jj)] - o.drop);
        if (pinned && (*pinned)[g.at(ii, jj)]) low = std::min(low, o.drop);
      }
      d.closed[g.cell(i, j)] = closed[g.at(i, j)];
      d.top[g.cell(i, j)] = best;
      d.ceiling[g.cell(i, j)] = low;
    }
  }
  return d;
}

/// Folds where the towel hangs free, a gentle waviness elsewhere.
struct Folds {
  explicit Folds(std::uint32_t seed) {
    std::mt19937 rng(seed ^ 0x70e1u);
    auto u = [&rng] { return static_cast<double>(rng()) / 4294967296.0; };
    wavelength = 0.06 + 0.04 * u();
    phase = 2.0 * kPi * u();
    for (auto& w : waves) w = {0.15 + 0.25 * u(), 2.0 * kPi * u(), 2.0 * kPi * u(), 2.0 * kPi * u()};
  }
  double operator()(double x, double y, double hanging) const {
    double z = 0.0;
    for (const auto& w : waves)
      z += 0.0006 * std::sin(2.0 * kPi * (x * std::cos(w[1]) + y * std::sin(w[1])) / w[0] + w[2]);
    const double fold = std::sin(2.0 * kPi * (x / wavelength + 0.2 * std::sin(2.0 * kPi * y / 0.23)) + phase);
    return z + 0.004 * hanging * fold;
  }
  double wavelength = 0.08, phase = 0.0;
  std::array<std::array<double, 4>, 3> waves{};
};

/// Box blur of radius r cells along rows then columns (softens the creases
/// where the dilation switches between neighbours).
std::vector<double> blurred(const Grid& g, const std::vector<double>& z, int r) {
  std::vector<double> a = z, b = z;
  for (int pass = 0; pass < 2; ++pass) {
    const bool rows = pass == 0;
    const std::vector<double>& in = pass == 0 ? z : a;
    std::vector<double>& out = pass == 0 ? a : b;
    for (int i = 0; i < g.rows; ++i) {
      for (int j = 0; j < g.cols; ++j) {
        double sum = 0.0;
        int n = 0;
        for (int k = -r; k <= r; ++k) {
          const int ii = rows ? i : i + k, jj = rows ? j + k : j;
          if (ii < 0 || ii >= g.rows || jj < 0 || jj >= g.cols) continue;
          sum += in[static_cast<std::size_t>(ii * g.cols + jj)];
          ++n;
        }
        out[static_cast<std::size_t>(i * g.cols + j)] = sum / n;
      }
    }
  }
  return b;
}

void addTopAndEdge(Mesh& mesh, const Grid& g, const std::vector<double>& top, double thick) {
  for (int i = 0; i < g.rows; ++i) {
    for (int j = 0; j < g.cols; ++j) {
      mesh.vertices.emplace_back(static_cast<float>(g.x(i, j)), static_cast<float>(g.y(j)),
                                 static_cast<float>(top[static_cast<std::size_t>(i * g.cols + j)]));
      mesh.uv.emplace_back(static_cast<float>(i * kSpacing), static_cast<float>(g.y(j)));
    }
  }
  for (int i = 0; i + 1 < g.rows; ++i) {
    for (int j = 0; j + 1 < g.cols; ++j) {
      const int a = i * g.cols + j, b = a + 1, c = a + g.cols, d = c + 1;
      mesh.triangles.emplace_back(a, b, d);
      mesh.triangles.emplace_back(a, d, c);
    }
  }
  // The cranial edge: a strip from the top surface down by the towel's thickness.
  const int first = static_cast<int>(mesh.vertices.size());
  for (int k = 0; k < 2; ++k) {
    for (int j = 0; j < g.cols; ++j) {
      Eigen::Vector3f v = mesh.vertices[static_cast<std::size_t>(j)];
      v.z() -= static_cast<float>(k * thick);
      mesh.vertices.push_back(v);
      mesh.uv.emplace_back(static_cast<float>(-k * thick), static_cast<float>(g.y(j)));
    }
  }
  for (int j = 0; j + 1 < g.cols; ++j) {
    const int t0 = first + j, t1 = t0 + 1, s0 = first + g.cols + j, s1 = s0 + 1;
    mesh.triangles.emplace_back(s0, s1, t0);
    mesh.triangles.emplace_back(s1, t1, t0);
  }
}

}  // namespace

Mesh towelMesh(const TrunkSurface& trunk, const std::vector<std::vector<TubeRing>>& arms, bool over_arms, double edge_x,
               double tilt, const Cloth& cloth, std::uint32_t seed) {
  Grid g;
  g.edge_x = edge_x;
  g.tan_tilt = std::tan(tilt);
  const double half = kTableHalfWidth + kOverhang;
  const double length = std::clamp(edge_x - (trunk.xMin() - 0.10), 0.30, 1.1);
  g.rows = static_cast<int>(std::ceil(length / kSpacing)) + 1;
  g.cols = static_cast<int>(std::ceil(2.0 * half / kSpacing)) + 1;
  g.y0 = -half;
  g.pad = static_cast<int>(std::ceil(std::max(kReach, kSpanWindow) / kSpacing));
  const bool pinned = !over_arms && !arms.empty();
  const std::vector<double> body = bodyRaster(g, trunk, over_arms ? &arms : nullptr);
  const std::vector<unsigned char> footprint = pinned ? armFootprint(g, arms) : std::vector<unsigned char>{};
  Drape d = drape(g, body, pinned ? &footprint : nullptr);
  const double thick = thickness(cloth.weave);
  const Folds folds(seed);
  for (std::size_t k = 0; k < d.top.size(); ++k) d.top[k] = std::min(d.top[k], d.ceiling[k]);
  std::vector<double> top = blurred(g, d.top, 2);
  for (int i = 0; i < g.rows; ++i) {
    for (int j = 0; j < g.cols; ++j) {
      const std::size_t k = g.cell(i, j);
      const double under = body[g.at(i, j)];
      const double draped = std::max(top[k], under);
      const double hanging = smooth5(0.006, 0.03, draped - std::max(d.closed[k], under));
      top[k] = draped + kGap + thick + folds(g.x(i, j), g.y(j), hanging);
    }
  }
  Mesh mesh;
  mesh.name = "towel";
  mesh.label = kLabelTowel;
  mesh.material = clothMaterial(cloth, seed ^ 0x70e1u);
  addTopAndEdge(mesh, g, top, thick);
  smoothNormals(mesh);
  return mesh;
}

}  // namespace massage_cell::sim
