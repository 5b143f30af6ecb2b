// A nodelet's diagnostics, updated once a second of wall time: diagnostic_updater::Updater::update() goes by ROS
// time, which stalls when a looping bag sends the simulated clock back.
#pragma once

#include <memory>
#include <string>

#include <diagnostic_updater/diagnostic_updater.h>
#include <ros/ros.h>

namespace massage_cell::nodes {

class WallDiagnostics {
 public:
  /// One status named `name` (hardware id "none"), filled by `owner`->`diagnose` every second.
  template <class T>
  void start(ros::NodeHandle& nh, ros::NodeHandle& pnh, const std::string& name, T* owner,
             void (T::*diagnose)(diagnostic_updater::DiagnosticStatusWrapper&)) {
    updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh, pnh.getNamespace());
    updater_->setHardwareID("none");
    updater_->add(name, owner, diagnose);
    timer_ =
        nh.createWallTimer(ros::WallDuration(1.0), [this](const ros::WallTimerEvent&) { updater_->force_update(); });
  }

 private:
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer timer_;
};

}  // namespace massage_cell::nodes
