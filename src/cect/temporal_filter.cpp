// Temporal filter of localised acupoints (see temporal_filter.h).
//
// Per name the filter keeps one estimate. What the header leaves open is
// decided here:
//  - the first measurement of a name (or the first after its estimate aged
//    past max_age, or one older than the estimate: the clock went back, as
//    when a replayed bag starts over) starts the estimate afresh;
//  - the covariance of the estimate is blended with the same weight as the
//    position, (1 - alpha) C + alpha C_new: it is never claimed to be much
//    better than one measurement, because the subject's motion between
//    frames (breathing) is not modelled;
//  - an outlier streak "agrees" while each new outlier lies within `gate` of
//    the streak's running mean (`pending`); one that does not starts a new
//    streak. The `reacquire_after`-th agreeing outlier makes the filter jump
//    to the streak's mean: that measurement counts as followed (update()
//    returns true), the earlier ones of the streak as rejected;
//  - a measurement with a non-finite position or covariance is ignored
//    (update() returns false; it is neither an outlier nor rejected);
//  - estimates older than max_age are erased when another measurement
//    arrives, so names that disappear do not accumulate;
//  - clear() forgets every estimate but not the rejected() count.
#include "massage_cell/cect/temporal_filter.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace massage_cell::cect {

namespace {

void checkParams(const TemporalFilterParams& p) {
  std::ostringstream problem;
  if (!(p.alpha > 0.0 && p.alpha <= 1.0)) {
    problem << "alpha = " << p.alpha << " must be in (0, 1]";
  } else if (!(p.gate > 0.0) || !std::isfinite(p.gate)) {
    problem << "gate = " << p.gate << " m must be a positive distance";
  } else if (p.reacquire_after < 1) {
    problem << "reacquire_after = " << p.reacquire_after << " must be >= 1";
  } else if (!(p.max_age > 0.0)) {
    problem << "max_age = " << p.max_age << " s must be > 0";
  }
  const std::string text = problem.str();
  if (!text.empty()) throw std::invalid_argument("temporal filter: " + text);
}

/// Starts (or restarts) the estimate of a point from one measurement.
void restart(FilteredPoint& point, const Eigen::Vector3d& position, const Eigen::Matrix3d& covariance, double stamp) {
  point.position = position;
  point.covariance = covariance;
  point.stamp = stamp;
  point.updates = 1;
  point.outliers = 0;
  point.pending = Eigen::Vector3d::Zero();
}

}  // namespace

TemporalFilter::TemporalFilter(const TemporalFilterParams& params) : params_(params) { checkParams(params_); }

void TemporalFilter::setParams(const TemporalFilterParams& params) {
  checkParams(params);  // throws, keeping the current parameters
  params_ = params;
}

bool TemporalFilter::update(const std::string& name, const Eigen::Vector3d& position, const Eigen::Matrix3d& covariance,
                            double stamp) {
  if (!position.allFinite() || !covariance.allFinite() || !std::isfinite(stamp)) return false;

  // Forget estimates nobody has refreshed for max_age (other names).
  for (auto it = points_.begin(); it != points_.end();) {
    if (it->first != name && stamp - it->second.stamp > params_.max_age) {
      it = points_.erase(it);
    } else {
      ++it;
    }
  }

  auto found = points_.find(name);
  if (found == points_.end()) {
    restart(points_[name], position, covariance, stamp);
    return true;
  }
  FilteredPoint& point = found->second;
  const double age = stamp - point.stamp;
  if (age > params_.max_age || age < 0.0) {  // stale, or the clock went back
    restart(point, position, covariance, stamp);
    return true;
  }

  // Inside the gate: blend.
  if ((position - point.position).norm() <= params_.gate) {
    const double a = params_.alpha;
    point.position = (1.0 - a) * point.position + a * position;
    point.covariance = (1.0 - a) * point.covariance + a * covariance;
    point.stamp = stamp;
    ++point.updates;
    point.outliers = 0;
    return true;
  }

  // An outlier: extend the current streak when it agrees, else start one.
  if (point.outliers > 0 && (position - point.pending).norm() <= params_.gate) {
    ++point.outliers;
    point.pending += (position - point.pending) / point.outliers;
  } else {
    point.outliers = 1;
    point.pending = position;
  }
  if (point.outliers >= params_.reacquire_after) {  // a sustained jump: the subject moved
    point.position = point.pending;
    point.covariance = covariance;
    point.stamp = stamp;
    ++point.updates;
    point.outliers = 0;
    point.pending = Eigen::Vector3d::Zero();
    return true;
  }
  ++rejected_;
  return false;
}

const FilteredPoint* TemporalFilter::get(const std::string& name, double now) const {
  const auto it = points_.find(name);
  if (it == points_.end() || now - it->second.stamp > params_.max_age) return nullptr;
  return &it->second;
}

void TemporalFilter::clear() { points_.clear(); }  // rejected() keeps counting: it is a statistic of the run

}  // namespace massage_cell::cect
