#include "osm_graph_slam/sim/lidar.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "osm_graph_slam/sim/sim_random.h"

namespace osm_graph_slam::sim {

LidarModel LidarModel::hdl64e() {
  LidarModel m;
  m.name = "hdl64e";
  for (int i = 0; i < 32; ++i) m.elevations_deg.push_back(2.0 - i * (10.333 / 31.0));
  for (int i = 0; i < 32; ++i) m.elevations_deg.push_back(-8.833 - i * (15.967 / 31.0));
  m.columns = 2083;
  m.max_range = 120.0;
  m.range_noise_sigma = 0.02;
  m.dropout_probability = 0.02;
  m.mount_height = 1.73;
  return m;
}

LidarModel LidarModel::os1_64() {
  LidarModel m;
  m.name = "os1_64";
  for (int i = 0; i < 64; ++i) m.elevations_deg.push_back(16.6 - i * (33.2 / 63.0));
  m.columns = 1024;
  m.max_range = 120.0;
  m.min_range = 1.0;
  m.range_noise_sigma = 0.03;
  m.dropout_probability = 0.02;
  m.mount_height = 1.80;
  return m;
}

namespace {

/// The firing time offset and azimuth of column c (clockwise from behind).
inline void columnGeometry(const LidarModel& m, int c, double& dt, double& azimuth) {
  const double f = (c + 0.5) / m.columns;
  dt = (f - 0.5) / m.rate_hz;
  azimuth = M_PI - 2.0 * M_PI * f;
}

}  // namespace

SimulatedScan simulateScan(const World& world, const LidarModel& model, const SensorPoseFn& pose,
                           double stamp, uint64_t seed, uint64_t scan_index, bool motion_distortion,
                           bool compensated_sweep) {
  const int beams = int(model.elevations_deg.size());
  const size_t rays = model.numRays();
  std::vector<float> range(rays, -1.0f), intensity(rays, 0.0f);
  std::vector<Eigen::Vector3f> local(rays);
  std::vector<SimLabel> label(rays, SimLabel::kNone);
  std::vector<int32_t> object(rays, -1);
  // Nominal beam directions (used to compute points) and the true ones (used to cast rays);
  // per-beam calibration errors are fixed for the sensor, i.e. drawn from the run seed only.
  std::vector<double> sin_el(beams), cos_el(beams), sin_true(beams), cos_true(beams);
  std::vector<double> range_offset(beams, 0.0);
  for (int b = 0; b < beams; ++b) {
    SimRng calib(hashCombine(seed, 0xCA1B0000ULL + uint64_t(b)));
    const double el = model.elevations_deg[b] * M_PI / 180.0;
    const double el_true =
        el + (model.elevation_bias_deg + model.beam_elevation_sigma_deg * calib.gaussian()) * M_PI /
                 180.0;
    range_offset[b] = model.beam_range_offset_sigma * calib.gaussian();
    sin_el[b] = std::sin(el);
    cos_el[b] = std::cos(el);
    sin_true[b] = std::sin(el_true);
    cos_true[b] = std::cos(el_true);
  }
  const Eigen::Isometry3d pose_at_stamp = pose(stamp);
  const Eigen::Isometry3d stamp_inv = pose_at_stamp.inverse();
  const std::vector<Primitive> moving = world.movingSnapshot(stamp);
  const uint64_t scan_seed = hashCombine(seed, scan_index);

  tbb::parallel_for(
      tbb::blocked_range<int>(0, model.columns, 16), [&](const tbb::blocked_range<int>& r) {
        for (int c = r.begin(); c < r.end(); ++c) {
          double dt, az;
          columnGeometry(model, c, dt, az);
          const Eigen::Isometry3d T = motion_distortion ? pose(stamp + dt) : pose_at_stamp;
          // A driver without motion compensation (KITTI raw, a plain velodyne_pointcloud) gives
          // each point in the frame of its own column; with compensated_sweep the simulator
          // moves it to the stamp's frame by the true motion (what a perfect deskew would do).
          const Eigen::Isometry3d to_stamp =
              compensated_sweep ? stamp_inv * T : Eigen::Isometry3d::Identity();
          const double ca = std::cos(az), sa = std::sin(az);
          for (int b = 0; b < beams; ++b) {
            const size_t i = size_t(c) * beams + b;
            SimRng rng(hashCombine(scan_seed, i));
            if (rng.bernoulli(model.dropout_probability)) continue;
            const Eigen::Vector3d dir_s(cos_el[b] * ca, cos_el[b] * sa, sin_el[b]);
            const Eigen::Vector3d dir_w =
                T.linear() * Eigen::Vector3d(cos_true[b] * ca, cos_true[b] * sa, sin_true[b]);
            RayHit hit;
            if (!world.castRay(T.translation(), dir_w, model.max_range, moving, hit)) continue;
            const double signal =
                hit.reflectivity * hit.cos_incidence * (400.0 / (hit.range * hit.range));
            if (signal < model.detection_threshold) continue;
            const double noisy =
                hit.range + range_offset[b] + model.range_noise_sigma * rng.gaussian();
            if (noisy < model.min_range || noisy > model.max_range) continue;
            const Eigen::Vector3d p_col = dir_s * noisy;
            local[i] = (to_stamp * p_col).cast<float>();
            range[i] = float(noisy);
            // Lambertian-ish return with a slight range fall-off, clamped to KITTI's [0, 1].
            const float reflectance =
                surfaceReflectance(world, hit, T.translation() + dir_w * hit.range, model.texture);
            const double value = reflectance * (0.35 + 0.65 * hit.cos_incidence) *
                                     (1.0 - 0.25 * noisy / model.max_range) +
                                 model.intensity_noise_sigma * rng.gaussian();
            intensity[i] = float(std::clamp(value, 0.0, 1.0));
            label[i] = hit.label;
            object[i] = hit.object;
          }
        }
      });

  SimulatedScan scan;
  scan.cloud.reserve(rays);
  scan.labels.reserve(rays);
  scan.objects.reserve(rays);
  for (size_t i = 0; i < rays; ++i) {
    if (range[i] < 0.0f) continue;
    PointT p;
    p.x = local[i].x();
    p.y = local[i].y();
    p.z = local[i].z();
    p.intensity = intensity[i];
    scan.cloud.push_back(p);
    scan.labels.push_back(label[i]);
    scan.objects.push_back(object[i]);
  }
  scan.cloud.width = uint32_t(scan.cloud.size());
  scan.cloud.height = 1;
  scan.cloud.is_dense = true;
  return scan;
}

}  // namespace osm_graph_slam::sim
