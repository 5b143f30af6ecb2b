// The body under the simulated arm's tool: a skin surface (arm base frame,
// z up) that rises and falls with breathing, and soft tissue under it that
// pushes back on the tool (Hunt-Crossley: stiffening with indentation, damped
// while it changes). SimCell puts it on the Z drive (SimDrive's external
// force), so the drive's torque carries what a real back would put on the
// tool. ROS-free.
//
// Tissue figures (docs/arm.md "Tissue under the tool", from
// shared/reference/massage_forces.md): paraspinal tissue ~1-5 N/mm over the
// first millimetre, stiffening to ~10-35 N/mm at 10-20 mm; F = k x^n with
// n ~1.2-1.5, damping 0.1-1 s/m, +-50 % between subjects; prone breathing
// moves the back 1-5 mm peak to peak at 0.2-0.33 Hz.
#pragma once

#include <functional>
#include <memory>
#include <vector>

#include <Eigen/Core>

namespace massage_cell::arm {

/// Hunt-Crossley contact: F = k x^n (1 + damping * dx/dt) for an indentation x > 0 (m), never pulling.
struct Tissue {
  double stiffness = 8.4e4;  ///< k, N / m^n (8.4e4 with n 1.5: 4 N/mm at 1 mm, 15 N/mm at 15 mm)
  double exponent = 1.5;     ///< n
  double damping = 0.5;      ///< s/m
  /// N, >= 0; 0 for x <= 0 (no contact).
  double force(double indentation, double rate) const;
  /// dF/dx at `indentation` (N/m): how stiff the tissue is there.
  double slope(double indentation) const;
  /// The indentation (m) at which the tissue holds `force` N still.
  double indentationAt(double force) const;
};

/// The back's breathing, as the skin rises and falls under the tool (a sine along z).
struct Breathing {
  double amplitude = 0.003;  ///< m peak to peak
  double period = 4.0;       ///< s
};

class SimBody {
 public:
  /// The skin's height at rest (m, arm base frame) at (x, y); NaN where there is no body (the tool meets nothing).
  using Surface = std::function<double(double x, double y)>;
  /// The tissue at (x, y): regions differ (the spine, the lumbar muscles).
  using TissueAt = std::function<Tissue(double x, double y)>;
  SimBody(Surface surface, TissueAt tissue, Breathing breathing = {});
  /// A flat body: skin at `height` everywhere, one tissue.
  static SimBody flat(double height, const Tissue& tissue, Breathing breathing = {});

  /// The skin's height at (x, y) at time `t` (s): at rest plus breathing (NaN off the body).
  double skinHeight(double x, double y, double t) const;
  /// How deep the tool tip at `tool` presses into the skin at time `t`, m (<= 0: not touching; NaN off the body).
  double indentation(const Eigen::Vector3d& tool, double t) const;
  /// The force the body pushes the tool tip up with, N (>= 0): the tip at `tool` moving at `tool_vz` m/s (up +) at `t`.
  double force(const Eigen::Vector3d& tool, double tool_vz, double t) const;
  const Breathing& breathing() const { return breathing_; }
  Tissue tissueAt(double x, double y) const { return tissue_(x, y); }

 private:
  double breathingOffset(double t) const;
  double breathingRate(double t) const;

  Surface surface_;
  TissueAt tissue_;
  Breathing breathing_;
};

/// A skin known by points on it (the session's true acupoints, arm base frame), updated while the body moves: its
/// height at (x, y) is the inverse-distance mean of the points within `radius` (NaN farther from every point: no
/// body known there). Thread-safe: set() from one thread, height() from the simulated drives'.
class SkinPoints {
 public:
  explicit SkinPoints(double radius) : radius_(radius) {}
  void set(std::vector<Eigen::Vector3d> points);
  double height(double x, double y) const;
  std::size_t size() const;
  /// A SimBody surface reading this skin (keeps it alive).
  static SimBody::Surface surface(std::shared_ptr<const SkinPoints> skin);

 private:
  double radius_;
  std::shared_ptr<const std::vector<Eigen::Vector3d>> points_ = std::make_shared<std::vector<Eigen::Vector3d>>();
};

}  // namespace massage_cell::arm
