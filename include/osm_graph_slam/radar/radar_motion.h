#pragma once
// Radar front-end, motion side (RadART-SLAM seed sec. 7.1.4, eqs. 7.1-7.9): the body velocity
// w = (vx, vy, omega) of a constant-velocity sensor between two sweeps, estimated from matched
// features whose every point carries its own time in the sweep (motion compensation), with the
// Doppler range correction of eq. 7.9, inside a RANSAC on minimal samples.
//
// Model: the sensor pose at time t relative to its pose at time 0 is T(t) = exp(t w^) (SE(2)).
// A static point seen at t1 as p1 and at t2 as p2 satisfies T(t1) p1 = T(t2) p2, so
// p2 = T_m p1 with T_m = exp(-(t2 - t1) w^) (eq. 7.1); the error e_m = p2 - T_m p1 (eq. 7.2) is
// minimised over w by Gauss-Newton (eqs. 7.4-7.6).
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

namespace osm_graph_slam::radar {

/// SE(2) exponential of a twist (vx, vy, omega) * dt: rotation omega dt, translation V(theta) v dt.
Eigen::Isometry2d se2Exp(const Eigen::Vector3d& twist, double dt);
/// Inverse of se2Exp(., 1): the twist (vx, vy, omega) with exp = T.
Eigen::Vector3d se2Log(const Eigen::Isometry2d& T);

/// One matched feature pair: range, beam direction and time of each observation.
struct RadarCorrespondence {
  double range1 = 0.0, range2 = 0.0;  ///< [m] measured
  Eigen::Vector2d dir1 = Eigen::Vector2d::UnitX(), dir2 = Eigen::Vector2d::UnitX();  ///< unit
  double t1 = 0.0, t2 = 0.0;  ///< [s] time of each observation
};

/// Eq. 7.9: the range a static target would have, given the measured one and the sensor's
/// linear velocity: r + beta * (v . dir). beta = f_t / (df/dt) [s].
double dopplerCorrectedRange(double measured_range, const Eigen::Vector2d& dir,
                             const Eigen::Vector2d& linear_velocity, double beta);

struct MotionEstimatorParams {
  bool motion_compensation = true;  ///< false: every point at its sweep's reference time
  bool doppler_correction = true;   ///< eq. 7.9 with doppler_beta
  double doppler_beta = 0.049;      ///< [s] f_t / (df/dt); the seed's value for MulRan
  int ransac_iterations = 400;
  double inlier_threshold = 0.35;  ///< [m] the seed's value
  int gauss_newton_iterations = 10;
  int min_inliers = 8;
  uint32_t seed = 7;
};

struct MotionEstimate {
  bool ok = false;
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  ///< (vx, vy, omega) [m/s, m/s, rad/s]
  std::vector<int> inliers;                            ///< indices into the correspondences
  double rms_error = 0.0;                              ///< [m] over the inliers
};

/// Times used when motion compensation is off: every observation of sweep 1 at t_ref1, of
/// sweep 2 at t_ref2 (the caller passes the sweeps' reference times).
struct SweepTimes {
  double t_ref1 = 0.0, t_ref2 = 0.0;
};

/// Residual e = p2 - exp(-(t2 - t1) w^) p1 of one correspondence, both points Doppler-corrected
/// with w's linear part when beta != 0.
Eigen::Vector2d correspondenceError(const RadarCorrespondence& c, const Eigen::Vector3d& w,
                                    double beta);

/// Gauss-Newton on the given correspondences from w0 (eqs. 7.4-7.6). Returns w.
Eigen::Vector3d refineVelocity(const std::vector<RadarCorrespondence>& correspondences,
                               const std::vector<int>& use, const Eigen::Vector3d& w0, double beta,
                               int iterations);

/// Motion-compensated RANSAC + Gauss-Newton. initial_velocity seeds the Doppler correction of
/// the minimal samples (the previous estimate). With motion_compensation off the times of the
/// correspondences are replaced by the sweep times.
MotionEstimate estimateVelocity(std::vector<RadarCorrespondence> correspondences,
                                const MotionEstimatorParams& params, const SweepTimes& sweeps,
                                const Eigen::Vector3d& initial_velocity = Eigen::Vector3d::Zero());

}  // namespace osm_graph_slam::radar
