#pragma once
// The simulated world: extruded buildings, a gently sloped ground, clutter primitives and a few
// moving objects, with a 2D uniform grid for ray casting (every static object is vertical, so a
// grid over the ground plane is enough).
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "osm_graph_slam/common/geometry2d.h"

namespace osm_graph_slam::sim {

/// What a ray hit (also the semantic label of a simulated point).
enum class SimLabel : uint8_t {
  kNone = 0,
  kGround,
  kBuilding,
  kTree,
  kCar,
  kFence,
  kPole,
  kMoving
};
const char* labelName(SimLabel label);

struct SimBuilding {
  int64_t osm_id = 0;
  Polygon2 outline;      ///< ENU, closed ring, first vertex not repeated
  double base_z = 0.0;   ///< wall bottom (below the lowest ground under the outline)
  double height = 10.0;  ///< above the ground at the outline
  double top_z = 10.0;
  float reflectivity = 0.3f;
};

/// Smooth ground z = sum of three low-frequency sinusoids (slopes of a few percent).
struct GroundModel {
  double amplitude[3] = {1.2, 0.8, 0.5};         ///< [m]
  double wavelength[3] = {420.0, 260.0, 190.0};  ///< [m]
  double direction[3] = {0.3, 1.9, 3.6};         ///< [rad] direction of each wave
  double phase[3] = {0.0, 1.0, 2.0};
  double height(double x, double y) const;
  /// Height and gradient.
  double height(double x, double y, Eigen::Vector2d& gradient) const;
  /// Largest slope magnitude the model can reach (sum of amplitude * 2 pi / wavelength).
  double maxSlope() const;
};

/// A static clutter primitive. Kinds: vertical cylinder (trunk, pole), sphere (tree crown),
/// oriented box (car body/cabin, fence, low wall).
struct Primitive {
  enum Kind : uint8_t { kCylinder, kSphere, kBox } kind = kBox;
  SimLabel label = SimLabel::kCar;
  Eigen::Vector2d center = Eigen::Vector2d::Zero();
  double z0 = 0.0, z1 = 1.0;                                ///< vertical extent (cylinder, box)
  double radius = 0.5;                                      ///< cylinder, sphere
  double sphere_z = 0.0;                                    ///< sphere centre height
  double yaw = 0.0;                                         ///< box heading
  Eigen::Vector2d half_extent = Eigen::Vector2d(1.0, 0.5);  ///< box half length/width
  float reflectivity = 0.3f;
  /// Conservative 2D radius around center (for the grid and culling).
  double footprintRadius() const;
};

/// An object moving back and forth along a segment at constant speed (a car or pedestrian).
struct MovingObject {
  Primitive shape;  ///< a box; center is overridden by the position at time t
  Eigen::Vector2d start = Eigen::Vector2d::Zero(), end = Eigen::Vector2d::Zero();
  double speed = 5.0;  ///< [m/s]
  double phase = 0.0;  ///< [s]
  Eigen::Vector2d positionAt(double t) const;
  double headingAt(double t) const;
};

struct RayHit {
  double range = 0.0;  ///< distance along the (unit) ray
  SimLabel label = SimLabel::kNone;
  int32_t object = -1;  ///< building index for kBuilding, primitive/moving index otherwise
  float reflectivity = 0.0f;
  double cos_incidence = 1.0;  ///< |cos| of the angle between ray and surface normal
};

class World {
 public:
  std::vector<SimBuilding> buildings;
  std::vector<Primitive> primitives;
  std::vector<MovingObject> moving;
  GroundModel ground;
  float ground_reflectivity = 0.18f;
  double cell_size = 2.0;  ///< grid cell [m]
  bool use_grid = true;    ///< false: test every wall and primitive (benchmark reference)

  /// Builds the grid; call after filling buildings/primitives (casting before is an error).
  void finalize();
  bool finalized() const { return !cell_start_.empty(); }

  /// Casts a unit ray; moving objects are placed at time t. False if nothing within max_range.
  bool castRay(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double max_range,
               double t, RayHit& hit) const;
  /// Moving objects as static boxes at time t (a scan uses one snapshot per sweep).
  std::vector<Primitive> movingSnapshot(double t) const;
  bool castRay(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double max_range,
               const std::vector<Primitive>& moving_snapshot, RayHit& hit) const;

  /// Grid statistics for the docs.
  size_t numWalls() const { return walls_.size(); }
  size_t numCells() const { return cell_start_.empty() ? 0 : cell_start_.size() - 1; }

 private:
  struct Wall {
    Eigen::Vector2d a, e;  ///< start and edge vector
    double z0, z1;
    int32_t building;
  };
  // Grid item: index >= 0 is a wall, < 0 is primitive (-1 - index).
  std::vector<int32_t> items_;
  std::vector<uint32_t> cell_start_;
  std::vector<Wall> walls_;
  Eigen::Vector2d grid_min_ = Eigen::Vector2d::Zero();
  int nx_ = 0, ny_ = 0;

  bool castGround(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double max_range,
                  double& t) const;
};

/// Ray-primitive intersection (nearest positive hit below t_max); exposed for tests.
bool intersectPrimitive(const Primitive& p, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                        double t_max, double& t, double& cos_incidence);

}  // namespace osm_graph_slam::sim
