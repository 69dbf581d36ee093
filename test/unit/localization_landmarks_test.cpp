// Global localisation by landmark geometry (issue 24: GeoSLAM as a global localiser against a
// saved map). A map package of one pass along a forest trail; scans of the return pass (heading
// reversed, 1 m to the side, between the map's keyframes) localised with no prior, with each
// global_method; scans of another forest must get no answer.
#include <gtest/gtest.h>
#include <pcl/common/transforms.h>

#include <cmath>
#include <iostream>
#include <map>
#include <stdexcept>

#include "forest_trail.h"
#include "osm_graph_slam/localization/localizer.h"
#include "osm_graph_slam/loop/scan_context.h"

using namespace osm_graph_slam;
using test::along;
using test::keyframeCloud;
using test::makeForest;
using test::sensorPose;

namespace {

constexpr double kSpacing = 4.0;  ///< [m] between map keyframes
constexpr int kKeyframes = 18;    ///< 68 m of trail

const sim::Scene& forest() {
  static const sim::Scene scene = makeForest(3);
  return scene;
}

/// The map: keyframes every 4 m along trail 0, clouds in the sensor frame (the sensor is the
/// base frame here, as in the Scan Context tests).
std::shared_ptr<const MapPackage> forestMap() {
  static const std::shared_ptr<const MapPackage> package = [] {
    auto p = std::make_shared<MapPackage>();
    auto map = std::make_shared<PointCloud>();
    for (int k = 0; k < kKeyframes; ++k) {
      const auto [xy, heading] = along(forest().roads[0], 10.0 + kSpacing * k);
      MapKeyframe kf;
      kf.id = static_cast<uint64_t>(k);
      kf.stamp = k;
      kf.pose = sensorPose(forest(), xy, heading);
      kf.cloud = keyframeCloud(forest(), kf.pose, 100 + k);
      kf.descriptor = computeScanContext(*kf.cloud, p->scan_context);
      PointCloud in_map;
      pcl::transformPointCloud(*kf.cloud, in_map, kf.pose.matrix().cast<float>());
      *map += in_map;
      p->keyframes.push_back(kf);
    }
    p->map_cloud = map;
    return p;
  }();
  return package;
}

struct Query {
  Eigen::Isometry3d truth;
  PointCloudConstPtr cloud;
};

/// The return pass through `scanned` at the map's trail positions + 2 m, heading reversed, 1 m
/// to the side.
std::vector<Query> returnPass(const sim::Scene& scanned) {
  std::vector<Query> queries;
  for (int k = 0; k + 1 < kKeyframes; ++k) {
    const auto [xy, heading] = along(scanned.roads[0], 12.0 + kSpacing * k);
    const double yaw = heading + M_PI;
    const Eigen::Vector2d side(-std::sin(yaw), std::cos(yaw));
    Query q;
    q.truth = sensorPose(scanned, xy + side, yaw);
    q.cloud = keyframeCloud(scanned, q.truth, 500 + k);
    queries.push_back(q);
  }
  return queries;
}

struct Tally {
  int correct = 0, wrong = 0, refused = 0, by_hierarchy = 0;
};

Tally localise(const std::string& method, const std::vector<Query>& queries) {
  LocalizationParams params;
  params.global_method = method;
  params.registration.num_threads = 2;
  Localizer localizer(params, forestMap());
  Tally t;
  for (size_t i = 0; i < queries.size(); ++i) {
    const GlobalLocalizationResult g = localizer.globalLocalize(queries[i].cloud);
    if (!g.success) {
      ++t.refused;
      continue;
    }
    const Eigen::Isometry3d err = queries[i].truth.inverse() * g.pose;
    const double yaw_err = std::abs(std::atan2(err.linear()(1, 0), err.linear()(0, 0)));
    if (err.translation().head<2>().norm() <= 0.5 && yaw_err <= 2.0 * M_PI / 180.0) {
      ++t.correct;
      t.by_hierarchy += g.source == "geometric_hierarchy";
    } else {
      ++t.wrong;
      std::cout << "  " << method << ": wrong answer for query " << i << " (" << g.source
                << "): " << err.translation().head<2>().norm() << " m\n";
    }
  }
  std::cout << method << ": " << t.correct << " correct (" << t.by_hierarchy
            << " from the hierarchy), " << t.refused << " refused, " << t.wrong << " wrong of "
            << queries.size() << "; " << localizer.stats().global_ms / queries.size()
            << " ms per search\n";
  return t;
}

}  // namespace

TEST(LocalizerLandmarks, ReversedHeadingInAForestIsFoundByTheHierarchy) {
  const std::vector<Query> queries = returnPass(forest());
  const Tally sc = localise("scan_context", queries);
  const Tally gh = localise("geometric_hierarchy", queries);
  const Tally combined = localise("combined", queries);
  const int n = static_cast<int>(queries.size());
  EXPECT_EQ(gh.wrong, 0);
  EXPECT_EQ(combined.wrong, 0);
  EXPECT_GE(gh.correct, n * 3 / 4) << "most of the return pass is found from landmarks alone";
  EXPECT_EQ(gh.by_hierarchy, gh.correct);
  EXPECT_GE(combined.correct, std::max(sc.correct, gh.correct) - 1)
      << "combined tries the hierarchy's place and Scan Context's";
}

TEST(LocalizerLandmarks, AnotherForestGetsNoAnswer) {
  const sim::Scene other = makeForest(8);
  const std::vector<Query> queries = returnPass(other);
  for (const char* method : {"scan_context", "geometric_hierarchy", "combined"}) {
    const Tally t = localise(method, queries);
    EXPECT_EQ(t.correct + t.wrong, 0) << method << ": a place of another forest was answered";
  }
}

TEST(LocalizerLandmarks, UnknownMethodIsRefused) {
  LocalizationParams params;
  params.global_method = "sift";
  EXPECT_THROW(Localizer(params, forestMap()), std::invalid_argument);
}
