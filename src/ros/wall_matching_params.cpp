#include "osm_graph_slam/ros/wall_matching_params.h"

#include <ros/node_handle.h>

#include "osm_graph_slam/cloud/params_io.h"
#include "osm_graph_slam/lines/params_io.h"
#include "osm_graph_slam/ros/ros_param_reader.h"

namespace osm_graph_slam {

WallMatchingParams readWallMatchingParams(const std::string& line_extraction_ns,
                                          const std::string& line_matcher_ns, bool* found) {
  WallMatchingParams p;
  const ros::NodeHandle lines_nh(line_extraction_ns), matcher_nh(line_matcher_ns);
  const RosParamReader lines(lines_nh);
  readParams(PrefixedParamReader(lines, "wall"), p.walls);
  readParams(PrefixedParamReader(lines, "segments"), p.segments);
  readParams(RosParamReader(matcher_nh), p.matcher);
  if (found) *found = lines_nh.hasParam("wall") && matcher_nh.hasParam("min_edge_angle_deg");
  return p;
}

}  // namespace osm_graph_slam
