#pragma once
// Road graph, a deterministic route with at least one revisit, and the vehicle trajectory along
// it (rounded corners, speed limited by lateral/longitudinal acceleration), optionally with
// manoeuvres that are hard for scan-matching trackers (sharp turns, U-turns, stops, dead ends, a
// long straight).
#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <optional>
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

/// Manoeuvres that break trackers (doc/simulator.md). All off by default: the route is then
/// exactly the one without manoeuvres (bit-identical). Every manoeuvre is placed by a seeded random
/// stream of its own, one every `spacing` metres of the walk (or more, spread over the first 70 %
/// of the requested length); a manoeuvre that finds no place within 1 km of walking is skipped.
struct ManoeuvreParams {
  bool sharp_turn = false;  ///< slow 90 deg corner with a high yaw rate, then strong acceleration
  bool u_turn = false;      ///< three-point turn in the middle of a street
  bool stop = false;        ///< stop-and-go: standstill for stop_duration
  bool dead_end = false;    ///< into a dead-end street, turn, back (else a mid-street U-turn)
  bool long_straight = false;  ///< the drive starts on the longest straight street of the map

  int sharp_turns = 2;  ///< how many of each (when enabled)
  int u_turns = 1;
  int stops = 2;
  int dead_ends = 1;
  double spacing = 60.0;  ///< minimal walk between two manoeuvres [m]

  /// Sharp turn: at a corner of sharp_turn_min_deg..max_deg, slowed to sharp_turn_speed on a
  /// fillet of sharp_turn_radius (2 m/s on 1.5 m: 76 deg/s, 2.7 m/s^2 lateral; tighter than a
  /// passenger car's ~5 m turning radius on purpose: it reproduces the yaw rate at which a real
  /// drive lost tracking), then sharp_turn_accel back to the cruise speed.
  double sharp_turn_speed = 2.0;              ///< [m/s]
  double sharp_turn_radius = 1.5;             ///< [m]
  double sharp_turn_max_yaw_rate = M_PI / 2;  ///< [rad/s] (90 deg/s)
  double sharp_turn_max_lateral_accel = 3.0;  ///< [m/s^2]
  double sharp_turn_accel = 5.0;              ///< [m/s^2] after the corner, up to cruise speed
  double sharp_turn_min_deg = 60.0, sharp_turn_max_deg = 120.0;

  /// U-turn: a three-point turn (forward left, reverse right, forward left, 60 deg each on
  /// u_turn_radius; 180 deg within pi * radius = 14.1 m of path and +-radius/2 of the road line),
  /// standing still u_turn_pause at each change of direction; in the middle of a street at least
  /// u_turn_min_street long.
  double u_turn_radius = 4.5;               ///< [m] (a mid-size car's rear-axle turning radius)
  double u_turn_speed = 1.5;                ///< [m/s]
  double u_turn_pause = 1.0;                ///< [s]
  double u_turn_min_street = 30.0;          ///< [m]
  double stop_duration = 5.0;               ///< [s] standstill (normal braking and acceleration)
  double dead_end_min_length = 15.0;        ///< [m] dead-end street length accepted
  double dead_end_max_length = 250.0;       ///< [m]
  double dead_end_max_detour = 800.0;       ///< [m] drive at most this far to reach one
  double long_straight_max_turn_deg = 6.0;  ///< per road vertex, and 2x over the whole straight
  double long_straight_max_length = 400.0;  ///< [m]

  bool any() const { return sharp_turn || u_turn || stop || dead_end || long_straight; }
};

/// Parses "none", "all" or a comma list of sharp_turn, u_turn, stop, dead_end, long_straight into
/// the enable flags (counts and parameters kept). False with the unknown name in error.
bool parseManoeuvreList(const std::string& list, ManoeuvreParams& params,
                        std::string* error = nullptr);
/// The enabled manoeuvres as a comma list ("none" if none).
std::string manoeuvreList(const ManoeuvreParams& params);

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
  ManoeuvreParams manoeuvres;   ///< none by default
  /// [m] ENU: the route starts at the junction nearest to this point (a fleet's depot: drives of
  /// one world then share its streets, as real drives from one garage do); none: a seeded one.
  std::optional<Eigen::Vector2d> start_near;
};

/// What the vehicle does at a route waypoint besides a normal rounded corner.
enum class WaypointAction : uint8_t {
  kNone = 0,
  kSharpTurn,  ///< tight, slow corner, then strong acceleration
  kUTurn,      ///< three-point turn: the route comes back the way it came
  kStop,       ///< full stop (at the start of the corner's fillet) for stop_duration
};

/// One manoeuvre of a route; times and arc lengths are filled by Trajectory::fromRoute.
struct ManoeuvreEvent {
  std::string type;       ///< sharp_turn, u_turn, stop, dead_end, long_straight
  bool fallback = false;  ///< dead_end only: no dead-end street reachable, a mid-street U-turn
  size_t first_waypoint = 0, last_waypoint = 0;  ///< span in Route::waypoints
  double length = 0.0;                           ///< dead_end / long_straight: street length [m]
  double t_begin = 0, t_end = 0;                 ///< [s]
  double s_begin = 0, s_end = 0;                 ///< arc length [m]
};

struct Route {
  /// In the drivable graph; -1 for waypoints that are not nodes of it (a U-turn point in the
  /// middle of a street, dead-end streets outside the 2-core).
  std::vector<int> node_ids;
  Polyline2 waypoints;
  double length = 0.0;
  /// Parallel to waypoints; empty when the route has no manoeuvre.
  std::vector<WaypointAction> actions;
  std::vector<ManoeuvreEvent> manoeuvres;  ///< in driving order
  int manoeuvres_skipped = 0;              ///< requested but no place found
};

/// Random walk without U-turns (preferring straight on and unused streets) until the walked
/// length plus the way back reaches params.length, then the shortest no-U-turn way back to the
/// start: every route ends where it began (a guaranteed revisit). False if the graph is too small.
/// With params.manoeuvres, the walk also takes them (see ManoeuvreParams); full_graph (the road
/// graph before drivableCore(), node positions shared) is where dead-end streets are looked for.
bool planRoute(const RoadGraph& graph, const RouteParams& params, Route& route,
               std::string* error = nullptr, const RoadGraph* full_graph = nullptr);

struct TrajectoryState {
  double t = 0.0;  ///< [s] since start
  double s = 0.0;  ///< arc length (distance travelled, also in reverse) [m]
  Eigen::Vector2d position = Eigen::Vector2d::Zero();
  double yaw = 0.0;        ///< heading (ENU, 0 = east) [rad], unwrapped
  double speed = 0.0;      ///< [m/s] along the heading: negative when reversing (three-point turn)
  double yaw_rate = 0.0;   ///< [rad/s] = speed * curvature
  double accel = 0.0;      ///< longitudinal, d(speed)/dt [m/s^2]
  double curvature = 0.0;  ///< d(yaw) / d(displacement along the heading) [1/m]
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
  /// Largest longitudinal acceleration (speeding up, either direction) and braking [m/s^2].
  double maxAccel() const;
  double maxDecel() const;
  /// The route's manoeuvres with their times and arc lengths.
  const std::vector<ManoeuvreEvent>& manoeuvres() const { return manoeuvres_; }

 private:
  std::vector<TrajectoryState> samples_;
  std::vector<ManoeuvreEvent> manoeuvres_;
};

/// Number of revisit events: runs of positions (sampled every `step` m) that come within
/// `radius` of a position at least `min_gap` metres of path earlier.
int countRevisits(const Trajectory& trajectory, double radius = 8.0, double min_gap = 150.0,
                  double step = 2.0);

}  // namespace osm_graph_slam::sim
