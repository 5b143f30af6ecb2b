// Small shape functions shared by the simulator's body parts (private to src/sim).
#pragma once

#include <cmath>

namespace massage_cell::sim {

/// Quintic smoothstep (C2): 0 at x = e0, 1 at x = e1 (e0 > e1 allowed).
inline double smooth5(double e0, double e1, double x) {
  const double t = (x - e0) / (e1 - e0);
  if (t <= 0.0) return 0.0;
  if (t >= 1.0) return 1.0;
  return t * t * t * (t * (6.0 * t - 15.0) + 10.0);
}

/// exp(-t^2).
inline double gauss(double t) { return std::exp(-t * t); }

}  // namespace massage_cell::sim
