#pragma once
// Road graph, a deterministic route with at least one revisit, and the vehicle trajectory along
// it (rounded corners, speed limited by lateral/longitudinal acceleration).
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace osm_graph_slam::sim {

using Polyline2 = std::vector<Eigen::Vector2d>;

/// Undirected graph of road polylines; nodes at identical positions (shared OSM nodes) merge.
struct RoadGraph {
  std::vector<Eigen::Vector2d> nodes;
  std::vector<std::vector<int>> adjacency;

  static RoadGraph fromPolylines(const std::vector<Polyline2>& roads);
  /// Keeps the largest connected component of the 2-core (no dead ends, so no U-turns needed).
  RoadGraph drivableCore() const;
  size_t numEdges() const;
};

struct RouteParams {
  uint64_t seed = 1;
  double length = 1500.0;          ///< [m] (approximate: the route returns to its start)
  double cruise_speed = 8.0;       ///< [m/s]
  double max_lateral_accel = 2.5;  ///< [m/s^2]
  /// [rad/s] (40 deg/s): OSM road polylines bend sharply between close vertices, and the
  /// lateral-acceleration limit alone allowed 120 deg/s on those tiny fillets, beyond any car
  /// (and, with motion distortion, a 12 deg smear within one sweep).
  double max_yaw_rate = 0.7;
  double max_accel = 1.2;       ///< [m/s^2]
  double max_decel = 2.0;       ///< [m/s^2]
  double corner_radius = 10.0;  ///< preferred fillet radius at polyline vertices [m]
};

struct Route {
  std::vector<int> node_ids;  ///< in the drivable graph
  Polyline2 waypoints;
  double length = 0.0;
};

/// Random walk without U-turns (preferring straight on and unused streets) until the walked
/// length plus the way back reaches params.length, then the shortest no-U-turn way back to the
/// start: every route ends where it began (a guaranteed revisit). False if the graph is too small.
bool planRoute(const RoadGraph& graph, const RouteParams& params, Route& route,
               std::string* error = nullptr);

struct TrajectoryState {
  double t = 0.0;  ///< [s] since start
  double s = 0.0;  ///< arc length [m]
  Eigen::Vector2d position = Eigen::Vector2d::Zero();
  double yaw = 0.0;        ///< heading (ENU, 0 = east) [rad], unwrapped
  double speed = 0.0;      ///< [m/s]
  double yaw_rate = 0.0;   ///< [rad/s]
  double accel = 0.0;      ///< longitudinal [m/s^2]
  double curvature = 0.0;  ///< [1/m]
};

/// A planar trajectory sampled densely along the smoothed route.
class Trajectory {
 public:
  static Trajectory fromRoute(const Route& route, const RouteParams& params);
  double duration() const { return samples_.empty() ? 0.0 : samples_.back().t; }
  double length() const { return samples_.empty() ? 0.0 : samples_.back().s; }
  /// Interpolated state at time t (clamped to the ends).
  TrajectoryState at(double t) const;
  const std::vector<TrajectoryState>& samples() const { return samples_; }
  double maxYawRate() const;
  double maxLateralAccel() const;

 private:
  std::vector<TrajectoryState> samples_;
};

/// Number of revisit events: runs of positions (sampled every `step` m) that come within
/// `radius` of a position at least `min_gap` metres of path earlier.
int countRevisits(const Trajectory& trajectory, double radius = 8.0, double min_gap = 150.0,
                  double step = 2.0);

}  // namespace osm_graph_slam::sim
