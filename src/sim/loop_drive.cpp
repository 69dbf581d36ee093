#include "osm_graph_slam/sim/loop_drive.h"

#include <chrono>

#include "osm_graph_slam/cloud/cloud_prefilter.h"
#include "osm_graph_slam/sim/simulator.h"

namespace osm_graph_slam::sim {

namespace {

/// Odometry step: the true step with the distance scaled and the heading biased.
Eigen::Isometry3d driftedStep(const Eigen::Isometry3d& step, const LoopDriveParams& p) {
  Eigen::Isometry3d out = step;
  const double length = step.translation().norm();
  out.translation() *= 1.0 + p.odometry_scale_error;
  out.linear() =
      out.linear() * Eigen::AngleAxisd(p.odometry_yaw_bias * length, Eigen::Vector3d::UnitZ());
  return out;
}

}  // namespace

bool simulateLoopDrive(const LoopDriveParams& params, LoopDrive& drive, std::string* error) {
  SimulationParams p;
  p.seed = params.seed;
  p.city.world = params.world;
  p.city.forest_density = params.forest_density;
  p.clutter_enabled = params.world == "city";  // forests bring their own undergrowth
  p.route.length = params.length;
  p.nav.rtk = true;
  UrbanSimulator sim;
  if (!sim.build(p, error)) return false;
  const auto start = std::chrono::steady_clock::now();
  const CloudPrefilter prefilter;
  drive = LoopDrive();
  Eigen::Isometry3d odom = Eigen::Isometry3d::Identity();
  double last_s = -1e9, accum = 0.0;
  for (size_t k = 0; k < sim.numScans(); ++k) {
    const double t = sim.scanTime(k);
    const double s = sim.trajectory().at(t).s;
    if (s - last_s < params.spacing) continue;
    last_s = s;
    const Eigen::Isometry3d pose = sim.sensorPose(t);
    if (drive.truth.empty()) {
      odom = pose;
    } else {
      const Eigen::Isometry3d step = drive.truth.back().inverse() * pose;
      accum += step.translation().norm() * (1.0 + params.odometry_scale_error);
      odom = odom * driftedStep(step, params);
    }
    const CloudPrefilterResult filtered = prefilter.filter(sim.simulate(k).cloud);
    LoopKeyframe kf;
    kf.id = drive.keyframes.size();
    kf.odom_pose = odom;
    kf.accum_distance = accum;
    kf.cloud = filtered.cloud;
    drive.truth.push_back(pose);
    drive.keyframes.push_back(kf);
    if (params.max_keyframes > 0 && int(drive.keyframes.size()) >= params.max_keyframes) break;
  }
  drive.simulate_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return true;
}

}  // namespace osm_graph_slam::sim
