// Global localisation by landmark geometry (issue 24: GeoSLAM as a global localiser against a
// saved map). A map package of one pass along a forest trail; scans of the return pass (heading
// reversed, 1 m to the side, between the map's keyframes) localised with no prior, with each
// global_method; scans of another forest must get no answer.
#include <gtest/gtest.h>
#include <pcl/common/transforms.h>

#include <chrono>
#include <cmath>
#include <iostream>
#include <map>
#include <optional>
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
      kf.descriptor = computeScanContext(*kf.cloud.load(), p->scan_context);
      PointCloud in_map;
      pcl::transformPointCloud(*kf.cloud.load(), in_map, kf.pose.matrix().cast<float>());
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

/// The return pass through `scanned` at the map's trail positions + 2 m, heading reversed,
/// `offset` metres to the side.
std::vector<Query> returnPass(const sim::Scene& scanned, double offset = 1.0) {
  std::vector<Query> queries;
  for (int k = 0; k + 1 < kKeyframes; ++k) {
    const auto [xy, heading] = along(scanned.roads[0], 12.0 + kSpacing * k);
    const double yaw = heading + M_PI;
    const Eigen::Vector2d side = offset * Eigen::Vector2d(-std::sin(yaw), std::cos(yaw));
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

Tally localise(const std::string& method, const std::vector<Query>& queries,
               const std::string& landmark_map = "keyframes") {
  LocalizationParams params;
  params.global_method = method;
  params.landmark_map = landmark_map;
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
  std::cout << method << " (" << landmark_map << "): " << t.correct << " correct ("
            << t.by_hierarchy << " from the hierarchy), " << t.refused << " refused, " << t.wrong
            << " wrong of " << queries.size() << "; "
            << localizer.stats().global_ms / queries.size() << " ms per search\n";
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

double msSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

struct Proposals {
  int right = 0, wrong = 0;
};

/// Proposals alone (no registration): right when within 0.5 m and 2 degrees of the truth.
void tallyProposal(const std::optional<Pose2>& pose, const Query& q, Proposals& p) {
  if (!pose) return;
  const Pose2 err = planarPose(q.truth).inverse() * *pose;
  const bool right = err.translation().norm() <= 0.5 && std::abs(err.theta) <= 2.0 * M_PI / 180.0;
  ++(right ? p.right : p.wrong);
}

TEST(LocalizerLandmarks, MergedMapLandmarksProposeScansOffTheMappedTrail) {
  // The map's landmarks (GeoSLAM §4.3): each keyframe's trunks merged where 3 keyframes agree.
  const LocalizationParams params;
  std::vector<KeyframeLandmarks> observed;
  std::vector<Eigen::Vector2d> path;
  LandmarkLoopSource per_keyframe(params.landmark_extraction, params.landmarks);
  size_t observations = 0;
  for (const MapKeyframe& kf : forestMap()->keyframes) {
    KeyframeLandmarks& k = observed.emplace_back();
    k.pose = planarPose(kf.pose);
    k.landmarks = landmarkCenters(extractLandmarks(*kf.cloud.load(), params.landmark_extraction));
    observations += k.landmarks.size();
    path.push_back(kf.pose.translation().head<2>());
    per_keyframe.add(kf.cloud.load());
  }
  const std::vector<MapLandmark> landmarks =
      discoverLandmarks(observed, params.landmark_map_params);
  double trunk_error = 0.0;  // to the nearest simulated trunk or pole
  for (const MapLandmark& m : landmarks) {
    double nearest = 1e9;
    for (const sim::Primitive& p : forest().world.primitives)
      if (p.kind == sim::Primitive::kCylinder)
        nearest = std::min(nearest, (p.center - m.position).norm());
    trunk_error += nearest / landmarks.size();
  }
  const LandmarkMapRecognizer merged(landmarks, path, params.landmark_map_params, params.landmarks);
  std::cout << observations << " observations -> " << landmarks.size() << " map landmarks, "
            << trunk_error << " m from the nearest trunk on average; "
            << merged.tileCentres().size() << " tiles\n";
  EXPECT_LT(trunk_error, 0.4);
  EXPECT_GT(landmarks.size(), observations / 18) << "more than one keyframe's worth";
  Proposals total_merged;
  double keyframe_ms = 0.0, map_ms = 0.0;
  for (double offset : {1.0, 4.0, 7.0, 10.0, 13.0, 16.0, 20.0}) {
    Proposals by_keyframes, by_map;
    for (const Query& q : returnPass(forest(), offset)) {
      auto start = std::chrono::steady_clock::now();
      const auto proposal = per_keyframe.propose(q.cloud, per_keyframe.size());
      keyframe_ms += msSince(start);
      std::optional<Pose2> from_keyframe;
      if (proposal)
        from_keyframe =
            planarPose(forestMap()->keyframes[proposal->index].pose * proposal->relative_pose);
      tallyProposal(from_keyframe, q, by_keyframes);
      start = std::chrono::steady_clock::now();
      const auto match =
          merged.query(landmarkCenters(extractLandmarks(*q.cloud, params.landmark_extraction)));
      map_ms += msSince(start);
      tallyProposal(match ? std::optional<Pose2>(match->pose) : std::nullopt, q, by_map);
    }
    std::cout << "offset " << offset << " m: keyframes " << by_keyframes.right << " right, "
              << by_keyframes.wrong << " wrong; map " << by_map.right << " right, " << by_map.wrong
              << " wrong (of 17)\n";
    EXPECT_EQ(by_map.wrong, 0) << offset;
    EXPECT_GE(by_map.right, by_keyframes.right) << offset;
    total_merged.right += by_map.right;
  }
  EXPECT_GE(total_merged.right, 113) << "of 119";
  std::cout << "ms per proposal (extraction included): keyframes " << keyframe_ms / 119 << ", map "
            << map_ms / 119 << "\n";
}

TEST(LocalizerLandmarks, MergedMapLocalisesTheReturnPass) {
  const Tally t = localise("geometric_hierarchy", returnPass(forest(), 7.0), "global");
  EXPECT_EQ(t.wrong, 0);
  EXPECT_GE(t.correct, 14) << "of 17";
}

TEST(LocalizerLandmarks, UnknownLandmarkMapIsRefused) {
  LocalizationParams params;
  params.global_method = "geometric_hierarchy";
  params.landmark_map = "octree";
  EXPECT_THROW(Localizer(params, forestMap()), std::invalid_argument);
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
