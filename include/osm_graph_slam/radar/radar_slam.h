#pragma once
// RadART-SLAM back-end (seed ch. 7.1.5-7.1.6): the radar odometry's keyframes as SE(2) vertices of
// a pose graph, odometry edges between consecutive keyframes, loop closures found by odometry
// candidates (keyframes near the current estimate) and by a radar Scan Context (max power per
// polar cell), verified by submap-to-submap registration and gated by the drift the odometry
// can have accumulated since the candidate; robust (Cauchy) loop edges, optimised on Ceres.
#include <Eigen/Geometry>
#include <memory>
#include <optional>
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

/// GNSS fixes and a yaw-rate gyro in the graph (as available: a drive without them runs as
/// before). The graph lives in the first keyframe's frame; the ENU frame of the fixes is an SE(2)
/// anchor vertex, initialised by a least-squares fit once the fixes span min_baseline.
struct RadarNavParams {
  bool gnss_enabled = true;
  double gnss_min_baseline = 30.0;  ///< [m] fixes this far apart before the anchor is set up
  double gnss_min_spacing = 5.0;    ///< [m] of travel between fixes used (their errors correlate)
  double gnss_sigma_floor = 0.5;    ///< [m] a fix is never trusted more than this
  double gnss_sigma_scale = 1.0;    ///< times the fix's own sigma (its covariance)
  double gnss_max_sigma = 10.0;     ///< [m] worse fixes (no fix, dead reckoning) are not used
  double gnss_max_interval = 0.5;   ///< [s] fixes bracketing a keyframe are interpolated
  double gnss_kernel_width = 2.0;   ///< Huber, on the whitened error
  int gnss_optimise_every = 10;     ///< keyframes with a fix between optimisations
  bool imu_enabled = true;
  double gyro_noise_deg_sqrt_s = 0.05;  ///< angle random walk of the integrated yaw rate
  /// The gyro's unmodelled bias [deg/s] and the time over which a loop or the fixes must be able
  /// to correct what it accumulates: the bias is the same in every edge, so it is spread over
  /// them as a random walk, sigma^2 = dt (noise^2 + bias^2 horizon), not added per edge (sqrt(N)
  /// independent edges would hold a drift of bias * horizon as if it were impossible).
  double gyro_bias_deg_s = 0.01;
  double gyro_bias_horizon_s = 100.0;
  double imu_max_gap = 0.5;  ///< [s] a longer gap between samples: no yaw edge
  double wait_s = 1.0;  ///< [s] a keyframe waits this long (sweep time) for late navigation data
};

struct RadarNavStats {
  int gnss_fixes = 0, gnss_rejected_sigma = 0, gnss_out_of_order = 0, gnss_edges = 0;
  int imu_samples = 0, imu_out_of_order = 0, imu_edges = 0, imu_missing = 0;
  bool anchored = false;
};

struct RadarSlamParams {
  RadarOdometryParams odometry;
  RadarGraphParams graph;
  RadarLoopParams loop;
  RadarNavParams nav;
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
  int optimisations = 0;  ///< of the whole graph (on a loop, the GNSS anchor, every few fixes)
  double ms_descriptor = 0, ms_search = 0, ms_verify = 0, ms_optimise = 0;  ///< totals
};

class RadarSlam {
 public:
  explicit RadarSlam(const RadarSlamParams& params);
  ~RadarSlam();

  /// One sweep: odometry, then (on a keyframe) loop search and optimisation.
  RadarOdometryStep process(const RadarPolarScan& scan);
  /// A GNSS fix (ENU [m], sigma per horizontal axis [m]) and a yaw rate about the vertical
  /// [rad/s], each at a time on the sweeps' clock. Give them before the sweep that reaches their
  /// time (a keyframe waits up to nav.wait_s for them); out-of-order samples are counted and
  /// dropped.
  void addGnssFix(double time, const Eigen::Vector2d& enu, double sigma);
  void addYawRate(double time, double rate);
  /// Final optimisation (all loops and navigation edges), call after the last sweep.
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
  const RadarNavStats& navStats() const { return nav_stats_; }
  /// The ENU frame of the fixes in the map frame (p_map = T * p_enu), once anchored.
  std::optional<Eigen::Isometry2d> mapFromEnu() const;
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
    bool has_fix = false;  ///< a GNSS fix at this keyframe's time was used
    Eigen::Vector2d fix = Eigen::Vector2d::Zero();
    double fix_sigma = 0.0;
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
  RadarNavStats nav_stats_;
  std::vector<std::pair<double, Eigen::Vector3d>> fixes_;  ///< time, (x, y, sigma)
  std::vector<std::pair<double, double>> rates_;           ///< time, yaw rate
  size_t nav_next_ = 0;             ///< first keyframe whose navigation edges are not decided yet
  double last_fix_travel_ = -1e18;  ///< travel at the last keyframe given a fix
  int fixes_since_optimise_ = 0;

  void attachNavigation(double now, bool final);
  void attachYawRate(int k);
  void attachFix(int k);
  bool anchor();
  void addFixEdge(int k);
  void pruneNavigation();

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
