// The piecewise-planar model: plane construction and fitting, the triangle
// mesh of the facets' polygons, its OBJ / PLY export and overlay pictures
// (see model.h).
#include "massage_cell/planar/model.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <locale>
#include <numeric>
#include <stdexcept>
#include <string>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include "massage_cell/camera/point_spread.h"

namespace massage_cell::planar {

namespace {

/// Points closer to a line than this fraction of their spread are collinear
/// (the triangle's height over its longest edge, the second singular value
/// over the first).
constexpr double kCollinear = 1e-6;

// ---------------------------------------------------------------------------
// Polygons

/// Twice the vector area of a polygon: its norm is twice the area of a
/// planar polygon and its direction the normal the vertex order turns about.
Eigen::Vector3d vectorArea(const std::vector<Eigen::Vector3d>& polygon) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (std::size_t i = 1; i + 1 < polygon.size(); ++i)
    sum += (polygon[i] - polygon[0]).cross(polygon[i + 1] - polygon[0]);
  return sum;
}

std::string polygonName(std::size_t facet, std::size_t polygon) {
  return "facet " + std::to_string(facet) + " polygon " + std::to_string(polygon);
}

/// Throws std::invalid_argument for a polygon with < 3 vertices or a non-finite one.
void checkPolygon(const char* caller, std::size_t facet, std::size_t index,
                  const std::vector<Eigen::Vector3d>& polygon) {
  if (polygon.size() < 3)
    throw std::invalid_argument(std::string(caller) + ": " + polygonName(facet, index) + " has " +
                                std::to_string(polygon.size()) + " vertices (needs >= 3)");
  for (const auto& X : polygon)
    if (!X.allFinite())
      throw std::invalid_argument(std::string(caller) + ": " + polygonName(facet, index) + " has a non-finite vertex");
}

// ---------------------------------------------------------------------------
// Mesh

/// Texture coordinates of X in a view (OBJ convention: (0, 0) is the image's
/// bottom-left corner, pixel centres are half a pixel inside it). A vertex
/// behind the camera has no meaningful coordinates and gets (0, 0).
Eigen::Vector2f textureCoordinates(const View& view, const Eigen::Vector3d& X) {
  Eigen::Vector2d pixel;
  if (!project(view.P, X, &pixel)) return Eigen::Vector2f::Zero();
  return {static_cast<float>((pixel.x() + 0.5) / view.image.cols),
          static_cast<float>(1.0 - (pixel.y() + 0.5) / view.image.rows)};
}

/// Appends one convex polygon as a fan, its vertex order turned to be
/// counter-clockwise seen from the side `facet.plane.n` points to.
void appendPolygon(const Facet& facet, int facet_index, const std::vector<Eigen::Vector3d>& polygon,
                   const View* texture, TriangleMesh* mesh) {
  std::vector<Eigen::Vector3d> ordered = polygon;
  if (vectorArea(ordered).dot(facet.plane.n) < 0.0) std::reverse(ordered.begin(), ordered.end());
  const int first = static_cast<int>(mesh->vertices.size());
  for (const auto& X : ordered) {
    mesh->vertices.push_back(X.cast<float>());
    mesh->colours.push_back(facet.colour);
    if (texture) mesh->uv.push_back(textureCoordinates(*texture, X));
  }
  for (int i = 1; i + 1 < static_cast<int>(ordered.size()); ++i) {
    mesh->triangles.push_back({first, first + i, first + i + 1});
    mesh->triangle_facet.push_back(facet_index);
  }
}

const View* textureView(const std::vector<View>& views, int texture_view) {
  if (texture_view < 0) return nullptr;
  if (static_cast<std::size_t>(texture_view) >= views.size())
    throw std::invalid_argument("toMesh: texture_view " + std::to_string(texture_view) + " is out of range (" +
                                std::to_string(views.size()) + " views)");
  const View& view = views[static_cast<std::size_t>(texture_view)];
  if (view.image.empty())
    throw std::invalid_argument("toMesh: texture view " + std::to_string(texture_view) + " has no image");
  return &view;
}

/// Throws std::invalid_argument when the mesh's arrays disagree or a triangle
/// names a vertex that does not exist.
void checkMesh(const char* caller, const TriangleMesh& mesh, bool needs_colours) {
  const std::size_t n = mesh.vertices.size();
  const std::string prefix = std::string(caller) + ": the mesh has " + std::to_string(n) + " vertices but ";
  if (needs_colours && mesh.colours.size() != n)
    throw std::invalid_argument(prefix + std::to_string(mesh.colours.size()) + " colours");
  if (!mesh.uv.empty() && mesh.uv.size() != n)
    throw std::invalid_argument(prefix + std::to_string(mesh.uv.size()) + " texture coordinates");
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t)
    for (int v : mesh.triangles[t])
      if (v < 0 || static_cast<std::size_t>(v) >= n)
        throw std::invalid_argument(prefix + "triangle " + std::to_string(t) + " names vertex " + std::to_string(v));
}

// ---------------------------------------------------------------------------
// Files

std::ofstream openForWriting(const char* caller, const std::string& path) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(std::string(caller) + ": cannot open '" + path + "' for writing");
  out.imbue(std::locale::classic());
  out.precision(std::numeric_limits<float>::max_digits10);
  return out;
}

void finishWriting(const char* caller, const std::string& path, std::ofstream* out) {
  out->close();
  if (!*out) throw std::runtime_error(std::string(caller) + ": failed writing '" + path + "'");
}

/// "folder/name.obj" -> "folder/name.mtl".
std::string materialPath(const std::string& obj_path) {
  const std::size_t slash = obj_path.find_last_of('/');
  const std::size_t dot = obj_path.find_last_of('.');
  const bool has_extension = dot != std::string::npos && (slash == std::string::npos || dot > slash);
  return (has_extension ? obj_path.substr(0, dot) : obj_path) + ".mtl";
}

std::string fileName(const std::string& path) {
  const std::size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

/// A plain white material textured with `texture_image` (a path relative to the .mtl's folder, or absolute).
void writeMaterial(const std::string& path, const std::string& texture_image) {
  std::ofstream out = openForWriting("writeObj", path);
  out << "newmtl planar\nKa 1 1 1\nKd 1 1 1\nKs 0 0 0\nd 1\nillum 1\nmap_Kd " << texture_image << "\n";
  finishWriting("writeObj", path, &out);
}

void writeObjFaces(const TriangleMesh& mesh, std::ofstream* out) {
  const bool uv = !mesh.uv.empty();
  for (const auto& t : mesh.triangles) {
    *out << 'f';
    for (int v : t) {
      *out << ' ' << v + 1;
      if (uv) *out << '/' << v + 1;
    }
    *out << '\n';
  }
}

// ---------------------------------------------------------------------------
// Overlay

/// Distinct colours (BGR) for facets, by index.
const cv::Scalar kPalette[] = {{180, 119, 31}, {14, 127, 255},  {44, 160, 44},  {40, 39, 214},  {189, 103, 148},
                               {75, 86, 140},  {194, 119, 227}, {47, 217, 255}, {34, 189, 188}, {207, 190, 23}};
constexpr double kFillAlpha = 0.4;
constexpr int kShift = 4;               ///< fractional bits of the polygon vertices handed to OpenCV
constexpr double kClipMarginPx = 16.0;  ///< polygons are clipped this far outside the image
constexpr double kNearFraction = 1e-9;  ///< near plane, relative to the polygon's largest depth

cv::Scalar facetColour(std::size_t facet) { return kPalette[facet % (sizeof(kPalette) / sizeof(kPalette[0]))]; }

cv::Mat bgrCopy(const cv::Mat& image) {
  if (image.empty() || image.depth() != CV_8U)
    throw std::invalid_argument("drawOverlay: the view's image must be a non-empty 8-bit image");
  cv::Mat out;
  if (image.channels() == 1)
    cv::cvtColor(image, out, cv::COLOR_GRAY2BGR);
  else if (image.channels() == 4)
    cv::cvtColor(image, out, cv::COLOR_BGRA2BGR);
  else if (image.channels() == 3)
    out = image.clone();
  else
    throw std::invalid_argument("drawOverlay: the view's image has " + std::to_string(image.channels()) +
                                " channels (1, 3 or 4 expected)");
  return out;
}

/// Sutherland-Hodgman against one half-space: the part of a convex polygon
/// of homogeneous image points where a . h + b >= 0. Homogeneous image
/// points are an affine function of the world points (h = P (X, 1)), so
/// interpolating them linearly is interpolating the world points.
std::vector<Eigen::Vector3d> clip(const std::vector<Eigen::Vector3d>& polygon, const Eigen::Vector3d& a, double b) {
  std::vector<Eigen::Vector3d> out;
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const Eigen::Vector3d& p = polygon[i];
    const Eigen::Vector3d& q = polygon[(i + 1) % polygon.size()];
    const double sp = a.dot(p) + b, sq = a.dot(q) + b;
    if (sp >= 0.0) out.push_back(p);
    if ((sp >= 0.0) != (sq >= 0.0)) out.push_back(p + (q - p) * (sp / (sp - sq)));
  }
  return out;
}

/// The visible part of a polygon in the image of size `size` (clipped to the
/// space in front of the camera and to the image plus a margin), as
/// fixed-point pixels with kShift fractional bits; empty when nothing is visible.
std::vector<cv::Point> projectVisible(const Projection& P, const std::vector<Eigen::Vector3d>& polygon, cv::Size size) {
  std::vector<Eigen::Vector3d> h;
  double far = 0.0;
  for (const auto& X : polygon) {
    h.push_back(P * X.homogeneous());
    far = std::max(far, h.back().z());
  }
  if (!(far > 0.0)) return {};
  const double right = size.width - 1 + kClipMarginPx, bottom = size.height - 1 + kClipMarginPx;
  h = clip(h, Eigen::Vector3d(0, 0, 1), -kNearFraction * far);
  h = clip(h, Eigen::Vector3d(1, 0, kClipMarginPx), 0.0);
  h = clip(h, Eigen::Vector3d(-1, 0, right), 0.0);
  h = clip(h, Eigen::Vector3d(0, 1, kClipMarginPx), 0.0);
  h = clip(h, Eigen::Vector3d(0, -1, bottom), 0.0);
  if (h.size() < 3) return {};
  std::vector<cv::Point> pixels;
  for (const auto& p : h)
    pixels.emplace_back(cvRound(p.x() / p.z() * (1 << kShift)), cvRound(p.y() / p.z() * (1 << kShift)));
  return pixels;
}

/// Mean depth of a facet's polygon vertices in the (normalised) camera P.
double meanDepth(const Projection& P, const Facet& facet) {
  double sum = 0.0;
  std::size_t n = 0;
  for (const auto& polygon : facet.polygons)
    for (const auto& X : polygon) {
      sum += P.row(2).dot(X.homogeneous());
      ++n;
    }
  return n > 0 ? sum / static_cast<double>(n) : 0.0;
}

/// Facet indices from the farthest to the nearest.
std::vector<std::size_t> farToNear(const Projection& P, const PlanarModel& model) {
  std::vector<double> depth;
  for (const auto& facet : model.facets) depth.push_back(meanDepth(P, facet));
  std::vector<std::size_t> order(model.facets.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return depth[a] > depth[b]; });
  return order;
}

/// Area centroid of a fixed-point polygon, in pixels (the vertex mean when it has no area).
cv::Point2d centroid(const std::vector<cv::Point>& polygon) {
  const cv::Moments m = cv::moments(polygon);
  if (std::abs(m.m00) > 1e-9) return {m.m10 / m.m00 / (1 << kShift), m.m01 / m.m00 / (1 << kShift)};
  cv::Point2d sum(0, 0);
  for (const auto& p : polygon) sum += cv::Point2d(p) / double(1 << kShift);
  return sum / static_cast<double>(polygon.size());
}

/// The facet's number centred on `at`, white with a dark outline to read on any colour.
void drawLabel(cv::Mat* image, std::size_t facet, const cv::Point2d& at) {
  const std::string text = std::to_string(facet);
  const double scale = std::max(0.4, std::min(image->cols, image->rows) / 800.0);
  const int thickness = std::max(1, cvRound(scale * 1.5));
  int baseline = 0;
  const cv::Size size = cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, scale, thickness, &baseline);
  const cv::Point origin(cvRound(at.x - size.width / 2.0), cvRound(at.y + size.height / 2.0));
  cv::putText(*image, text, origin, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(0, 0, 0), thickness + 2, cv::LINE_AA);
  cv::putText(*image, text, origin, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(255, 255, 255), thickness, cv::LINE_AA);
}

}  // namespace

// ---------------------------------------------------------------------------
// Plane

double Plane::angleTo(const Plane& other) const {
  // atan2 of sine and |cosine| is accurate near 0 and 90 degrees, where acos
  // and asin are not, and needs no unit normals.
  const double sine = n.cross(other.n).norm(), cosine = std::abs(n.dot(other.n));
  return std::atan2(sine, cosine) * 180.0 / M_PI;
}

bool Plane::through(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, Plane* plane) {
  // The normal follows the right-hand rule: a, b, c are counter-clockwise
  // seen from the side n points to.
  const Eigen::Vector3d normal = (b - a).cross(c - a);
  const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
  // |normal| / longest is the height over the longest edge.
  if (!normal.allFinite() || !(normal.norm() > kCollinear * longest * longest)) return false;
  plane->n = normal.normalized();
  plane->d = -plane->n.dot(a);
  return true;
}

bool Plane::fit(const std::vector<Eigen::Vector3d>& points, Plane* plane) {
  if (points.size() < 3) return false;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& X : points) mean += X;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix3Xd centred(3, static_cast<Eigen::Index>(points.size()));
  for (std::size_t i = 0; i < points.size(); ++i) centred.col(static_cast<Eigen::Index>(i)) = points[i] - mean;
  if (!centred.allFinite()) return false;
  // The normal is the direction of least spread; the points must spread
  // along two directions (rank 2) for it to be defined.
  const camera::PrincipalAxes axes = camera::principalAxes(centred);
  const Eigen::Vector3d& sigma = axes.spread;
  if (!(sigma(1) > kCollinear * sigma(0))) return false;
  plane->n = axes.axes.col(2).normalized();
  plane->d = -plane->n.dot(mean);
  return true;
}

// ---------------------------------------------------------------------------
// Model, mesh, files

double PlanarModel::area() const {
  double sum = 0.0;
  for (const auto& facet : facets)
    for (const auto& polygon : facet.polygons) sum += 0.5 * vectorArea(polygon).norm();
  return sum;
}

TriangleMesh toMesh(const PlanarModel& model, const std::vector<View>& views, int texture_view) {
  const View* texture = textureView(views, texture_view);
  TriangleMesh mesh;
  for (std::size_t f = 0; f < model.facets.size(); ++f) {
    const Facet& facet = model.facets[f];
    for (std::size_t p = 0; p < facet.polygons.size(); ++p) {
      checkPolygon("toMesh", f, p, facet.polygons[p]);
      appendPolygon(facet, static_cast<int>(f), facet.polygons[p], texture, &mesh);
    }
  }
  return mesh;
}

void writeObj(const TriangleMesh& mesh, const std::string& path, const std::string& texture_image) {
  checkMesh("writeObj", mesh, false);
  const bool material = !texture_image.empty() && !mesh.uv.empty();
  std::ofstream out = openForWriting("writeObj", path);
  out << "# planar model: " << mesh.vertices.size() << " vertices, " << mesh.triangles.size() << " triangles\n";
  if (material) {
    writeMaterial(materialPath(path), texture_image);
    out << "mtllib " << fileName(materialPath(path)) << "\nusemtl planar\n";
  }
  for (const auto& v : mesh.vertices) out << "v " << v.x() << ' ' << v.y() << ' ' << v.z() << '\n';
  for (const auto& t : mesh.uv) out << "vt " << t.x() << ' ' << t.y() << '\n';
  writeObjFaces(mesh, &out);
  finishWriting("writeObj", path, &out);
}

void writePly(const TriangleMesh& mesh, const std::string& path) {
  checkMesh("writePly", mesh, true);
  std::ofstream out = openForWriting("writePly", path);
  out << "ply\nformat ascii 1.0\ncomment planar model\n"
      << "element vertex " << mesh.vertices.size() << "\n"
      << "property float x\nproperty float y\nproperty float z\n"
      << "property uchar red\nproperty uchar green\nproperty uchar blue\n"
      << "element face " << mesh.triangles.size() << "\n"
      << "property list uchar int vertex_indices\nend_header\n";
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    const auto& v = mesh.vertices[i];
    const cv::Vec3b& bgr = mesh.colours[i];
    out << v.x() << ' ' << v.y() << ' ' << v.z() << ' ' << int(bgr[2]) << ' ' << int(bgr[1]) << ' ' << int(bgr[0])
        << '\n';
  }
  for (const auto& t : mesh.triangles) out << "3 " << t[0] << ' ' << t[1] << ' ' << t[2] << '\n';
  finishWriting("writePly", path, &out);
}

// ---------------------------------------------------------------------------
// Overlay

cv::Mat drawOverlay(const View& view, const PlanarModel& model) {
  const cv::Mat image = bgrCopy(view.image);
  // Normalised: w = P.row(2) X is the depth, positive in front of the camera.
  const Projection P = normalisedProjection(view.P);
  std::vector<std::vector<std::vector<cv::Point>>> visible(model.facets.size());
  for (std::size_t f = 0; f < model.facets.size(); ++f)
    for (std::size_t p = 0; p < model.facets[f].polygons.size(); ++p) {
      checkPolygon("drawOverlay", f, p, model.facets[f].polygons[p]);
      auto pixels = projectVisible(P, model.facets[f].polygons[p], image.size());
      if (!pixels.empty()) visible[f].push_back(std::move(pixels));
    }
  // Fills on a layer blended once, so overlapping facets do not mix: the
  // nearer one, drawn later, wins.
  const std::vector<std::size_t> order = farToNear(P, model);
  cv::Mat layer = image.clone();
  for (std::size_t f : order)
    for (const auto& polygon : visible[f]) cv::fillConvexPoly(layer, polygon, facetColour(f), cv::LINE_AA, kShift);
  cv::Mat overlay;
  cv::addWeighted(layer, kFillAlpha, image, 1.0 - kFillAlpha, 0.0, overlay);
  const int thickness = std::max(1, std::min(image.cols, image.rows) / 400);
  for (std::size_t f : order) {
    cv::polylines(overlay, visible[f], true, facetColour(f), thickness, cv::LINE_AA, kShift);
    for (const auto& polygon : visible[f]) drawLabel(&overlay, f, centroid(polygon));
  }
  return overlay;
}

}  // namespace massage_cell::planar
