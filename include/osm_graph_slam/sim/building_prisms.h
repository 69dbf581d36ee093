#pragma once
// The simulated world's buildings as 2.5-D prisms (footprint polygon from wall bottom to roof) for
// GNSS signal paths: is the straight path from the antenna to a satellite blocked, and which
// facade can reflect a blocked satellite's signal to the antenna (single specular bounce).
#include <Eigen/Core>
#include <vector>

#include "osm_graph_slam/sim/world.h"

namespace osm_graph_slam::sim {

/// One wall of a building: the vertical rectangle over the footprint edge a -> b.
struct Facade {
  Eigen::Vector2d a = Eigen::Vector2d::Zero(), b = Eigen::Vector2d::Zero();
  Eigen::Vector2d normal = Eigen::Vector2d::Zero();  ///< horizontal, out of the building
  double base_z = 0.0, top_z = 0.0;
  int building = -1;
};

/// A satellite's signal reaching the antenna after one bounce off a facade.
struct SpecularReflection {
  int facade = -1;
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  ///< where the signal meets the facade
  /// Reflected path (satellite -> facade -> antenna) minus the direct one: the NLOS delay [m].
  double extra_path_m = 0.0;
};

class BuildingPrisms {
 public:
  explicit BuildingPrisms(const std::vector<SimBuilding>& buildings, double cell_size = 20.0);

  const std::vector<Facade>& facades() const { return facades_; }
  double maxTopZ() const { return max_top_z_; }
  /// Indices (ascending, each once) of the facades whose bounding box comes within radius of p.
  std::vector<int> facadesNear(const Eigen::Vector2d& p, double radius) const;

  /// True if the path from origin along the unit direction, up to length, passes through a wall
  /// of the candidates below its roof. skip_facade: the facade the path starts on (a reflection).
  bool blocked(const std::vector<int>& candidates, const Eigen::Vector3d& origin,
               const Eigen::Vector3d& direction, double length, int skip_facade = -1) const;

  /// The single-bounce path from satellite to antenna with the smallest extra length over the
  /// candidates within max_distance (horizontal) of the antenna whose two legs are unobstructed.
  /// False if no facade reflects the satellite to the antenna.
  bool shortestReflection(const std::vector<int>& candidates, const Eigen::Vector3d& antenna,
                          const Eigen::Vector3d& satellite, double max_distance,
                          SpecularReflection& reflection) const;

  /// The specular point of one facade (image method: the antenna-to-mirrored-satellite line
  /// crosses the facade plane), ignoring obstruction. False if the facade cannot reflect it.
  bool specularPoint(int facade, const Eigen::Vector3d& antenna, const Eigen::Vector3d& satellite,
                     SpecularReflection& reflection) const;

 private:
  std::vector<Facade> facades_;
  std::vector<std::vector<int>> cells_;  ///< facade indices per grid cell (row-major)
  Eigen::Vector2d grid_min_ = Eigen::Vector2d::Zero();
  double cell_size_ = 20.0;
  int nx_ = 0, ny_ = 0;
  double max_top_z_ = 0.0;

  void buildGrid();
  Eigen::Vector2i cellOf(const Eigen::Vector2d& p) const;
};

}  // namespace osm_graph_slam::sim
