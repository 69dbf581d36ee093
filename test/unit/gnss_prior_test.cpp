// GNSS as evidence: with gnss_prior_std > 0 every keyframe's fix is a robust position prior and the
// first keyframe is no longer fixed at its own (noisy) fix; without, the whole trajectory carries
// the first fix's error.
#include <gtest/gtest.h>

#include "osm_graph_slam/slam/graph_backend.h"

using namespace osm_graph_slam;

namespace {

/// 20 keyframes 2 m apart along x (exact odometry); the first fix is 3 m off in y, the others
/// exact, one of them an outlier 30 m off. Returns the trajectory's mean |y| error.
double meanLateralError(double gnss_prior_std) {
  GraphBackendParams params;
  params.use_osm = false;
  params.initial_yaw_known = true;
  params.initial_yaw = 0.0;
  params.gnss_prior_std = gnss_prior_std;
  GraphBackend backend(params);
  for (uint64_t i = 0; i < 20; ++i) {
    KeyframeInput kf;
    kf.id = i;
    kf.stamp = 1.0 + i;
    kf.odom_pose.translation().x() = 2.0 * i;
    kf.odom_fitness = 0.05;
    kf.gnss_position = Eigen::Vector2d(2.0 * i, i == 0 ? 3.0 : (i == 10 ? 30.0 : 0.0));
    backend.addKeyframe(kf);
  }
  backend.update(true);
  double sum = 0.0;
  const Trajectory t = backend.trajectory();
  for (const auto& p : t) sum += std::abs(p.pose.translation().y());
  return sum / t.size();
}

}  // namespace

TEST(GnssPrior, FixesAverageOutTheFirstFixError) {
  const double fixed = meanLateralError(0.0), priors = meanLateralError(2.0);
  std::printf("[gnss_prior] mean lateral error: first keyframe fixed %.3f m, GNSS priors %.3f m\n",
              fixed, priors);
  EXPECT_NEAR(fixed, 3.0, 1e-6);  // the first fix's error everywhere
  EXPECT_LT(priors, 0.4);         // 19 good fixes outweigh it; the 30 m outlier is down-weighted
}
