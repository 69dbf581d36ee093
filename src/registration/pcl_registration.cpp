// PCL baselines behind the Registration interface: GeneralizedIterativeClosestPoint and
// NormalDistributionsTransform.
#include <pcl/registration/gicp.h>
#include <pcl/registration/ndt.h>

#include <chrono>
#include <cmath>
#include <exception>

#include "registration_backends.h"

namespace osm_graph_slam::detail {
namespace {

/// PCL hides the iteration count of GICP; this subclass exposes it.
template <typename Base>
class IterationAccess : public Base {
 public:
  int iterations() const { return this->nr_iterations_; }
};

PointCloudPtr finitePoints(const PointCloudConstPtr& cloud) {
  PointCloudPtr out = std::make_shared<PointCloud>();
  if (!cloud) return out;
  out->reserve(cloud->size());
  for (const auto& p : cloud->points) {
    if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) out->push_back(p);
  }
  out->header = cloud->header;
  return out;
}

template <typename PclReg>
class PclRegistration : public Registration {
 public:
  PclRegistration(std::string name, const RegistrationParams& params, int min_points)
      : name_(std::move(name)), params_(params), min_points_(min_points) {
    reg_.setMaximumIterations(params.max_iterations);
    reg_.setTransformationEpsilon(params.transformation_epsilon);
    reg_.setMaxCorrespondenceDistance(params.max_correspondence_distance);
  }

  std::string name() const override { return name_; }
  PclReg& impl() { return reg_; }

  void setTarget(const PointCloudConstPtr& target) override {
    target_ = finitePoints(target);
    if (static_cast<int>(target_->size()) >= min_points_) reg_.setInputTarget(target_);
  }

  RegistrationResult align(const PointCloudConstPtr& source,
                           const Eigen::Isometry3d& guess) override {
    const auto start = std::chrono::steady_clock::now();
    RegistrationResult result;
    result.transform = guess;
    const PointCloudPtr src = finitePoints(source);
    if (!target_ || static_cast<int>(target_->size()) < min_points_) {
      result.message =
          name_ + ": target has fewer than " + std::to_string(min_points_) + " valid points";
    } else if (static_cast<int>(src->size()) < min_points_) {
      result.message =
          name_ + ": source has fewer than " + std::to_string(min_points_) + " valid points";
    } else {
      try {
        reg_.setInputSource(src);
        PointCloud aligned;
        reg_.align(aligned, guess.matrix().cast<float>());
        result.iterations = reg_.iterations();
        const Eigen::Matrix4d m = reg_.getFinalTransformation().template cast<double>();
        if (!reg_.hasConverged() || !m.allFinite()) {
          result.message = name_ + ": did not converge";
        } else {
          result.transform.matrix() = m;
          result.transform.linear() =
              Eigen::Quaterniond(m.topLeftCorner<3, 3>()).normalized().toRotationMatrix();
          result.fitness = reg_.getFitnessScore(params_.max_correspondence_distance *
                                                params_.max_correspondence_distance);
          result.converged = std::isfinite(result.fitness);
          if (!result.converged) result.message = name_ + ": no correspondence at the solution";
        }
      } catch (const std::exception& e) {
        result.message = name_ + ": " + e.what();
      }
    }
    if (!result.converged) result.transform = guess;
    result.time_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    return result;
  }

 private:
  std::string name_;
  RegistrationParams params_;
  int min_points_;
  IterationAccess<PclReg> reg_;
  PointCloudPtr target_;
};

}  // namespace

std::unique_ptr<Registration> makePclGicp(const RegistrationParams& params) {
  using Gicp = pcl::GeneralizedIterativeClosestPoint<PointT, PointT>;
  auto reg = std::make_unique<PclRegistration<Gicp>>("pcl_gicp", params,
                                                     std::max(params.k_correspondences, 6));
  reg->impl().setCorrespondenceRandomness(params.k_correspondences);
  return reg;
}

std::unique_ptr<Registration> makePclNdt(const RegistrationParams& params) {
  using Ndt = pcl::NormalDistributionsTransform<PointT, PointT>;
  auto reg = std::make_unique<PclRegistration<Ndt>>("pcl_ndt", params, 6);
  reg->impl().setResolution(static_cast<float>(params.ndt_resolution));
  reg->impl().setStepSize(params.ndt_step_size);
  return reg;
}

}  // namespace osm_graph_slam::detail
