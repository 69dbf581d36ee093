// The multi-cue images: spherical projection of a known scene (the pixel of a known point, the
// depth buffer keeps the nearest), normals of a plane, the projection presets and their
// validation, the intensity cue turned off for a cloud without intensity, and the pyramid.
#include <gtest/gtest.h>

#include <cmath>

#include "osm_graph_slam/multi_cue/multi_cue_image.h"

using namespace osm_graph_slam;

namespace {

constexpr double kDeg = M_PI / 180.0;

PointT pointAt(double x, double y, double z, float intensity = 0.5f) {
  PointT p;
  p.x = x;
  p.y = y;
  p.z = z;
  p.intensity = intensity;
  return p;
}

/// A return at the given azimuth and elevation [rad] and range.
PointT pointInDirection(double azimuth, double elevation, double range, float intensity = 0.5f) {
  return pointAt(range * std::cos(elevation) * std::cos(azimuth),
                 range * std::cos(elevation) * std::sin(azimuth), range * std::sin(elevation),
                 intensity);
}

/// A small image: 8 rows over [-8, 8] deg, 36 columns of 10 deg each, starting at -180 deg.
SphericalProjectionParams smallImage() {
  SphericalProjectionParams p;
  p.rows = 8;
  p.cols = 36;
  p.elevation_min = -8.0 * kDeg;
  p.elevation_max = 8.0 * kDeg;
  p.min_range = 1.0;
  p.max_range = 100.0;
  return p;
}

/// The ground plane z = -height as a dense grid of points around the sensor.
PointCloud groundPlane(double height, double half_size, double step) {
  PointCloud cloud;
  for (double x = -half_size; x <= half_size; x += step)
    for (double y = -half_size; y <= half_size; y += step) cloud.push_back(pointAt(x, y, -height));
  return cloud;
}

}  // namespace

TEST(MultiCueProjection, AKnownPointLandsInItsPixel) {
  const SphericalProjectionParams params = smallImage();
  // Azimuth 45 deg: (45 + 180) / 10 = column 22.5; elevation 3 deg: (8 - 3) / 2 = row 2.5.
  PointCloud cloud;
  cloud.push_back(pointInDirection(45.0 * kDeg, 3.0 * kDeg, 10.0, 0.7f));
  const MultiCueImage image = projectCloud(cloud, params);
  const int i = image.index(2, 22);
  ASSERT_TRUE(image.hasPoint(i));
  EXPECT_EQ(image.pointCount(), 1u);
  EXPECT_NEAR(image.range[i], 10.0, 1e-4);
  EXPECT_NEAR(image.intensity[i], 0.7, 1e-6);
  EXPECT_NEAR(image.subpixel[i].x(), 22.5, 1e-3);
  EXPECT_NEAR(image.subpixel[i].y(), 2.5, 1e-3);
  EXPECT_NEAR((image.point[i] - cloud[0].getVector3fMap()).norm(), 0.0, 1e-6);
  EXPECT_TRUE(image.has_intensity);
}

TEST(MultiCueProjection, TheDepthBufferKeepsTheNearestReturn) {
  const SphericalProjectionParams params = smallImage();
  PointCloud cloud;
  // Three returns into one pixel, the nearest in the middle of the cloud's order.
  cloud.push_back(pointInDirection(-95.0 * kDeg, -1.0 * kDeg, 30.0, 0.1f));
  cloud.push_back(pointInDirection(-98.0 * kDeg, -1.5 * kDeg, 12.0, 0.9f));
  cloud.push_back(pointInDirection(-92.0 * kDeg, -0.5 * kDeg, 20.0, 0.3f));
  const MultiCueImage image = projectCloud(cloud, params);
  EXPECT_EQ(image.pointCount(), 1u);
  const int i = image.index(4, 8);  // rows (8 + 0.5 ... 1.5) / 2; columns (180 - 98 ... 92) / 10
  ASSERT_TRUE(image.hasPoint(i));
  EXPECT_NEAR(image.range[i], 12.0, 1e-4);
  EXPECT_NEAR(image.intensity[i], 0.9, 1e-6);
}

TEST(MultiCueProjection, ReturnsOutsideTheFieldOfViewOrRangeAreDropped) {
  const SphericalProjectionParams params = smallImage();
  PointCloud cloud;
  cloud.push_back(pointInDirection(0.0, 20.0 * kDeg, 10.0));   // above the image
  cloud.push_back(pointInDirection(0.0, -20.0 * kDeg, 10.0));  // below
  cloud.push_back(pointInDirection(0.0, 0.0, 0.5));            // too close
  cloud.push_back(pointInDirection(0.0, 0.0, 150.0));          // too far
  cloud.push_back(pointAt(NAN, 1.0, 0.0));
  EXPECT_EQ(projectCloud(cloud, params).pointCount(), 0u);

  // A half sensor looking forward (-90 ... +90 deg) does not see behind.
  const SphericalProjectionParams front = SphericalProjectionParams::halfScan(params, -M_PI_2);
  EXPECT_EQ(front.cols, 18);
  PointCloud two;
  two.push_back(pointInDirection(15.0 * kDeg, 0.0, 10.0));
  two.push_back(pointInDirection(170.0 * kDeg, 0.0, 10.0));
  const MultiCueImage half = projectCloud(two, front);
  EXPECT_EQ(half.pointCount(), 1u);
  EXPECT_TRUE(half.hasPoint(half.index(4, 10)));  // (15 + 90) / 10
}

TEST(MultiCueProjection, TheFastArcTangentIsWithinItsBound) {
  double worst = 0.0;
  for (double a = -M_PI; a <= M_PI; a += 1e-4) {
    for (double r : {0.01, 1.0, 80.0}) {
      const float y = r * std::sin(a), x = r * std::cos(a);
      worst = std::max(
          worst, std::abs(std::remainder(
                     SphericalProjectionParams::fastAtan2(y, x) - std::atan2(y, x), 2.0 * M_PI)));
    }
  }
  EXPECT_LT(worst, 1.2e-5);
  EXPECT_EQ(SphericalProjectionParams::fastAtan2(0.0f, 0.0f), 0.0f);
}

TEST(MultiCueProjection, PresetsAreValidAndBadParametersAreExplained) {
  const auto hdl = SphericalProjectionParams::hdl64e();
  const auto os1 = SphericalProjectionParams::os1_64();
  EXPECT_EQ(hdl.validate(), "");
  EXPECT_EQ(os1.validate(), "");
  EXPECT_EQ(hdl.rows, 64);
  EXPECT_EQ(os1.rows, 64);
  EXPECT_EQ(os1.cols, 1024);
  const auto half = SphericalProjectionParams::halfScan(hdl, -M_PI_2);
  EXPECT_EQ(half.validate(), "");
  EXPECT_NEAR(half.azimuth_span, M_PI, 1e-12);
  EXPECT_EQ(half.cols, hdl.cols / 2);
  EXPECT_FALSE(half.fullCircle());
  // The HDL-64E's outer beams (+2.0 and -24.8 deg) fall inside the image.
  float u, v, r;
  EXPECT_TRUE(hdl.project(pointInDirection(0.0, 2.0 * kDeg, 10.0).getVector3fMap(), &u, &v, &r));
  EXPECT_TRUE(hdl.project(pointInDirection(0.0, -24.8 * kDeg, 10.0).getVector3fMap(), &u, &v, &r));

  auto bad = hdl;
  bad.rows = 0;
  EXPECT_NE(bad.validate().find("row"), std::string::npos) << bad.validate();
  bad = hdl;
  bad.elevation_max = NAN;
  EXPECT_NE(bad.validate().find("finite"), std::string::npos) << bad.validate();
  bad = hdl;
  bad.azimuth_span = 0.0;
  EXPECT_NE(bad.validate().find("horizontal field of view"), std::string::npos) << bad.validate();
  bad = hdl;
  bad.elevation_min = bad.elevation_max;
  EXPECT_NE(bad.validate().find("vertical field of view"), std::string::npos) << bad.validate();
  bad = hdl;
  bad.min_range = 200.0;
  EXPECT_NE(bad.validate().find("range"), std::string::npos) << bad.validate();
}

TEST(MultiCueProjection, NormalsOfAPlaneAreThePlaneNormalFacingTheSensor) {
  auto params = SphericalProjectionParams::hdl64e();
  params.cols = 512;
  MultiCueImage image = projectCloud(groundPlane(1.73, 30.0, 0.05), params);
  computeNormals(image, SurfaceContinuityParams());
  ASSERT_GT(image.normalCount(), 2000u);
  double worst_deg = 0.0;
  for (int i = 0; i < params.size(); ++i) {
    if (!image.hasNormal(i)) continue;
    const double angle = std::acos(std::min(1.0f, image.normal[i].dot(Eigen::Vector3f::UnitZ())));
    worst_deg = std::max(worst_deg, angle / kDeg);
  }
  // A plane sampled 5 cm apart: the nearest return per pixel is off the pixel centre by up to
  // 2.5 cm, which tilts a short neighbour vector a little.
  EXPECT_LT(worst_deg, 10.0);

  // A vertical wall x = 8 m in front: normals point back at the sensor (-x).
  PointCloud wall;
  for (double y = -6.0; y <= 6.0; y += 0.03)
    for (double z = -2.0; z <= 1.0; z += 0.03) wall.push_back(pointAt(8.0, y, z));
  MultiCueImage wall_image = projectCloud(wall, params);
  computeNormals(wall_image, SurfaceContinuityParams());
  ASSERT_GT(wall_image.normalCount(), 500u);
  for (int i = 0; i < params.size(); ++i) {
    if (!wall_image.hasNormal(i)) continue;
    EXPECT_GT(-wall_image.normal[i].x(), std::cos(10.0 * kDeg));
  }
}

TEST(MultiCueProjection, NoNormalAcrossADepthDiscontinuity) {
  const SphericalProjectionParams params = smallImage();
  PointCloud cloud;
  // A wall 10 m ahead over every pixel, except one column 40 m away (a gap in the wall).
  for (int row = 0; row < params.rows; ++row) {
    for (int col = 0; col < params.cols; ++col) {
      const double azimuth = (col + 0.5) / params.colsPerRadian() + params.azimuth_start;
      const double elevation = params.elevation_max - (row + 0.5) / params.rowsPerRadian();
      const double range = col == 20 ? 40.0 : 10.0;
      cloud.push_back(pointInDirection(azimuth, elevation, range));
    }
  }
  MultiCueImage image = projectCloud(cloud, params);
  computeNormals(image, SurfaceContinuityParams());
  for (int row = 0; row < params.rows; ++row) {
    EXPECT_FALSE(image.hasNormal(image.index(row, 20))) << "row " << row;
    // Its neighbours still find a continuous neighbour on their other side.
    if (row > 0 && row + 1 < params.rows) {
      EXPECT_TRUE(image.hasNormal(image.index(row, 19)));
      EXPECT_TRUE(image.hasNormal(image.index(row, 21)));
    }
  }
}

TEST(MultiCueProjection, ACloudWithoutIntensityTurnsTheIntensityCueOff) {
  PointCloud xyz_only = groundPlane(1.73, 10.0, 0.2);
  for (auto& p : xyz_only.points) p.intensity = 0.0f;
  EXPECT_FALSE(cloudHasIntensity(xyz_only));
  const MultiCueImage image = projectCloud(xyz_only, SphericalProjectionParams::hdl64e());
  EXPECT_FALSE(image.has_intensity);
  EXPECT_GT(image.pointCount(), 0u);

  PointCloud non_finite = xyz_only;
  for (auto& p : non_finite.points) p.intensity = NAN;
  EXPECT_FALSE(cloudHasIntensity(non_finite));
  EXPECT_FALSE(cloudHasIntensity(PointCloud()));

  PointCloud one = xyz_only;
  one.points[3].intensity = 0.2f;
  EXPECT_TRUE(cloudHasIntensity(one));
  const MultiCuePyramid pyramid =
      buildPyramid(xyz_only, SphericalProjectionParams::hdl64e(), 3, SurfaceContinuityParams());
  EXPECT_FALSE(pyramid.has_intensity());
  for (const auto& level : pyramid.levels) EXPECT_FALSE(level.has_intensity);
}

TEST(MultiCueProjection, ThePyramidHalvesTheImageAndKeepsRealReturns) {
  auto params = SphericalProjectionParams::hdl64e();
  PointCloud cloud = groundPlane(1.73, 30.0, 0.1);
  // A pole 5 m ahead in front of the ground: coarse pixels at its edge hold the pole's return or
  // the ground's, never a range in between.
  for (double z = -1.7; z < 1.0; z += 0.02)
    for (double a = 0.0; a < 2 * M_PI; a += 0.1)
      cloud.push_back(pointAt(5.0 + 0.1 * std::cos(a), 0.1 * std::sin(a), z));
  MultiCueBuildTimes times;
  const MultiCuePyramid pyramid = buildPyramid(cloud, params, 3, SurfaceContinuityParams(), &times);
  ASSERT_EQ(pyramid.levels.size(), 3u);
  EXPECT_EQ(pyramid.levels[1].rows(), 32);
  EXPECT_EQ(pyramid.levels[1].cols(), 512);
  EXPECT_EQ(pyramid.levels[2].rows(), 16);
  EXPECT_EQ(pyramid.levels[2].cols(), 256);
  EXPECT_GT(times.projection_ms, 0.0);
  for (const auto& level : pyramid.levels) {
    EXPECT_GT(level.pointCount(), 0u);
    for (int i = 0; i < level.projection.size(); ++i) {
      if (!level.hasPoint(i)) continue;
      const Eigen::Vector3f& p = level.point[i];
      const bool on_pole = std::abs(std::hypot(p.x() - 5.0f, p.y()) - 0.1f) < 1e-3f;
      const bool on_ground = std::abs(p.z() + 1.73f) < 1e-4f;
      EXPECT_TRUE(on_pole || on_ground) << p.transpose();
    }
  }
}
