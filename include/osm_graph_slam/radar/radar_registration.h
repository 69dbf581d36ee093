#pragma once
// Scan-to-local-map refinement of the radar odometry (ours, in the spirit of CFEAR, Adolfsson et
// al. 2021): the sweep's detections, motion-compensated to the sweep's reference time and
// Doppler-corrected with the feature-based velocity, are registered point-to-line against the
// detections of the last few keyframes. Sweep-to-sweep velocities integrate their errors at 4 Hz;
// registering against keyframes that stay put for several metres integrates them only once per
// keyframe, and the walls' lines constrain what 0.9 deg azimuth bins blur for single features.
#include <Eigen/Geometry>
#include <deque>
#include <memory>
#include <vector>

#include "osm_graph_slam/radar/radar_features.h"

namespace osm_graph_slam::radar {

struct RadarRegistrationParams {
  bool enabled = true;              ///< false: the feature-based velocity alone (seed 7.1.4)
  int submap_keyframes = 3;         ///< keyframes in the local map
  double max_correspondence = 1.5;  ///< [m] nearest map point farther away: no correspondence
  int normal_neighbours = 6;        ///< map points per line fit
  double max_line_ratio = 0.1;      ///< smaller / larger eigenvalue: a line (else point-to-point)
  int iterations = 12;              ///< Gauss-Newton iterations (re-associating each time)
  double huber = 0.25;              ///< [m] robust kernel width
  int min_correspondences = 40;     ///< fewer: the registration is not trusted
  /// Smaller / larger eigenvalue of the translation information (yaw marginalised) below this:
  /// degenerate (one wall direction only), not trusted.
  double min_translation_ratio = 1e-3;
  /// When the feature velocity failed or the aligned sweep overlaps the map less than
  /// search_below_overlap, yaw hypotheses every yaw_search_step_deg up to +-yaw_search_deg around
  /// the prediction are aligned too and the best kept: a sharp turn from standstill rotates a
  /// sweep by 10 deg or more, beyond what a constant-velocity guess converges from.
  double search_below_overlap = 0.6;
  double yaw_search_deg = 20.0;
  double yaw_search_step_deg = 4.0;
  bool velocity_from_registration = true;  ///< next prediction from the registered motion
  bool recompensate = false;  ///< de-skew again with the registered motion and re-align
};

/// The detections of one sweep at its reference time t_ref, in the sensor frame at t_ref: each
/// range Doppler-corrected with the linear velocity (beta [s], 0 = off), each point moved from
/// its azimuth's time to t_ref along the constant velocity (when motion_compensation).
std::vector<Eigen::Vector2d> compensatedPoints(const std::vector<RadarFeature>& features,
                                               const Eigen::Vector3d& velocity, double t_ref,
                                               double beta, bool clockwise,
                                               bool motion_compensation);

struct RadarAlignment {
  bool ok = false;
  Eigen::Isometry2d pose = Eigen::Isometry2d::Identity();  ///< the sweep in the map frame
  int correspondences = 0;
  double rms = 0.0;  ///< [m] of the robustly weighted residuals at the end
  /// Information of (x, y, yaw) from the last normal equations (J^T W J / sigma^2).
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
};

/// Point-to-line Gauss-Newton registration of 2D points against a fixed 2D point map (Huber
/// weights, re-association each iteration). Map normals from the map points' neighbours.
class PlanarPointMap {
 public:
  PlanarPointMap();
  ~PlanarPointMap();
  PlanarPointMap(PlanarPointMap&&) noexcept;
  PlanarPointMap& operator=(PlanarPointMap&&) noexcept;

  void build(std::vector<Eigen::Vector2d> points, const RadarRegistrationParams& params);
  size_t size() const;
  const std::vector<Eigen::Vector2d>& points() const;
  /// Aligns points (in their own frame) to the map starting from guess.
  RadarAlignment align(const std::vector<Eigen::Vector2d>& points, const Eigen::Isometry2d& guess,
                       const RadarRegistrationParams& params) const;

 private:
  struct Index;
  std::unique_ptr<Index> index_;
};

/// The last submap_keyframes keyframes' points in the odometry frame.
class RadarLocalMap {
 public:
  explicit RadarLocalMap(const RadarRegistrationParams& params) : params_(params) {}
  bool empty() const { return keyframes_.empty(); }
  void clear() {
    keyframes_.clear();
    map_ = PlanarPointMap();
  }
  /// points in the keyframe's frame, pose in the odometry frame.
  void addKeyframe(const Eigen::Isometry2d& pose, const std::vector<Eigen::Vector2d>& points);
  const Eigen::Isometry2d& lastKeyframePose() const { return keyframes_.back().pose; }
  RadarAlignment align(const std::vector<Eigen::Vector2d>& points,
                       const Eigen::Isometry2d& guess) const {
    return map_.align(points, guess, params_);
  }

 private:
  struct Keyframe {
    Eigen::Isometry2d pose;
    std::vector<Eigen::Vector2d> points;
  };
  RadarRegistrationParams params_;
  std::deque<Keyframe> keyframes_;
  PlanarPointMap map_;
};

}  // namespace osm_graph_slam::radar
