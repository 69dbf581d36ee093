// Multi-cue photometric registration: the analytic Jacobians of the pixel residuals against
// numeric differences, a known 6-DoF motion recovered on simulated urban HDL-64E scans, the
// intensity cue turned off for a scan without intensity, and bad parameters refused.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <iostream>

#include "osm_graph_slam/multi_cue/multi_cue_registration.h"
#include "osm_graph_slam/sim/lidar.h"
#include "osm_graph_slam/sim/simulator.h"
#include "sim_worlds.h"

using namespace osm_graph_slam;
using namespace osm_graph_slam::sim;

namespace {

constexpr double kDeg = M_PI / 180.0;

/// An HDL-64E scan of the city from the sensor pose of route scan k moved by `motion` (in the
/// sensor frame).
PointCloud scanAt(size_t k, const Eigen::Isometry3d& motion, uint64_t noise_seed) {
  const UrbanSimulator& sim = test::smallCity();
  const Eigen::Isometry3d pose = sim.sensorPose(sim.scanTime(k)) * motion;
  return simulateScan(
             sim.scene().world, LidarModel::hdl64e(), [pose](double) { return pose; }, 0.0,
             noise_seed, k)
      .cloud;
}

/// 0.3 m mostly forward, 2 deg of yaw and a little roll and pitch.
Eigen::Isometry3d knownMotion() {
  Eigen::Isometry3d m = Eigen::Isometry3d::Identity();
  m.linear() = (Eigen::AngleAxisd(2.0 * kDeg, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(0.4 * kDeg, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(-0.3 * kDeg, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  m.translation() = Eigen::Vector3d(0.27, 0.12, 0.04);
  return m;
}

double translationError(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.inverse() * b).translation().norm();
}

double rotationErrorDeg(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd((a.inverse() * b).linear()).angle() / kDeg;
}

MultiCuePyramid pyramidOf(const PointCloud& cloud, const MultiCueParams& params) {
  return buildPyramid(cloud, SphericalProjectionParams::hdl64e(), params.pyramid_levels,
                      SurfaceContinuityParams());
}

Eigen::Isometry3d perturbed(const Eigen::Isometry3d& X, int axis, double h) {
  Eigen::Matrix<double, 6, 1> delta = Eigen::Matrix<double, 6, 1>::Zero();
  delta(axis) = h;
  Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
  const Eigen::Vector3d omega = delta.tail<3>();
  if (omega.norm() > 0.0)
    step.linear() = Eigen::AngleAxisd(omega.norm(), omega.normalized()).toRotationMatrix();
  step.translation() = delta.head<3>();
  return step * X;
}

}  // namespace

TEST(MultiCueRegistration, AnalyticJacobiansMatchNumericDifferences) {
  const MultiCueImage model = projectCloud(scanAt(40, Eigen::Isometry3d::Identity(), 1),
                                           SphericalProjectionParams::hdl64e());
  MultiCueImage measured =
      projectCloud(scanAt(40, knownMotion(), 2), SphericalProjectionParams::hdl64e());
  MultiCueImage model_with_normals = model;
  computeNormals(model_with_normals, SurfaceContinuityParams());
  computeNormals(measured, SurfaceContinuityParams());
  const CueGradients gradients = computeCueGradients(measured, SurfaceContinuityParams());
  // Near the true model -> current transform, but not at it.
  const Eigen::Isometry3d X = perturbed(perturbed(knownMotion().inverse(), 0, 0.02), 5, 0.2 * kDeg);

  int checked = 0, with_normal = 0, with_intensity = 0;
  double worst = 0.0;
  for (int j = 0; j < model.projection.size() && checked < 400; j += 37) {
    if (!model_with_normals.hasPoint(j)) continue;
    const Eigen::Vector3f p = model_with_normals.point[j];
    float u, v, r;
    const Eigen::Vector3f q = (X * p.cast<double>()).cast<float>();
    if (!measured.projection.project(q, &u, &v, &r)) continue;
    const int pixel = measured.index(int(v), int(u));
    CueResidual at;
    if (!cueResidual(p, model_with_normals.normal[j], model_with_normals.intensity[j], X, measured,
                     gradients, pixel, &at))
      continue;
    ++checked;
    with_normal += at.normal_valid;
    with_intensity += at.intensity_valid;
    const double h = 1e-6;
    for (int axis = 0; axis < 6; ++axis) {
      CueResidual plus, minus;
      ASSERT_TRUE(cueResidual(p, model_with_normals.normal[j], model_with_normals.intensity[j],
                              perturbed(X, axis, h), measured, gradients, pixel, &plus));
      ASSERT_TRUE(cueResidual(p, model_with_normals.normal[j], model_with_normals.intensity[j],
                              perturbed(X, axis, -h), measured, gradients, pixel, &minus));
      const Eigen::Matrix<double, 5, 1> numeric = (plus.error - minus.error) / (2.0 * h);
      for (int row = 0; row < 5; ++row) {
        const double diff = std::abs(numeric(row) - at.jacobian(row, axis));
        const double scale = 1.0 + std::abs(numeric(row));
        worst = std::max(worst, diff / scale);
        EXPECT_LT(diff, 1e-4 * scale)
            << "pixel " << pixel << " cue " << row << " axis " << axis << ": numeric "
            << numeric(row) << " analytic " << at.jacobian(row, axis);
      }
    }
  }
  std::cout << checked << " pixels checked (" << with_normal << " with a normal, " << with_intensity
            << " with intensity), worst relative difference " << worst << "\n";
  EXPECT_GT(checked, 200);
  EXPECT_GT(with_normal, checked / 2);
  EXPECT_EQ(with_intensity, checked);
}

TEST(MultiCueRegistration, RecoversAKnownMotionOnASimulatedUrbanScan) {
  const MultiCueParams params;
  const MultiCueRegistration registration(params);
  for (size_t k : {40u, 200u}) {
    const MultiCuePyramid model = pyramidOf(scanAt(k, Eigen::Isometry3d::Identity(), 11), params);
    const MultiCuePyramid current = pyramidOf(scanAt(k, knownMotion(), 12), params);
    const MultiCueResult r = registration.align(model, current, Eigen::Isometry3d::Identity());
    const double t_cm = 100.0 * translationError(knownMotion(), r.transform);
    const double r_deg = rotationErrorDeg(knownMotion(), r.transform);
    std::cout << "scan " << k << ": " << t_cm << " cm, " << r_deg << " deg, " << r.iterations
              << " iterations, " << r.inliers << " inliers, chi2 " << r.chi2 << ", " << r.time_ms
              << " ms\n";
    EXPECT_TRUE(r.converged) << r.message;
    EXPECT_TRUE(r.intensity_used);
    EXPECT_LT(t_cm, 2.0) << "scan " << k;
    EXPECT_LT(r_deg, 0.1) << "scan " << k;
    // The information is symmetric positive definite: usable as an odometry edge's.
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(r.information);
    EXPECT_GT(eig.eigenvalues().minCoeff(), 0.0);
    EXPECT_LT((r.information - r.information.transpose()).norm(), 1e-9 * r.information.norm());
  }
}

TEST(MultiCueRegistration, AScanWithoutIntensityIsAlignedWithTheIntensityCueOff) {
  MultiCueParams params;
  params.kernel = "cauchy";
  const MultiCueRegistration registration(params);
  PointCloud xyz_only = scanAt(40, knownMotion(), 12);
  for (auto& p : xyz_only.points) p.intensity = 0.0f;
  const MultiCuePyramid model = pyramidOf(scanAt(40, Eigen::Isometry3d::Identity(), 11), params);
  const MultiCuePyramid current = pyramidOf(xyz_only, params);
  EXPECT_FALSE(current.has_intensity());
  const MultiCueResult r = registration.align(model, current, Eigen::Isometry3d::Identity());
  EXPECT_FALSE(r.intensity_used);
  EXPECT_TRUE(r.converged) << r.message;
  EXPECT_LT(translationError(knownMotion(), r.transform), 0.03);
  EXPECT_LT(rotationErrorDeg(knownMotion(), r.transform), 0.15);
}

TEST(MultiCueRegistration, TheResultDoesNotDependOnTheThreadCount) {
  MultiCueParams one, two;
  one.num_threads = 1;
  two.num_threads = 2;
  const PointCloud model_cloud = scanAt(200, Eigen::Isometry3d::Identity(), 11);
  const PointCloud current_cloud = scanAt(200, knownMotion(), 12);
  const SphericalProjectionParams hdl = SphericalProjectionParams::hdl64e();
  const MultiCuePyramid model_1 = buildPyramid(model_cloud, hdl, 3, {}, nullptr, 1);
  const MultiCuePyramid model_2 = buildPyramid(model_cloud, hdl, 3, {}, nullptr, 2);
  const MultiCuePyramid current_1 = buildPyramid(current_cloud, hdl, 3, {}, nullptr, 1);
  const MultiCuePyramid current_2 = buildPyramid(current_cloud, hdl, 3, {}, nullptr, 2);
  const MultiCueResult a =
      MultiCueRegistration(one).align(model_1, current_1, Eigen::Isometry3d::Identity());
  const MultiCueResult b =
      MultiCueRegistration(two).align(model_2, current_2, Eigen::Isometry3d::Identity());
  EXPECT_EQ(a.transform.matrix(), b.transform.matrix());
  EXPECT_EQ(a.iterations, b.iterations);
  EXPECT_EQ(a.inliers, b.inliers);
  EXPECT_EQ(a.information, b.information);
}

TEST(MultiCueRegistration, AHalfScanSensorRecoversTheMotionToo) {
  // The front half (-90 ... +90 deg) of the same scans: the image does not wrap around.
  const SphericalProjectionParams front =
      SphericalProjectionParams::halfScan(SphericalProjectionParams::hdl64e(), -M_PI_2);
  const MultiCueParams params;
  const MultiCuePyramid model = buildPyramid(scanAt(200, Eigen::Isometry3d::Identity(), 11), front,
                                             params.pyramid_levels, SurfaceContinuityParams());
  const MultiCuePyramid current = buildPyramid(scanAt(200, knownMotion(), 12), front,
                                               params.pyramid_levels, SurfaceContinuityParams());
  ASSERT_EQ(model.levels.front().cols(), 512);
  const MultiCueResult r =
      MultiCueRegistration(params).align(model, current, Eigen::Isometry3d::Identity());
  std::cout << "front half: " << 100.0 * translationError(knownMotion(), r.transform) << " cm, "
            << rotationErrorDeg(knownMotion(), r.transform) << " deg, " << r.inliers
            << " inliers\n";
  EXPECT_TRUE(r.converged) << r.message;
  EXPECT_LT(translationError(knownMotion(), r.transform), 0.03);
  EXPECT_LT(rotationErrorDeg(knownMotion(), r.transform), 0.15);
}

TEST(MultiCueRegistration, BadParametersAndInputsFailWithAMessage) {
  MultiCueParams params;
  params.kernel = "tukey";
  EXPECT_NE(params.validate().find("kernel"), std::string::npos);
  const MultiCueResult r = MultiCueRegistration(params).align(MultiCuePyramid(), MultiCuePyramid(),
                                                              Eigen::Isometry3d::Identity());
  EXPECT_FALSE(r.converged);
  EXPECT_NE(r.message.find("kernel"), std::string::npos) << r.message;

  params = MultiCueParams();
  params.range_weight = params.intensity_weight = params.normal_weight = 0.0;
  EXPECT_NE(params.validate().find("weight"), std::string::npos);
  EXPECT_EQ(MultiCueParams().validate(), "");

  const MultiCueResult empty =
      MultiCueRegistration(MultiCueParams())
          .align(MultiCuePyramid(), MultiCuePyramid(), Eigen::Isometry3d::Identity());
  EXPECT_FALSE(empty.converged);
  EXPECT_FALSE(empty.message.empty());
}
