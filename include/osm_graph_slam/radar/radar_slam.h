#pragma once
// RadART-SLAM back-end (seed ch. 7.1.5-7.1.6): the radar odometry's keyframes as SE(2) vertices of
// a pose graph, odometry edges between consecutive keyframes, loop closures found by odometry
// candidates (keyframes near the current estimate) and by a radar Scan Context (max power per
// polar cell), verified by submap-to-submap registration and gated by the drift the odometry
// can have accumulated since the candidate; robust (Cauchy) loop edges, optimised on Ceres.
#include <Eigen/Geometry>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "osm_graph_slam/loop/scan_context.h"
#include "osm_graph_slam/radar/radar_odometry.h"

namespace osm_graph_slam {
class ParamReader;
class PoseGraph;
namespace radar {

/// The LiDAR grid, without the radar's near field (the vehicle's own returns, features.min_range).
inline ScanContextParams radarScanContextParams() {
  ScanContextParams p;
  p.min_radius = 3.0;
  return p;
}

struct RadarLoopParams {
  bool enabled = true;
  double min_travel = 60.0;     ///< [m] along the path between the two keyframes
  double search_radius = 25.0;  ///< [m] odometry candidates: keyframes this near the estimate
  double scan_context_threshold = 0.3;  ///< radar Scan Context distance accepted as a candidate
  int max_candidates = 4;               ///< verified per keyframe (nearest / most similar first)
  double submap_travel = 20.0;          ///< [m] keyframes within this much travel form a submap
  double max_rms = 0.32;                ///< [m] registration residual accepted
  double min_overlap = 0.7;             ///< fraction of the query submap with a correspondence
  double gate_base = 10.0;              ///< [m] a loop may move the estimate by gate_base +
  double gate_fraction = 0.05;          ///< gate_fraction * travel since the candidate
  double sigma_translation = 0.2;       ///< [m] loop edge
  double sigma_yaw_deg = 0.3;           ///< loop edge
  double kernel_width = 1.0;            ///< Cauchy, on the whitened error
  ScanContextParams scan_context = radarScanContextParams();  ///< grid (rings, sectors, radii)
};

struct RadarGraphParams {
  double sigma_translation_per_m = 0.02;  ///< odometry edge sigma grows with the distance
  double sigma_yaw_deg_per_m = 0.02;
  double sigma_yaw_per_rad = 0.05;      ///< + this fraction of the angle turned between keyframes
  double min_sigma_translation = 0.05;  ///< [m]
  double min_sigma_yaw_deg = 0.05;
};

struct RadarSlamParams {
  RadarOdometryParams odometry;
  RadarGraphParams graph;
  RadarLoopParams loop;
};

/// Reads the odometry keys (readParams) and "graph/...", "loop/...".
bool readSlamParams(const ParamReader& reader, RadarSlamParams& params, std::string* error);

struct RadarLoop {
  int from = -1, to = -1;                 ///< keyframe indices (from is the older one)
  double from_time = 0.0, to_time = 0.0;  ///< the keyframes' sweep reference times [s]
  Eigen::Isometry2d measurement = Eigen::Isometry2d::Identity();  ///< to in from's frame
  double rms = 0.0, overlap = 0.0;
  bool by_scan_context = false;  ///< found by the descriptor (else by the odometry estimate)
};

struct RadarLoopStats {
  int keyframes_searched = 0, candidates = 0, verified = 0, accepted = 0;
  int rejected_registration = 0, rejected_gate = 0;
  double ms_descriptor = 0, ms_search = 0, ms_verify = 0, ms_optimise = 0;  ///< totals
};

class RadarSlam {
 public:
  explicit RadarSlam(const RadarSlamParams& params);
  ~RadarSlam();

  /// One sweep: odometry, then (on a keyframe) loop search and optimisation.
  RadarOdometryStep process(const RadarPolarScan& scan);
  /// Final optimisation (all loops), call after the last sweep.
  void finish();
  /// A gap in the input: the odometry forgets its velocity and local map (RadarOdometry::restart)
  /// and its pose continues, so the next keyframe hangs from the last one by an odometry edge
  /// that does not know the motion during the gap. The graph and the loops are kept.
  void restart() { odometry_.restart(); }

  /// Corrected pose of every processed sweep (map frame = the first keyframe's odometry frame).
  std::vector<Eigen::Isometry2d> sweepPoses() const;
  const std::vector<double>& sweepTimes() const { return sweep_times_; }
  const std::vector<RadarLoop>& loops() const { return loops_; }
  const RadarLoopStats& loopStats() const { return stats_; }
  size_t numKeyframes() const { return keyframes_.size(); }
  /// The map -> odometry correction at the last keyframe.
  Eigen::Isometry2d mapToOdometry() const;
  /// Corrected pose of every keyframe (map frame).
  std::vector<Eigen::Isometry2d> keyframePoses() const;
  /// The accepted loops as segments between the corrected keyframe positions (map frame).
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> loopSegments() const;

 private:
  struct Keyframe {
    Eigen::Isometry2d odom;               ///< odometry pose
    double travel = 0.0;                  ///< [m] path length up to here
    double time = 0.0;                    ///< the sweep reference time
    std::vector<Eigen::Vector2d> points;  ///< in the keyframe frame
    ScanContext descriptor;
  };
  RadarSlamParams params_;
  RadarOdometry odometry_;
  std::unique_ptr<PoseGraph> graph_;
  std::vector<Keyframe> keyframes_;
  std::vector<RadarLoop> loops_;
  RadarLoopStats stats_;
  std::vector<double> sweep_times_;
  std::vector<Eigen::Isometry2d> sweep_odom_;
  std::vector<int> sweep_keyframe_;  ///< the keyframe each sweep hangs from (-1: none yet)
  double travel_ = 0.0;
  Eigen::Isometry2d last_odom_ = Eigen::Isometry2d::Identity();

  void addKeyframe(const RadarOdometryStep& step);
  void searchLoops(int query);
  bool verify(int query, int candidate, const Eigen::Isometry2d& guess, RadarLoop& loop);
  std::vector<Eigen::Vector2d> submap(int center, bool past_only) const;
  Eigen::Isometry2d estimate(int keyframe) const;
  void optimise();
};

/// Radar Scan Context: the maximum power (0..1) per polar cell of a sweep's points.
ScanContext radarScanContext(const std::vector<Eigen::Vector2d>& points,
                             const std::vector<float>& powers, const ScanContextParams& params);

}  // namespace radar
}  // namespace osm_graph_slam
