// Nodelets `massage_cell/stereo_camera` and `massage_cell/mono_camera`.
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>

#include "camera_driver.h"

namespace massage_cell::nodes {

template <int Views>
class CameraNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    driver_ = std::make_unique<CameraDriver>(getNodeHandle(), getPrivateNodeHandle(), Views);
    try {
      driver_->start();
    } catch (const std::exception& e) {
      NODELET_FATAL_STREAM("configuration error: " << e.what());
      driver_.reset();
      throw;  // nodelet::Loader::load() fails: the node exits non-zero
    }
  }
  std::unique_ptr<CameraDriver> driver_;
};

class StereoCameraNodelet : public CameraNodelet<2> {};
class MonoCameraNodelet : public CameraNodelet<1> {};

}  // namespace massage_cell::nodes

PLUGINLIB_EXPORT_CLASS(massage_cell::nodes::StereoCameraNodelet, nodelet::Nodelet)
PLUGINLIB_EXPORT_CLASS(massage_cell::nodes::MonoCameraNodelet, nodelet::Nodelet)
