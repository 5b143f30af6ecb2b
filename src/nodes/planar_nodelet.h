// The `massage_cell/planar` nodelet: the scene's planes (table, floor, boxes,
// fixtures) as a mesh, from the planar library (include/massage_cell/planar).
// Reconstructs from the synchronised stereo pair every ~stereo_period seconds
// (left optical frame, metres) and from any set of calibrated views given to
// the ~reconstruct service; publishes the newest model, latched, on ~mesh
// (visualization_msgs/Marker TRIANGLE_LIST) and ~planes
// (massage_cell/PlanarModel), and can write it as OBJ / PLY.
//
// Threading: stereo pairs are processed on StereoPairInput's worker thread,
// service calls on the nodelet's callback thread; one mutex serialises the
// reconstructions (each takes the views' memory and both cores).
#pragma once

#include <memory>
#include <mutex>
#include <string>

#include <diagnostic_updater/diagnostic_updater.h>
#include <dynamic_reconfigure/server.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <boost/thread/recursive_mutex.hpp>

#include "massage_cell/PlanarConfig.h"
#include "massage_cell/Reconstruct.h"
#include "massage_cell/planar/reconstruct.h"
#include "stereo_pair_input.h"
#include "wall_diagnostics.h"

namespace massage_cell::nodes {

class PlanarNodelet : public nodelet::Nodelet {
 public:
  PlanarNodelet();
  ~PlanarNodelet() override;

 private:
  using Config = massage_cell::PlanarConfig;

  void onInit() override;  ///< init(); a parameter of the wrong type: FATAL, the node exits 1
  void init();
  void configCb(Config& config, uint32_t level);
  void onPair(const StereoPair& pair);  // the input's worker thread
  bool reconstructCb(massage_cell::Reconstruct::Request& req, massage_cell::Reconstruct::Response& res);
  /// Reconstructs, publishes and (with output_prefix) writes; returns the
  /// model message. Throws on bad views.
  massage_cell::PlanarModel run(const std::vector<planar::View>& views, const std_msgs::Header& header,
                                const std::string& output_prefix, const std::string& source);
  void failed(const std::string& source, const std::string& problem);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& status);

  std::unique_ptr<StereoPairInput> input_;
  ros::Publisher mesh_pub_, planes_pub_;
  ros::ServiceServer reconstruct_srv_;
  std::string views_frame_;    ///< ~views_frame: frame of ~reconstruct's view poses when the request names none
  std::string output_prefix_;  ///< ~output_prefix: write every stereo model as <prefix>.obj / .ply (empty: no)

  boost::recursive_mutex config_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<Config>> reconfigure_server_;
  Config config_;  // guarded by config_mutex_

  std::mutex run_mutex_;  // one reconstruction at a time
  ros::WallTime last_stereo_;

  std::mutex status_mutex_;  // guards the fields below
  PairStats stats_;
  std::string last_source_;
  int last_planes_ = 0;
  planar::StageTimes last_times_;
  ProblemThrottle log_throttle_;
  WallDiagnostics diagnostics_;
};

}  // namespace massage_cell::nodes
