#include "osm_graph_slam/sim/stereo_camera_sim.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "osm_graph_slam/sim/sim_random.h"

namespace osm_graph_slam::sim {

Eigen::Isometry3d kittiCameraFromLidar(const Eigen::Isometry3d& world_from_lidar) {
  Eigen::Isometry3d lidar_from_camera = Eigen::Isometry3d::Identity();
  // Camera axes in the LiDAR frame: x right = -y, y down = -z, z forward = x.
  lidar_from_camera.linear() << 0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0;
  lidar_from_camera.translation() << 0.27, 0.0, -0.08;
  return world_from_lidar * lidar_from_camera;
}

cv::Mat renderCameraImage(const World& world, const StereoCameraModel& model,
                          const Eigen::Isometry3d& world_from_camera, double t, uint64_t seed) {
  cv::Mat image(model.height, model.width, CV_8UC1);
  const std::vector<Primitive> moving = world.movingSnapshot(t);
  const Eigen::Matrix3d R = world_from_camera.linear();
  const Eigen::Vector3d origin = world_from_camera.translation();
  const uint64_t frame_seed = hashCombine(seed, static_cast<uint64_t>(std::llround(t * 1e3)));
  tbb::parallel_for(
      tbb::blocked_range<int>(0, model.height), [&](const tbb::blocked_range<int>& rows) {
        for (int v = rows.begin(); v < rows.end(); ++v) {
          uint8_t* out = image.ptr<uint8_t>(v);
          for (int u = 0; u < model.width; ++u) {
            const Eigen::Vector3d ray = (R * Eigen::Vector3d((u + 0.5 - model.cx) / model.fx,
                                                             (v + 0.5 - model.cy) / model.fy, 1.0))
                                            .normalized();
            double gray = model.sky;
            RayHit hit;
            if (world.castRay(origin, ray, model.max_range, moving, hit)) {
              const float reflectance =
                  surfaceReflectance(world, hit, origin + ray * hit.range, model.texture);
              gray = model.exposure * 255.0 * reflectance *
                     (model.ambient + (1.0 - model.ambient) * hit.cos_incidence);
            }
            SimRng rng(hashCombine(frame_seed, static_cast<uint64_t>(v) * 65536u + u));
            gray += model.noise_sigma * rng.gaussian();
            out[u] = static_cast<uint8_t>(std::clamp(std::lround(gray), 0L, 255L));
          }
        }
      });
  return image;
}

void renderStereoPair(const World& world, const StereoCameraModel& model,
                      const Eigen::Isometry3d& world_from_left, double t, uint64_t seed,
                      cv::Mat& left, cv::Mat& right) {
  Eigen::Isometry3d left_from_right = Eigen::Isometry3d::Identity();
  left_from_right.translation().x() = model.baseline;
  left = renderCameraImage(world, model, world_from_left, t, hashCombine(seed, 0));
  right =
      renderCameraImage(world, model, world_from_left * left_from_right, t, hashCombine(seed, 1));
}

}  // namespace osm_graph_slam::sim
