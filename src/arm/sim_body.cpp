// The simulated body under the tool (see sim_body.h).
#include "massage_cell/arm/sim_body.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <stdexcept>
#include <utility>

namespace massage_cell::arm {

double Tissue::force(double indentation, double rate) const {
  if (!(indentation > 0.0)) return 0.0;
  const double elastic = stiffness * std::pow(indentation, exponent);
  return std::max(0.0, elastic * (1.0 + damping * rate));  // a tissue springing back slower than the tool lets go
}

double Tissue::slope(double indentation) const {
  if (!(indentation > 0.0)) return 0.0;
  return exponent * stiffness * std::pow(indentation, exponent - 1.0);
}

double Tissue::indentationAt(double force) const {
  if (!(force > 0.0)) return 0.0;
  return std::pow(force / stiffness, 1.0 / exponent);
}

SimBody::SimBody(Surface surface, TissueAt tissue, Breathing breathing)
    : surface_(std::move(surface)), tissue_(std::move(tissue)), breathing_(breathing) {
  if (!surface_ || !tissue_) throw std::invalid_argument("SimBody: needs a surface and a tissue");
  if (!(breathing_.period > 0.0) || !(breathing_.amplitude >= 0.0))
    throw std::invalid_argument("SimBody: breathing needs a period > 0 and an amplitude >= 0");
}

SimBody SimBody::flat(double height, const Tissue& tissue, Breathing breathing) {
  return SimBody([height](double, double) { return height; }, [tissue](double, double) { return tissue; }, breathing);
}

double SimBody::breathingOffset(double t) const {
  return 0.5 * breathing_.amplitude * std::sin(2.0 * M_PI * t / breathing_.period);
}

double SimBody::breathingRate(double t) const {
  return 0.5 * breathing_.amplitude * 2.0 * M_PI / breathing_.period * std::cos(2.0 * M_PI * t / breathing_.period);
}

double SimBody::skinHeight(double x, double y, double t) const { return surface_(x, y) + breathingOffset(t); }

double SimBody::indentation(const Eigen::Vector3d& tool, double t) const {
  return skinHeight(tool.x(), tool.y(), t) - tool.z();
}

double SimBody::force(const Eigen::Vector3d& tool, double tool_vz, double t) const {
  const double depth = indentation(tool, t);
  if (!(depth > 0.0)) return 0.0;  // not touching, or no body there (NaN)
  // The indentation grows as the skin rises and the tool goes down.
  const double rate = breathingRate(t) - tool_vz;
  return tissue_(tool.x(), tool.y()).force(depth, rate);
}

void SkinPoints::set(std::vector<Eigen::Vector3d> points) {
  std::atomic_store(&points_, std::shared_ptr<const std::vector<Eigen::Vector3d>>(
                                  std::make_shared<std::vector<Eigen::Vector3d>>(std::move(points))));
}

std::size_t SkinPoints::size() const { return std::atomic_load(&points_)->size(); }

double SkinPoints::height(double x, double y) const {
  const auto points = std::atomic_load(&points_);
  double weights = 0.0, sum = 0.0;
  for (const Eigen::Vector3d& p : *points) {
    const double d = std::hypot(p.x() - x, p.y() - y);
    if (d > radius_) continue;
    const double w = 1.0 / std::max(d, 1e-4);  // on a point: that point
    weights += w;
    sum += w * p.z();
  }
  return weights > 0.0 ? sum / weights : NAN;
}

SimBody::Surface SkinPoints::surface(std::shared_ptr<const SkinPoints> skin) {
  return [skin](double x, double y) { return skin->height(x, y); };
}

}  // namespace massage_cell::arm
