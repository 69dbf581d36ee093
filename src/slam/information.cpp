#include "osm_graph_slam/slam/information.h"

#include <algorithm>

namespace osm_graph_slam {

Matrix6d odometryInformation(double fitness, const InformationParams& p) {
  const double w =
      fitness < 0.0 ? 0.5 : std::clamp(fitness / std::max(p.max_fitness, 1e-9), 0.0, 1.0);
  const double std_xyz = p.min_std_xyz + w * (p.max_std_xyz - p.min_std_xyz);
  const double std_rot = p.min_std_rot + w * (p.max_std_rot - p.min_std_rot);
  const double std_yaw = p.min_std_yaw + w * (p.max_std_yaw - p.min_std_yaw);
  Matrix6d info = Matrix6d::Zero();
  info.diagonal().head<3>().setConstant(1.0 / (std_xyz * std_xyz));
  info(3, 3) = info(4, 4) = 1.0 / (std_rot * std_rot);
  info(5, 5) = 1.0 / (std_yaw * std_yaw);
  return info;
}

}  // namespace osm_graph_slam
