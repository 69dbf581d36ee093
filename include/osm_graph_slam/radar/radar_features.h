#pragma once
// Radar front-end, feature side (RadART-SLAM seed sec. 7.1.3): detections on the polar power
// returns (k-strongest per azimuth or cell-averaging CFAR), thinned to the strongest per
// Cartesian cell, described by ORB on the Cartesian (bird's-eye) image, matched by brute force
// with the nearest-neighbour ratio test.
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "osm_graph_slam/radar/radar_scan.h"

namespace osm_graph_slam::radar {

struct RadarFeatureParams {
  std::string detector = "kstrongest";  ///< "kstrongest" or "cfar"
  int k_strongest = 20;                 ///< returns kept per azimuth (k-strongest)
  int min_power = 60;                   ///< [8-bit power] below: noise floor (k-strongest)
  int cfar_train_cells = 24;            ///< training bins each side (CFAR)
  int cfar_guard_cells = 4;             ///< guard bins each side (CFAR)
  double cfar_scale = 2.0;              ///< detection if power > scale * local mean (CFAR)
  int cfar_min_power = 40;              ///< and above this absolute floor (CFAR)
  double min_range = 3.0;               ///< [m] the vehicle's own returns and the near-field ring
  double max_range = 100.0;             ///< [m] also bounds the Cartesian image
  double thinning_cell = 0.5;           ///< [m] keep the strongest detection per cell
  int max_features = 1500;              ///< strongest after thinning
  double cart_resolution = 0.25;        ///< [m/pixel] of the Cartesian image for ORB
  int orb_patch_size = 21;              ///< [pixel] ORB patch (21 px = 5.25 m)
  bool azimuth_clockwise = true;        ///< Navtech: azimuth grows clockwise seen from above
};

/// One detection: where and when it was seen. x forward, y left (sensor frame at its time).
struct RadarFeature {
  double range = 0.0;    ///< [m] as measured (no Doppler correction)
  double azimuth = 0.0;  ///< [rad] as recorded
  double time = 0.0;     ///< [s] the row's time
  float power = 0.0f;
  Eigen::Vector2d point = Eigen::Vector2d::Zero();  ///< [m] from range and azimuth
};

struct RadarFeatureSet {
  std::vector<RadarFeature> features;  ///< only those with a descriptor
  cv::Mat descriptors;                 ///< one ORB row per feature
  int detections = 0;                  ///< before thinning
};

/// Unit vector of a recorded azimuth in the sensor frame (x forward, y left).
Eigen::Vector2d beamDirection(double azimuth, bool clockwise);

/// Per azimuth, the k strongest bins above min_power within [min_range, max_range].
std::vector<RadarFeature> detectKStrongest(const RadarPolarScan& scan, const RadarFeatureParams& p);
/// Cell-averaging CFAR along each azimuth (training/guard cells each side), local maxima only.
std::vector<RadarFeature> detectCfar(const RadarPolarScan& scan, const RadarFeatureParams& p);
/// The configured detector.
std::vector<RadarFeature> detectFeatures(const RadarPolarScan& scan, const RadarFeatureParams& p);

/// Keeps the strongest detection per thinning_cell, then the max_features strongest.
std::vector<RadarFeature> thinFeatures(std::vector<RadarFeature> features,
                                       const RadarFeatureParams& p);

/// Bird's-eye image (8-bit): x forward is up, y left is left, sensor at the centre,
/// resolution cart_resolution, half-width max_range.
cv::Mat polarToCartesian(const RadarPolarScan& scan, const RadarFeatureParams& p);
/// Pixel (column, row) of a sensor-frame point in that image.
cv::Point2f cartesianPixel(const Eigen::Vector2d& point, const RadarFeatureParams& p);

/// Detect, thin, Cartesian image, ORB descriptors (upright: consecutive scans rotate by a few
/// degrees at most). Features too close to the image border for a descriptor are dropped.
RadarFeatureSet extractFeatures(const RadarPolarScan& scan, const RadarFeatureParams& p,
                                cv::Mat* cartesian = nullptr);

struct FeatureMatch {
  int previous = -1;  ///< index into the earlier set
  int current = -1;   ///< index into the later set
  float distance = 0.0f;
};

/// Brute-force Hamming matching, nearest-neighbour ratio test (d1 < ratio * d2).
std::vector<FeatureMatch> matchFeatures(const RadarFeatureSet& previous,
                                        const RadarFeatureSet& current, double ratio);

}  // namespace osm_graph_slam::radar
