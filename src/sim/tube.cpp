// Swept tubes and ellipsoids for the dressed scene's parts (body_parts.h).
#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "massage_cell/sim/body_parts.h"

namespace massage_cell::sim {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kCapRows = 6;  // rings of a half-ellipsoid end cap

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

void validateTube(const std::string& name, const std::vector<TubeRing>& rings, const TubeOptions& o) {
  const std::string who = "makeTube(" + name + "): ";
  if (rings.size() < 2) throw std::invalid_argument(who + "needs at least 2 rings");
  if (o.segments < 3 || o.segments > 1024) throw std::invalid_argument(who + "segments must be in 3..1024");
  const double span = o.angle_to - o.angle_from;
  if (!std::isfinite(span) || !(span > 0.0) || span > 2.0 * kPi + 1e-9) {
    throw std::invalid_argument(who + "angle_to - angle_from = " + num(span) + " must be in (0, 2 pi]");
  }
  for (std::size_t i = 0; i < rings.size(); ++i) {
    const TubeRing& r = rings[i];
    if (!r.centre.allFinite() || !(r.a > 0.0) || !(r.b > 0.0) || !std::isfinite(r.a) || !std::isfinite(r.b)) {
      throw std::invalid_argument(who + "ring " + std::to_string(i) + " needs a finite centre and a, b > 0");
    }
    if (i > 0 && !((r.centre - rings[i - 1].centre).norm() > 1e-9)) {
      throw std::invalid_argument(who + "rings " + std::to_string(i - 1) + " and " + std::to_string(i) +
                                  " share their centre");
    }
  }
}

/// Orthonormal frame of one ring: tangent t, horizontal normal n1, upward normal n2.
struct Frame {
  Eigen::Vector3d t, n1, n2;
};

std::vector<Frame> tubeFrames(const std::string& name, const std::vector<TubeRing>& rings) {
  const std::size_t n = rings.size();
  std::vector<Frame> frames(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d& lo = rings[i == 0 ? 0 : i - 1].centre;
    const Eigen::Vector3d& hi = rings[i + 1 == n ? n - 1 : i + 1].centre;
    Frame& f = frames[i];
    f.t = (hi - lo).normalized();
    const Eigen::Vector3d side = Eigen::Vector3d::UnitZ().cross(f.t);
    if (!(side.norm() > 1e-6)) throw std::invalid_argument("makeTube(" + name + "): the path is vertical");
    f.n1 = side.normalized();
    f.n2 = f.t.cross(f.n1);
  }
  return frames;
}

/// One row of vertices of the tube (a ring or a cap ring) appended to `mesh`.
struct RowSpec {
  Eigen::Vector3d centre;
  Frame frame;
  double a, b;       // semi-axes of the row
  double da, db;     // their derivatives along the path (main rings)
  double cap = 0.0;  // cap rows: sin(alpha) of the half-ellipsoid (+ toward the path's end), 0 on the main body
  double cap_len = 0.0;
  double u = 0.0;  // arc length coordinate
};

void appendRow(Mesh& mesh, const RowSpec& r, const TubeOptions& o, double v_scale) {
  for (int j = 0; j <= o.segments; ++j) {
    const double phi = o.angle_from + (o.angle_to - o.angle_from) * j / o.segments;
    const double c = std::cos(phi), s = std::sin(phi);
    const Eigen::Vector3d p = r.centre + r.a * c * r.frame.n1 + r.b * s * r.frame.n2;
    Eigen::Vector3d n;
    if (r.cap != 0.0) {
      // Half ellipsoid (A, B, L) about the end ring's centre: gradient direction.
      const double ca = std::sqrt(std::max(0.0, 1.0 - r.cap * r.cap));
      const double A = r.a / std::max(ca, 1e-9), B = r.b / std::max(ca, 1e-9);
      n = ca * c / A * r.frame.n1 + ca * s / B * r.frame.n2 + r.cap / r.cap_len * r.frame.t;
    } else {
      const Eigen::Vector3d d_phi = -r.a * s * r.frame.n1 + r.b * c * r.frame.n2;
      const Eigen::Vector3d d_s = r.frame.t + r.da * c * r.frame.n1 + r.db * s * r.frame.n2;
      n = d_phi.cross(d_s);
      if (n.dot(p - r.centre) < 0.0) n = -n;
    }
    mesh.vertices.push_back(p.cast<float>());
    mesh.normals.push_back(n.normalized().cast<float>());
    mesh.uv.emplace_back(static_cast<float>(r.u), static_cast<float>(phi * v_scale));
  }
}

/// Cap rows at one end: from the end ring (excluded) to the apex, or the reverse.
void appendCap(Mesh& mesh, const RowSpec& end, double direction, bool to_apex, const TubeOptions& o, double v_scale) {
  const double len = 0.45 * (end.a + end.b);
  for (int k = 1; k <= kCapRows; ++k) {
    const int kk = to_apex ? k : kCapRows + 1 - k;
    const double alpha = 0.5 * kPi * kk / kCapRows;
    RowSpec r = end;
    const double ca = std::max(std::cos(alpha), 0.0);
    r.a = std::max(end.a * ca, 1e-7);
    r.b = std::max(end.b * ca, 1e-7);
    r.centre = end.centre + direction * len * std::sin(alpha) * end.frame.t;
    r.cap = direction * std::max(std::sin(alpha), 1e-6);
    r.cap_len = len;
    r.u = end.u + direction * len * std::sin(alpha);
    appendRow(mesh, r, o, v_scale);
  }
}

void stitchRows(Mesh& mesh, int rows, int cols, bool flip) {
  for (int i = 0; i + 1 < rows; ++i) {
    for (int j = 0; j + 1 < cols; ++j) {
      const int a = i * cols + j, b = a + 1, c = a + cols, d = c + 1;
      if (flip) {
        mesh.triangles.emplace_back(a, b, c);
        mesh.triangles.emplace_back(b, d, c);
      } else {
        mesh.triangles.emplace_back(a, c, b);
        mesh.triangles.emplace_back(b, c, d);
      }
    }
  }
}

/// true when the triangles (a, c, b) of stitchRows, at vertex `a`, face away from `centre`.
bool outwardWithoutFlip(const Mesh& mesh, int a, int cols, const Eigen::Vector3d& centre) {
  const Eigen::Vector3f& pa = mesh.vertices[static_cast<std::size_t>(a)];
  const Eigen::Vector3f& pb = mesh.vertices[static_cast<std::size_t>(a + 1)];
  const Eigen::Vector3f& pc = mesh.vertices[static_cast<std::size_t>(a + cols)];
  const Eigen::Vector3f normal = (pc - pa).cross(pb - pa);
  return normal.cast<double>().dot(pa.cast<double>() - centre) > 0.0;
}

}  // namespace

Mesh makeTube(const std::string& name, const std::vector<TubeRing>& rings, const TubeOptions& options,
              const Material& material, std::uint8_t label) {
  validateTube(name, rings, options);
  const std::vector<Frame> frames = tubeFrames(name, rings);
  const std::size_t n = rings.size();
  std::vector<double> arc(n, 0.0);
  double mean_radius = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    if (i > 0) arc[i] = arc[i - 1] + (rings[i].centre - rings[i - 1].centre).norm();
    mean_radius += 0.5 * (rings[i].a + rings[i].b) / static_cast<double>(n);
  }
  auto spec = [&](std::size_t i) {
    const std::size_t lo = i == 0 ? 0 : i - 1, hi = i + 1 == n ? n - 1 : i + 1;
    const double ds = arc[hi] - arc[lo];
    return RowSpec{rings[i].centre,
                   frames[i],
                   rings[i].a,
                   rings[i].b,
                   (rings[hi].a - rings[lo].a) / ds,
                   (rings[hi].b - rings[lo].b) / ds,
                   0.0,
                   0.0,
                   arc[i]};
  };

  Mesh mesh;
  mesh.name = name;
  mesh.material = material;
  mesh.label = label;
  const int cols = options.segments + 1;
  if (options.cap_start) appendCap(mesh, spec(0), -1.0, false, options, mean_radius);
  for (std::size_t i = 0; i < n; ++i) appendRow(mesh, spec(i), options, mean_radius);
  if (options.cap_end) appendCap(mesh, spec(n - 1), 1.0, true, options, mean_radius);
  const int rows = static_cast<int>(mesh.vertices.size()) / cols;
  const int first_ring = options.cap_start ? kCapRows : 0;
  const bool flip = !outwardWithoutFlip(mesh, first_ring * cols + cols / 2, cols, rings[0].centre);
  stitchRows(mesh, rows, cols, flip);
  return mesh;
}

Mesh makeEllipsoid(const std::string& name, const Eigen::Vector3d& centre, const Eigen::Matrix3d& rotation,
                   const Eigen::Vector3d& axes, int rings, int segments, const Material& material, std::uint8_t label,
                   const std::function<bool(const Eigen::Vector3d&)>& keep) {
  if (!centre.allFinite() || !(axes.minCoeff() > 0.0) || !axes.allFinite()) {
    throw std::invalid_argument("makeEllipsoid(" + name + "): needs a finite centre and positive semi-axes");
  }
  if (rings < 2 || segments < 3 || rings > 1024 || segments > 1024) {
    throw std::invalid_argument("makeEllipsoid(" + name + "): rings must be in 2..1024, segments in 3..1024");
  }
  Mesh mesh;
  mesh.name = name;
  mesh.material = material;
  mesh.label = label;
  const int cols = segments + 1;
  for (int i = 0; i <= rings; ++i) {
    const double theta = kPi * i / rings;
    for (int j = 0; j <= segments; ++j) {
      const double phi = 2.0 * kPi * j / segments;
      const Eigen::Vector3d q(std::cos(theta), std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi));
      const Eigen::Vector3d local = q.cwiseProduct(axes);
      const Eigen::Vector3d normal = rotation * q.cwiseQuotient(axes);
      mesh.vertices.push_back((centre + rotation * local).cast<float>());
      mesh.normals.push_back(normal.normalized().cast<float>());
      mesh.uv.emplace_back(static_cast<float>(theta * axes[0]), static_cast<float>(phi * axes[1]));
    }
  }
  std::vector<bool> accepted(mesh.vertices.size(), true);
  if (keep) {
    for (std::size_t k = 0; k < accepted.size(); ++k) accepted[k] = keep(mesh.vertices[k].cast<double>());
  }
  const bool right_handed = rotation.determinant() > 0.0;
  for (int i = 0; i < rings; ++i) {
    for (int j = 0; j < segments; ++j) {
      const int a = i * cols + j, b = a + 1, c = a + cols, d = c + 1;
      // theta grows along c - a, phi along b - a: (a, c, b) faces outward in a right-handed frame.
      const Eigen::Vector3i t1 = right_handed ? Eigen::Vector3i(a, c, b) : Eigen::Vector3i(a, b, c);
      const Eigen::Vector3i t2 = right_handed ? Eigen::Vector3i(b, c, d) : Eigen::Vector3i(b, d, c);
      for (const Eigen::Vector3i& t : {t1, t2}) {
        if (accepted[static_cast<std::size_t>(t[0])] && accepted[static_cast<std::size_t>(t[1])] &&
            accepted[static_cast<std::size_t>(t[2])]) {
          mesh.triangles.push_back(t);
        }
      }
    }
  }
  return mesh;
}

void smoothNormals(Mesh& mesh) {
  std::vector<Eigen::Vector3f> sum(mesh.vertices.size(), Eigen::Vector3f::Zero());
  for (const Eigen::Vector3i& t : mesh.triangles) {
    const Eigen::Vector3f& a = mesh.vertices[static_cast<std::size_t>(t[0])];
    const Eigen::Vector3f n = (mesh.vertices[static_cast<std::size_t>(t[1])] - a)
                                  .cross(mesh.vertices[static_cast<std::size_t>(t[2])] - a);  // area weighted
    for (int k = 0; k < 3; ++k) sum[static_cast<std::size_t>(t[k])] += n;
  }
  mesh.normals.resize(mesh.vertices.size());
  for (std::size_t k = 0; k < sum.size(); ++k) {
    const float len = sum[k].norm();
    mesh.normals[k] = len > 0.0f ? Eigen::Vector3f(sum[k] / len) : Eigen::Vector3f::UnitZ();
  }
}

}  // namespace massage_cell::sim
