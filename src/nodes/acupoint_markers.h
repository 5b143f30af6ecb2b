// The acupoints as rviz markers (the cect node's ~markers): a sphere coloured by body region and the name per
// acupoint with an estimate.
#pragma once

#include <std_msgs/Header.h>
#include <visualization_msgs/MarkerArray.h>

#include "massage_cell/cect/tracker.h"

namespace massage_cell::nodes {

/// A sphere and the name of acupoint number `index` at `position` (DELETE both when it has no estimate); measured
/// points in their region's colour, held ones grey.
void addAcupointMarkers(const std_msgs::Header& header, int index, const cect::TrackedAcupoint& point,
                        visualization_msgs::MarkerArray* markers);

}  // namespace massage_cell::nodes
