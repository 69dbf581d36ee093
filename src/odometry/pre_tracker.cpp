#include "osm_graph_slam/odometry/pre_tracker.h"

#include <algorithm>
#include <chrono>
#include <tuple>
#include <utility>

#include "osm_graph_slam/cloud/voxel_filter.h"

namespace osm_graph_slam {
namespace {

/// The two scales' copies of a scan. The coarse one is made from the fine one when it is
/// coarser: a few thousand points to bin instead of the whole scan (the binning of the scan
/// was half of the pre-tracker's time, frontend_benchmark).
std::pair<PointCloudConstPtr, PointCloudConstPtr> downsampleScales(const PointCloudConstPtr& cloud,
                                                                   const PreTrackerParams& p) {
  PointCloudConstPtr fine = voxelDownsample(cloud, p.fine_voxel);
  PointCloudConstPtr coarse =
      voxelDownsample(p.coarse_voxel >= p.fine_voxel ? fine : cloud, p.coarse_voxel);
  return {coarse, fine};
}

std::unique_ptr<Registration> scaleRegistration(RegistrationParams p, const PreTrackerParams& pre,
                                                double max_correspondence, double voxel) {
  p.max_correspondence_distance = max_correspondence;
  if (!pre.method.empty()) p.method = pre.method;
  if (pre.max_iterations > 0) p.max_iterations = pre.max_iterations;
  p.vgicp_resolution = std::max(p.vgicp_resolution, 2.0 * voxel);  // a few points per voxel
  return createRegistration(p);
}

}  // namespace

PreTracker::PreTracker(const PreTrackerParams& params, const RegistrationParams& registration)
    : params_(params),
      coarse_(scaleRegistration(registration, params, params.coarse_max_correspondence,
                                params.coarse_voxel)),
      fine_(scaleRegistration(registration, params, params.fine_max_correspondence,
                              params.fine_voxel)),
      fitness_gate_(params.fitness_ratio, params.fitness_ratio_floor) {}

PreTracker::~PreTracker() = default;

void PreTracker::reset() {
  previous_ = previous_coarse_ = previous_fine_ = current_coarse_ = current_fine_ = nullptr;
  current_source_ = nullptr;
  fitness_gate_.clear();
}

void PreTracker::remember(const PointCloudConstPtr& cloud) {
  if (!cloud || cloud->empty()) return;
  previous_ = cloud;
  if (cloud.get() == current_source_ && current_coarse_) {
    previous_coarse_ = current_coarse_;  // estimated already: reuse its downsampled copies
    previous_fine_ = current_fine_;
  } else {
    previous_coarse_ = previous_fine_ = nullptr;
  }
  current_source_ = nullptr;
  current_coarse_ = current_fine_ = nullptr;
}

std::optional<PreTrackerEstimate> PreTracker::estimate(const PointCloudConstPtr& cloud,
                                                       const Eigen::Isometry3d& guess) {
  if (!ready() || !cloud || cloud->empty()) return std::nullopt;
  const auto t0 = std::chrono::steady_clock::now();
  if (!previous_coarse_) {
    std::tie(previous_coarse_, previous_fine_) = downsampleScales(previous_, params_);
  }
  if (cloud.get() != current_source_ || !current_coarse_) {
    std::tie(current_coarse_, current_fine_) = downsampleScales(cloud, params_);
    current_source_ = cloud.get();
  }
  PreTrackerEstimate out;
  try {
    coarse_->setTarget(previous_coarse_);
    const RegistrationResult coarse = coarse_->align(current_coarse_, guess);
    fine_->setTarget(previous_fine_);
    const RegistrationResult fine =
        fine_->align(current_fine_, coarse.converged ? coarse.transform : guess);
    out.time_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    if (!fine.converged || !(fine.fitness <= params_.max_fitness) ||
        !fitness_gate_.accepts(fine.fitness))
      return std::nullopt;
    fitness_gate_.add(fine.fitness);
    out.motion = fine.transform;
    out.fitness = fine.fitness;
  } catch (const std::exception&) {
    return std::nullopt;  // a degenerate cloud: no estimate, the tracker has other guesses
  }
  return out;
}

}  // namespace osm_graph_slam
