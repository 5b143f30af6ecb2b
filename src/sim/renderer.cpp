// Ray-traced rendering of a Scene: Embree finds the intersections, the
// shading (ambient + directional Lambert + Blinn-Phong, hard shadows),
// supersampling, exposure, sRGB encoding and sensor noise are ours.
#include "massage_cell/sim/renderer.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <limits>
#include <memory>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <embree3/rtcore.h>
#include <pmmintrin.h>
#include <xmmintrin.h>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <opencv2/core/utility.hpp>

namespace massage_cell::sim {

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
/// Offset of shadow-ray origins along the normal, relative to the hit distance.
constexpr float kShadowOffset = 1e-4f;

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

const char* errorName(RTCError code) {
  switch (code) {
    case RTC_ERROR_NONE:
      return "RTC_ERROR_NONE";
    case RTC_ERROR_UNKNOWN:
      return "RTC_ERROR_UNKNOWN";
    case RTC_ERROR_INVALID_ARGUMENT:
      return "RTC_ERROR_INVALID_ARGUMENT";
    case RTC_ERROR_INVALID_OPERATION:
      return "RTC_ERROR_INVALID_OPERATION";
    case RTC_ERROR_OUT_OF_MEMORY:
      return "RTC_ERROR_OUT_OF_MEMORY";
    case RTC_ERROR_UNSUPPORTED_CPU:
      return "RTC_ERROR_UNSUPPORTED_CPU";
    case RTC_ERROR_CANCELLED:
      return "RTC_ERROR_CANCELLED";
  }
  return "RTC_ERROR (unrecognised code)";
}

/// Collects the text Embree reports through its error callback.
struct ErrorLog {
  std::mutex mutex;
  std::string last;
};

void onEmbreeError(void* user, RTCError code, const char* str) {
  auto* log = static_cast<ErrorLog*>(user);
  std::lock_guard<std::mutex> lock(log->mutex);
  log->last = std::string(errorName(code)) + (str ? std::string(" (") + str + ")" : std::string());
}

/// Flush-to-zero / denormals-are-zero for the calling thread while alive
/// (Embree's recommendation); restores the previous MXCSR.
class ScopedFlushDenormals {
 public:
  ScopedFlushDenormals() : saved_(_mm_getcsr()) {
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
  }
  ~ScopedFlushDenormals() { _mm_setcsr(saved_); }
  ScopedFlushDenormals(const ScopedFlushDenormals&) = delete;
  ScopedFlushDenormals& operator=(const ScopedFlushDenormals&) = delete;

 private:
  unsigned int saved_;
};

void validateMesh(const Mesh& mesh, std::size_t index) {
  const std::string who = "Renderer: mesh '" + mesh.name + "' (#" + std::to_string(index) + "): ";
  const std::size_t nv = mesh.vertices.size();
  const std::size_t nt = mesh.triangles.size();
  if (nv > static_cast<std::size_t>(std::numeric_limits<int>::max()) ||
      nt > static_cast<std::size_t>(std::numeric_limits<int>::max())) {
    throw std::invalid_argument(who + "too many vertices or triangles");
  }
  for (std::size_t i = 0; i < nv; ++i) {
    if (!mesh.vertices[i].allFinite()) {
      throw std::invalid_argument(who + "vertex " + std::to_string(i) + " is not finite");
    }
  }
  for (std::size_t t = 0; t < nt; ++t) {
    for (int k = 0; k < 3; ++k) {
      const int idx = mesh.triangles[t][k];
      if (idx < 0 || static_cast<std::size_t>(idx) >= nv) {
        throw std::invalid_argument(who + "triangle " + std::to_string(t) + " has vertex index " + std::to_string(idx) +
                                    " out of range [0, " + std::to_string(nv) + ")");
      }
    }
  }
  if (!mesh.normals.empty() && mesh.normals.size() != nv) {
    throw std::invalid_argument(who + "has " + std::to_string(mesh.normals.size()) + " normals for " +
                                std::to_string(nv) + " vertices (must be 0 or equal)");
  }
  for (std::size_t i = 0; i < mesh.normals.size(); ++i) {
    if (!mesh.normals[i].allFinite()) {
      throw std::invalid_argument(who + "normal " + std::to_string(i) + " is not finite");
    }
  }
  if (!mesh.uv.empty() && mesh.uv.size() != nv) {
    throw std::invalid_argument(who + "has " + std::to_string(mesh.uv.size()) + " uv coordinates for " +
                                std::to_string(nv) + " vertices (must be 0 or equal)");
  }
  for (std::size_t i = 0; i < mesh.uv.size(); ++i) {
    if (!mesh.uv[i].allFinite()) throw std::invalid_argument(who + "uv " + std::to_string(i) + " is not finite");
  }
  if (!mesh.triangle_labels.empty() && mesh.triangle_labels.size() != nt) {
    throw std::invalid_argument(who + "has " + std::to_string(mesh.triangle_labels.size()) + " triangle labels for " +
                                std::to_string(nt) + " triangles (must be 0 or equal)");
  }
  if (!mesh.material.albedo.allFinite() || !std::isfinite(mesh.material.specular) ||
      !std::isfinite(mesh.material.shininess)) {
    throw std::invalid_argument(who + "material albedo, specular and shininess must be finite");
  }
}

void validateOptions(const RenderOptions& o) {
  if (o.supersample < 1 || o.supersample > 8) {
    throw std::invalid_argument("RenderOptions: supersample must be in 1..8, got " + std::to_string(o.supersample));
  }
  if (!(o.noise_sigma >= 0.0f) || !std::isfinite(o.noise_sigma)) {
    throw std::invalid_argument("RenderOptions: noise_sigma must be finite and >= 0, got " + num(o.noise_sigma));
  }
  if (!(o.exposure > 0.0f) || !std::isfinite(o.exposure)) {
    throw std::invalid_argument("RenderOptions: exposure must be finite and > 0, got " + num(o.exposure));
  }
}

Eigen::Vector3f validLightDirection(const Lighting& l) {
  if (!l.direction_to_light.allFinite() || !(l.direction_to_light.norm() > 0.0f)) {
    throw std::invalid_argument("Lighting: direction_to_light must be finite and non-zero");
  }
  if (!std::isfinite(l.intensity) || l.intensity < 0.0f || !std::isfinite(l.ambient) || l.ambient < 0.0f) {
    throw std::invalid_argument("Lighting: intensity and ambient must be finite and >= 0, got " + num(l.intensity) +
                                " and " + num(l.ambient));
  }
  return l.direction_to_light.normalized();
}

void validateCamera(const CameraModel& camera) {
  if (camera.width <= 0 || camera.height <= 0) {
    throw std::invalid_argument("Renderer: camera size must be positive, got " + std::to_string(camera.width) + "x" +
                                std::to_string(camera.height));
  }
  if (!camera.centre().allFinite()) throw std::invalid_argument("Renderer: camera centre must be finite");
}

/// Standard sRGB transfer function (IEC 61966-2-1) of a linear value in [0, 1].
inline float srgbEncode(float c) {
  c = std::clamp(c, 0.0f, 1.0f);
  return c <= 0.0031308f ? 12.92f * c : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
}

inline void setRay(RTCRayHit& rh, const Eigen::Vector3f& o, const Eigen::Vector3f& d, float tnear) {
  rh.ray.org_x = o.x();
  rh.ray.org_y = o.y();
  rh.ray.org_z = o.z();
  rh.ray.dir_x = d.x();
  rh.ray.dir_y = d.y();
  rh.ray.dir_z = d.z();
  rh.ray.tnear = tnear;
  rh.ray.tfar = kInf;
  rh.ray.time = 0.0f;
  rh.ray.mask = 0xFFFFFFFFu;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
}

}  // namespace

// ---------------------------------------------------------------------------

Lighting Lighting::preset(LightPreset preset) {
  Lighting l;
  switch (preset) {
    case LightPreset::kTopLeft:
      l.direction_to_light = Eigen::Vector3f(0.5f, 0.6f, 1.0f).normalized();
      break;
    case LightPreset::kTopCentre:
      l.direction_to_light = Eigen::Vector3f(0.5f, 0.0f, 1.0f).normalized();
      break;
    case LightPreset::kTopRight:
      l.direction_to_light = Eigen::Vector3f(0.5f, -0.6f, 1.0f).normalized();
      break;
  }
  l.intensity = 0.85f;
  l.ambient = 0.30f;
  return l;
}

// ---------------------------------------------------------------------------

namespace {

/// One view's camera rays: exact ones at the pixel centres on a grid padded by one pixel (x = -1..W, y = -1..H),
/// each scaled to unit optical depth (q = d / (d . z)), and the sampling of its pixels.
struct ViewRays {
  int W = 0, H = 0, n = 1;       ///< image size, sub-samples per pixel side
  bool centre_is_sample = true;  ///< odd n: the middle sub-sample is the pixel centre
  int middle = 0;                ///< its index
  int samples_per_row = 0, rays_per_row = 0;
  Eigen::Vector3d centre_d, optical_z;
  Eigen::Vector3f centre;
  std::shared_ptr<const std::vector<Eigen::Vector3d>> grid;

  /// Unit direction through (sx, sy), -0.5 < sx < W - 0.5, -0.5 < sy < H - 0.5: q is affine in the pixel for a
  /// pinhole camera, so the sub-pixel rays are bilinear interpolations of the grid - exact without distortion, within
  /// ~1e-4 px with it (second order in the distortion's curvature over half a pixel) - and exactly the grid's value
  /// at integer (pixel centre) coordinates.
  Eigen::Vector3f direction(double sx, double sy) const {
    const int GW = W + 2;
    const int x0 = std::clamp(static_cast<int>(std::floor(sx)), -1, W - 1);
    const int y0 = std::clamp(static_cast<int>(std::floor(sy)), -1, H - 1);
    const double fx = sx - x0;
    const double fy = sy - y0;
    const Eigen::Vector3d* g = &(*grid)[static_cast<std::size_t>(y0 + 1) * GW + (x0 + 1)];
    Eigen::Vector3d q = g[0];
    if (fx != 0.0) q = (1.0 - fx) * q + fx * g[1];
    if (fy != 0.0) {
      Eigen::Vector3d q1 = g[GW];
      if (fx != 0.0) q1 = (1.0 - fx) * q1 + fx * g[GW + 1];
      q = (1.0 - fy) * q + fy * q1;
    }
    return q.normalized().cast<float>();
  }
};

/// One thread's buffers for a row. Sample k of the row lies in sub-row j = k / (W n), pixel x = (k / n) % W,
/// sub-column i = k % n, so that neighbouring rays are neighbours in the image (coherent packets); the pixel centres
/// follow (even n).
struct RowBuffers {
  std::vector<RTCRayHit> rays;
  std::vector<Eigen::Vector3f> dirs, radiance, direct;
  std::vector<int> shadow_owner;
  std::vector<RTCRay> shadow_rays;

  explicit RowBuffers(const ViewRays& v)
      : rays(static_cast<std::size_t>(v.rays_per_row)),
        dirs(static_cast<std::size_t>(v.rays_per_row)),
        radiance(static_cast<std::size_t>(v.samples_per_row)) {
    direct.reserve(static_cast<std::size_t>(v.samples_per_row));
    shadow_owner.reserve(static_cast<std::size_t>(v.samples_per_row));
    shadow_rays.reserve(static_cast<std::size_t>(v.samples_per_row));
  }
};

/// Row y's primary rays: the sub-pixel grid, then (even n) the pixel centres.
void primaryRays(const ViewRays& v, int y, RowBuffers& b) {
  const int n = v.n;
  for (int j = 0; j < n; ++j) {
    const double sy = y - 0.5 + (j + 0.5) / n;
    for (int x = 0; x < v.W; ++x) {
      for (int i = 0; i < n; ++i) {
        const double sx = x - 0.5 + (i + 0.5) / n;
        const std::size_t k = (static_cast<std::size_t>(j) * v.W + x) * n + i;
        b.dirs[k] = v.direction(sx, sy);
        setRay(b.rays[k], v.centre, b.dirs[k], 0.0f);
      }
    }
  }
  if (!v.centre_is_sample) {
    for (int x = 0; x < v.W; ++x) {
      const std::size_t k = static_cast<std::size_t>(v.samples_per_row + x);
      b.dirs[k] = v.direction(x, y);
      setRay(b.rays[k], v.centre, b.dirs[k], 0.0f);
    }
  }
}

/// Additive Gaussian noise on every channel (rounded, saturated), from `seed`.
void addNoise(float sigma, std::uint64_t seed, cv::Mat* image) {
  cv::RNG rng(seed);
  cv::Mat noise(image->size(), CV_32FC3);
  rng.fill(noise, cv::RNG::NORMAL, cv::Scalar::all(0.0), cv::Scalar::all(sigma));
  cv::Mat noisy;
  image->convertTo(noisy, CV_32FC3);
  noisy += noise;
  noisy.convertTo(*image, CV_8UC3);
}

}  // namespace

struct Renderer::Impl {
  ErrorLog log;
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::vector<Mesh> meshes;  ///< geomID == index
  Eigen::Vector3f background;

  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }

  /// Ray grids of recently rendered cameras (see render()); rayDirection()
  /// depends on the size, K, D and orientation only, so those are the key.
  struct GridEntry {
    int width, height;
    Eigen::Matrix3d K, rotation;
    std::vector<double> D;
    std::shared_ptr<const std::vector<Eigen::Vector3d>> grid;
  };
  static constexpr std::size_t kGridCacheSize = 4;
  mutable std::mutex grid_mutex;
  mutable std::vector<GridEntry> grid_cache;  ///< most recent last

  std::shared_ptr<const std::vector<Eigen::Vector3d>> rayGrid(const CameraModel& camera,
                                                              const Eigen::Vector3d& optical_z) const {
    const Eigen::Matrix3d rotation = camera.world_from_camera.linear();
    {
      std::lock_guard<std::mutex> lock(grid_mutex);
      for (auto it = grid_cache.begin(); it != grid_cache.end(); ++it) {
        if (it->width == camera.width && it->height == camera.height && it->K == camera.K && it->rotation == rotation &&
            it->D == camera.D) {
          GridEntry hit = std::move(*it);
          grid_cache.erase(it);
          grid_cache.push_back(std::move(hit));
          return grid_cache.back().grid;
        }
      }
    }
    const int W = camera.width;
    const int H = camera.height;
    const int GW = W + 2;
    const int GH = H + 2;
    auto grid = std::make_shared<std::vector<Eigen::Vector3d>>(static_cast<std::size_t>(GW) * GH);
    (void)camera.rayDirection(0.0, 0.0);  // a camera that throws does so here, in the calling thread
    std::mutex error_mutex;
    std::exception_ptr error;
    cv::parallel_for_(cv::Range(0, GH), [&](const cv::Range& rows) {
      try {
        for (int gy = rows.start; gy < rows.end; ++gy) {
          for (int gx = 0; gx < GW; ++gx) {
            const Eigen::Vector3d d = camera.rayDirection(gx - 1, gy - 1);
            const double dz = d.dot(optical_z);
            (*grid)[static_cast<std::size_t>(gy) * GW + gx] =
                (d.allFinite() && dz > 1e-6) ? Eigen::Vector3d(d / dz) : Eigen::Vector3d::Constant(kNaN);
          }
        }
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
      }
    });
    if (error) std::rethrow_exception(error);
    for (const Eigen::Vector3d& q : *grid) {
      if (!q.allFinite()) {
        throw std::invalid_argument("Renderer: the camera's rayDirection() is not finite or not in front of it");
      }
    }
    std::lock_guard<std::mutex> lock(grid_mutex);
    if (grid_cache.size() >= kGridCacheSize) grid_cache.erase(grid_cache.begin());
    grid_cache.push_back(GridEntry{W, H, camera.K, rotation, camera.D, grid});
    return grid;
  }

  void check(const std::string& what) {
    const RTCError code = rtcGetDeviceError(device);
    if (code == RTC_ERROR_NONE) return;
    std::string text;
    {
      std::lock_guard<std::mutex> lock(log.mutex);
      text = log.last;
    }
    throw std::runtime_error("Renderer: Embree failed to " + what + ": " + errorName(code) +
                             (text.empty() ? std::string() : " - " + text));
  }

  /// Surface data of an Embree hit: shading happens on these.
  struct Surface {
    Eigen::Vector3f normal;     ///< unit shading normal, facing the viewer
    Eigen::Vector3f geometric;  ///< unit geometric normal, facing the viewer
    Eigen::Vector2f uv;
    const Mesh* mesh;
  };

  Surface surface(const RTCRayHit& rh, const Eigen::Vector3f& dir, const Eigen::Vector3f& point) const {
    const Mesh& mesh = meshes[rh.hit.geomID];
    const Eigen::Vector3i& tri = mesh.triangles[rh.hit.primID];
    const float u = rh.hit.u;
    const float v = rh.hit.v;
    const float w = 1.0f - u - v;
    Surface s;
    s.mesh = &mesh;
    Eigen::Vector3f ng(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z);
    const float ng_len = ng.norm();
    ng = ng_len > 0.0f ? Eigen::Vector3f(ng / ng_len) : Eigen::Vector3f(-dir);
    if (ng.dot(dir) > 0.0f) ng = -ng;
    s.geometric = ng;
    s.normal = ng;
    if (!mesh.normals.empty()) {
      Eigen::Vector3f n = w * mesh.normals[tri[0]] + u * mesh.normals[tri[1]] + v * mesh.normals[tri[2]];
      const float len = n.norm();
      if (len > 1e-12f) {
        n /= len;
        s.normal = n.dot(ng) < 0.0f ? Eigen::Vector3f(-n) : n;
      }
    }
    if (!mesh.uv.empty()) {
      s.uv = w * mesh.uv[tri[0]] + u * mesh.uv[tri[1]] + v * mesh.uv[tri[2]];
    } else {
      s.uv = point.head<2>();
    }
    return s;
  }

  RTCRayHit trace(const Eigen::Vector3f& o, const Eigen::Vector3f& d, RTCIntersectContext* ctx) const {
    RTCRayHit rh;
    setRay(rh, o, d, 0.0f);
    rtcIntersect1(scene, ctx, &rh);
    return rh;
  }

  /// Shading of one primary sample, split so that shadow rays can be traced
  /// in bulk: radiance = base + (visible ? direct : 0).
  struct Shade {
    Eigen::Vector3f base;    ///< ambient part (or the background on a miss)
    Eigen::Vector3f direct;  ///< diffuse + specular part of the light
    bool needs_shadow_ray;   ///< direct > 0 and its visibility still has to be tested
    Eigen::Vector3f shadow_origin;
  };

  Shade shade(const RTCRayHit& rh, const Eigen::Vector3f& o, const Eigen::Vector3f& d, const Eigen::Vector3f& light,
              const Lighting& lighting, bool shadows) const {
    Shade out;
    out.direct.setZero();
    out.needs_shadow_ray = false;
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) {
      out.base = background;
      return out;
    }
    const float t = rh.ray.tfar;
    const Eigen::Vector3f p = o + t * d;
    const Surface s = surface(rh, d, p);
    const Material& m = s.mesh->material;
    const Eigen::Vector3f albedo = albedoAt(m, s.uv);
    out.base = lighting.ambient * albedo;
    const float ndotl = s.normal.dot(light);
    // No direct light when it is behind the shading normal or behind the
    // actual (flat) triangle, which would shadow itself.
    if (!(ndotl > 0.0f) || !(lighting.intensity > 0.0f) || s.geometric.dot(light) <= 0.0f) return out;
    float specular = 0.0f;
    if (m.specular > 0.0f) {
      const Eigen::Vector3f h = (light - d).normalized();  // v = -d points toward the camera
      const float ndoth = std::max(0.0f, s.normal.dot(h));
      specular = m.specular * lighting.intensity * std::pow(ndoth, m.shininess);
    }
    out.direct = (lighting.intensity * ndotl) * albedo + Eigen::Vector3f::Constant(specular);
    if (shadows) {
      out.needs_shadow_ray = true;
      out.shadow_origin = p + (kShadowOffset * std::max(t, 1e-3f)) * s.geometric;
    }
    return out;
  }

  /// Shades row y's samples in b.radiance (its primary rays already traced): shadow rays collected and traced
  /// together.
  void shadeRow(const Eigen::Vector3f& centre, const Eigen::Vector3f& light, const Lighting& lighting, bool shadows,
                int samples, RTCIntersectContext* ctx, RowBuffers& b) const;
  /// Image (mean of the samples in linear space, exposure, sRGB) and ground truth of the pixel-centre rays of row y.
  void writeRow(const ViewRays& v, int y, float exposure, const RowBuffers& b, ViewRender& out) const;
};

Renderer::Renderer(const Scene& scene) : impl_(std::make_unique<Impl>()) {
  if (!scene.background.allFinite()) throw std::invalid_argument("Renderer: scene background must be finite");
  for (std::size_t i = 0; i < scene.meshes.size(); ++i) validateMesh(scene.meshes[i], i);
  if (scene.meshes.size() >= static_cast<std::size_t>(RTC_INVALID_GEOMETRY_ID)) {
    throw std::invalid_argument("Renderer: too many meshes");
  }
  Impl& im = *impl_;
  im.meshes = scene.meshes;
  im.background = scene.background;

  im.device = rtcNewDevice(nullptr);
  if (!im.device) {
    throw std::runtime_error(std::string("Renderer: Embree could not create a device: ") +
                             errorName(rtcGetDeviceError(nullptr)));
  }
  rtcSetDeviceErrorFunction(im.device, &onEmbreeError, &im.log);
  im.scene = rtcNewScene(im.device);
  im.check("create a scene");
  rtcSetSceneBuildQuality(im.scene, RTC_BUILD_QUALITY_HIGH);

  for (std::size_t i = 0; i < im.meshes.size(); ++i) {
    const Mesh& mesh = im.meshes[i];
    if (mesh.triangles.empty()) continue;  // nothing to intersect; index stays reserved
    RTCGeometry geom = rtcNewGeometry(im.device, RTC_GEOMETRY_TYPE_TRIANGLE);
    im.check("create the geometry of mesh '" + mesh.name + "'");
    // Embree-owned copies (they come with the padding Embree needs).
    auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                           3 * sizeof(float), mesh.vertices.size()));
    auto* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                              3 * sizeof(unsigned), mesh.triangles.size()));
    if (!vb || !ib) {
      rtcReleaseGeometry(geom);
      im.check("allocate the buffers of mesh '" + mesh.name + "'");
      throw std::runtime_error("Renderer: Embree could not allocate the buffers of mesh '" + mesh.name + "'");
    }
    for (std::size_t k = 0; k < mesh.vertices.size(); ++k) {
      vb[3 * k + 0] = mesh.vertices[k].x();
      vb[3 * k + 1] = mesh.vertices[k].y();
      vb[3 * k + 2] = mesh.vertices[k].z();
    }
    for (std::size_t k = 0; k < mesh.triangles.size(); ++k) {
      ib[3 * k + 0] = static_cast<unsigned>(mesh.triangles[k][0]);
      ib[3 * k + 1] = static_cast<unsigned>(mesh.triangles[k][1]);
      ib[3 * k + 2] = static_cast<unsigned>(mesh.triangles[k][2]);
    }
    rtcCommitGeometry(geom);
    rtcAttachGeometryByID(im.scene, geom, static_cast<unsigned>(i));
    rtcReleaseGeometry(geom);  // the scene holds its reference
    im.check("add mesh '" + mesh.name + "'");
  }
  rtcCommitScene(im.scene);
  im.check("build the scene");
}

Renderer::~Renderer() = default;

void Renderer::Impl::shadeRow(const Eigen::Vector3f& centre, const Eigen::Vector3f& light, const Lighting& lighting,
                              bool shadows, int samples, RTCIntersectContext* ctx, RowBuffers& b) const {
  b.direct.clear();
  b.shadow_owner.clear();
  b.shadow_rays.clear();
  for (int k = 0; k < samples; ++k) {
    const Shade sh = shade(b.rays[k], centre, b.dirs[k], light, lighting, shadows);
    b.radiance[k] = sh.base;
    if (!sh.needs_shadow_ray) {
      b.radiance[k] += sh.direct;
      continue;
    }
    RTCRay r;
    r.org_x = sh.shadow_origin.x();
    r.org_y = sh.shadow_origin.y();
    r.org_z = sh.shadow_origin.z();
    r.dir_x = light.x();
    r.dir_y = light.y();
    r.dir_z = light.z();
    r.tnear = 0.0f;
    r.tfar = kInf;
    r.time = 0.0f;
    r.mask = 0xFFFFFFFFu;
    r.id = 0;
    r.flags = 0;
    b.shadow_rays.push_back(r);
    b.shadow_owner.push_back(k);
    b.direct.push_back(sh.direct);
  }
  if (b.shadow_rays.empty()) return;
  rtcOccluded1M(scene, ctx, b.shadow_rays.data(), static_cast<unsigned>(b.shadow_rays.size()), sizeof(RTCRay));
  for (std::size_t s = 0; s < b.shadow_rays.size(); ++s) {
    // Embree sets tfar to -inf when the ray is occluded.
    if (b.shadow_rays[s].tfar >= 0.0f) b.radiance[b.shadow_owner[s]] += b.direct[s];
  }
}

void Renderer::Impl::writeRow(const ViewRays& v, int y, float exposure, const RowBuffers& b, ViewRender& out) const {
  const int n = v.n;
  const float inv_samples = 1.0f / static_cast<float>(n * n);
  auto* img = out.image.ptr<cv::Vec3b>(y);
  auto* dep = out.depth.ptr<float>(y);
  auto* pts = out.points.ptr<cv::Vec3f>(y);
  auto* lab = out.labels.ptr<std::uint8_t>(y);
  for (int x = 0; x < v.W; ++x) {
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    for (int j = 0; j < n; ++j) {
      const std::size_t k0 = (static_cast<std::size_t>(j) * v.W + x) * n;
      for (int i = 0; i < n; ++i) sum += b.radiance[k0 + i];
    }
    const Eigen::Vector3f c = sum * (inv_samples * exposure);
    img[x] = cv::Vec3b(cv::saturate_cast<std::uint8_t>(255.0f * srgbEncode(c.z())),
                       cv::saturate_cast<std::uint8_t>(255.0f * srgbEncode(c.y())),
                       cv::saturate_cast<std::uint8_t>(255.0f * srgbEncode(c.x())));
    // Ground truth of the exact pixel-centre ray (for odd n the middle sub-sample is exactly (x, y)).
    const std::size_t kc = v.centre_is_sample ? (static_cast<std::size_t>(v.middle) * v.W + x) * n + v.middle
                                              : static_cast<std::size_t>(v.samples_per_row + x);
    const RTCRayHit& rh = b.rays[kc];
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) {
      dep[x] = kNaN;
      pts[x] = cv::Vec3f(kNaN, kNaN, kNaN);
      lab[x] = kLabelBackground;
      continue;
    }
    const double t = rh.ray.tfar;
    const Eigen::Vector3d dir = b.dirs[kc].cast<double>();
    const Eigen::Vector3d p = v.centre_d + t * dir;
    dep[x] = static_cast<float>(t * dir.dot(v.optical_z));
    pts[x] = cv::Vec3f(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()));
    const Mesh& mesh = meshes[rh.hit.geomID];
    lab[x] = mesh.triangle_labels.empty() ? mesh.label : mesh.triangle_labels[rh.hit.primID];
  }
}

ViewRender Renderer::render(const CameraModel& camera, const Lighting& lighting, const RenderOptions& options) const {
  validateOptions(options);
  validateCamera(camera);
  const Eigen::Vector3f light = validLightDirection(lighting);
  const Impl& im = *impl_;

  ViewRays v;
  v.W = camera.width;
  v.H = camera.height;
  v.n = options.supersample;
  v.centre_is_sample = (v.n % 2) == 1;
  v.middle = (v.n - 1) / 2;
  v.centre_d = camera.centre();
  v.centre = v.centre_d.cast<float>();
  v.optical_z = camera.world_from_camera.linear().col(2).normalized();
  v.samples_per_row = v.W * v.n * v.n;
  v.rays_per_row = v.samples_per_row + (v.centre_is_sample ? 0 : v.W);
  // rayDirection once per pixel instead of n^2 + 1 times (with distortion it iterates, about 1 us per call); the
  // grid is cached for the last few cameras (same size, K, D and orientation).
  v.grid = im.rayGrid(camera, v.optical_z);

  ViewRender out;
  out.image.create(v.H, v.W, CV_8UC3);
  out.depth.create(v.H, v.W, CV_32F);
  out.points.create(v.H, v.W, CV_32FC3);
  out.labels.create(v.H, v.W, CV_8U);
  cv::parallel_for_(cv::Range(0, v.H), [&](const cv::Range& rows) {
    ScopedFlushDenormals ftz;
    RTCIntersectContext coherent;
    rtcInitIntersectContext(&coherent);
    coherent.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    RowBuffers b(v);
    for (int y = rows.start; y < rows.end; ++y) {
      primaryRays(v, y, b);
      rtcIntersect1M(im.scene, &coherent, b.rays.data(), static_cast<unsigned>(v.rays_per_row), sizeof(RTCRayHit));
      im.shadeRow(v.centre, light, lighting, options.shadows, v.samples_per_row, &coherent, b);
      im.writeRow(v, y, options.exposure, b, out);
    }
  });
  if (options.noise_sigma > 0.0f) addNoise(options.noise_sigma, options.noise_seed, &out.image);
  return out;
}

bool Renderer::intersect(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction, Hit* hit) const {
  if (!origin.allFinite() || !direction.allFinite() || !(direction.norm() > 0.0)) {
    throw std::invalid_argument("Renderer::intersect: origin and direction must be finite, direction non-zero");
  }
  const Impl& im = *impl_;
  const Eigen::Vector3d dd = direction.normalized();
  const Eigen::Vector3f d = dd.cast<float>();
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  const RTCRayHit rh = im.trace(origin.cast<float>(), d, &ctx);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
  if (hit) {
    const double t = rh.ray.tfar;
    hit->distance = t;
    hit->point = origin + t * d.cast<double>();
    const Impl::Surface s = im.surface(rh, d, hit->point.cast<float>());
    hit->normal = s.normal.cast<double>().normalized();
    const Mesh& mesh = im.meshes[rh.hit.geomID];
    hit->label = mesh.triangle_labels.empty() ? mesh.label : mesh.triangle_labels[rh.hit.primID];
    hit->mesh = static_cast<int>(rh.hit.geomID);
  }
  return true;
}

}  // namespace massage_cell::sim
