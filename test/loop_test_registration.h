#pragma once
// Test-only Registration back-end on pcl::GeneralizedIterativeClosestPoint, used by the loop
// tests until the project's registration module (createRegistration) is available.
#include <pcl/registration/gicp.h>

#include <chrono>

#include "osm_graph_slam/loop/loop_detector.h"
#include "osm_graph_slam/registration/registration.h"

namespace osm_graph_slam::test {

class PclGicpTestRegistration : public Registration {
 public:
  explicit PclGicpTestRegistration(const RegistrationParams& p) : params_(p) {}
  std::string name() const override { return "test_pcl_gicp"; }
  void setTarget(const PointCloudConstPtr& target) override { target_ = target; }
  RegistrationResult align(const PointCloudConstPtr& source,
                           const Eigen::Isometry3d& guess) override {
    RegistrationResult r;
    if (!source || !target_ || source->size() < 20 || target_->size() < 20) {
      r.message = "empty cloud";
      return r;
    }
    const auto start = std::chrono::steady_clock::now();
    pcl::GeneralizedIterativeClosestPoint<PointT, PointT> gicp;
    gicp.setMaximumIterations(params_.max_iterations);
    gicp.setMaxCorrespondenceDistance(params_.max_correspondence_distance);
    gicp.setTransformationEpsilon(params_.transformation_epsilon);
    gicp.setCorrespondenceRandomness(params_.k_correspondences);
    gicp.setInputSource(source);
    gicp.setInputTarget(target_);
    PointCloud aligned;
    gicp.align(aligned, guess.matrix().cast<float>());
    r.converged = gicp.hasConverged();
    r.transform = Eigen::Isometry3d(gicp.getFinalTransformation().cast<double>());
    r.fitness = gicp.getFitnessScore(params_.max_correspondence_distance);
    r.time_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    return r;
  }

 private:
  RegistrationParams params_;
  PointCloudConstPtr target_;
};

inline RegistrationFactory testRegistrationFactory() {
  return [](const RegistrationParams& p) -> std::unique_ptr<Registration> {
    return std::make_unique<PclGicpTestRegistration>(p);
  };
}

}  // namespace osm_graph_slam::test
