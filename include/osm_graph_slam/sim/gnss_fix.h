#pragma once
// Single-point positioning as a receiver does it: position and clock bias from four or more
// pseudoranges by Gauss-Newton least squares, and the dilution of precision of that geometry.
#include <Eigen/Core>
#include <vector>

namespace osm_graph_slam::sim {

struct Pseudorange {
  Eigen::Vector3d satellite = Eigen::Vector3d::Zero();  ///< ENU [m]
  double range_m = 0.0;  ///< geometric range + clock bias + errors [m]
};

struct PositionFix {
  bool valid = false;  ///< false: fewer than 4 ranges or a singular geometry
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< ENU [m]
  double clock_bias_m = 0.0;                           ///< receiver clock times c [m]
  double hdop = 0.0;  ///< horizontal dilution of precision of the ranges used
  double vdop = 0.0;
  int iterations = 0;
};

/// Least-squares position and clock from the ranges, Gauss-Newton started at initial_position
/// with zero clock bias (a receiver starts from its last fix; the simulator from the truth).
PositionFix solvePositionFix(const std::vector<Pseudorange>& ranges,
                             const Eigen::Vector3d& initial_position, int max_iterations = 10);

}  // namespace osm_graph_slam::sim
