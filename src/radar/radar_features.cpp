#include "osm_graph_slam/radar/radar_features.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <unordered_map>

namespace osm_graph_slam::radar {
namespace {

/// Bins covering [min_range, max_range] of a scan.
void binWindow(const RadarPolarScan& scan, const RadarFeatureParams& p, int& first, int& last) {
  first = std::max(0, int(std::ceil(p.min_range / scan.range_resolution - 0.5)));
  last = std::min(scan.num_bins - 1, int(std::floor(p.max_range / scan.range_resolution - 0.5)));
}

RadarFeature makeFeature(const RadarPolarScan& scan, int a, int b, const RadarFeatureParams& p) {
  RadarFeature f;
  f.range = scan.binRange(b);
  f.azimuth = scan.azimuths[a];
  f.time = scan.times[a];
  f.power = scan.row(a)[b];
  f.point = f.range * beamDirection(f.azimuth, p.azimuth_clockwise);
  return f;
}

}  // namespace

Eigen::Vector2d beamDirection(double azimuth, bool clockwise) {
  return Eigen::Vector2d(std::cos(azimuth), clockwise ? -std::sin(azimuth) : std::sin(azimuth));
}

std::vector<RadarFeature> detectKStrongest(const RadarPolarScan& scan,
                                           const RadarFeatureParams& p) {
  std::vector<RadarFeature> out;
  int first, last;
  binWindow(scan, p, first, last);
  std::vector<int> bins;
  for (int a = 0; a < scan.num_azimuths; ++a) {
    const uint8_t* row = scan.row(a);
    bins.clear();
    for (int b = first; b <= last; ++b)
      if (row[b] >= p.min_power) bins.push_back(b);
    const size_t k = std::min<size_t>(bins.size(), size_t(std::max(0, p.k_strongest)));
    std::partial_sort(bins.begin(), bins.begin() + k, bins.end(),
                      [&](int x, int y) { return row[x] > row[y] || (row[x] == row[y] && x < y); });
    for (size_t i = 0; i < k; ++i) out.push_back(makeFeature(scan, a, bins[i], p));
  }
  return out;
}

std::vector<RadarFeature> detectCfar(const RadarPolarScan& scan, const RadarFeatureParams& p) {
  std::vector<RadarFeature> out;
  int first, last;
  binWindow(scan, p, first, last);
  const int train = std::max(1, p.cfar_train_cells), guard = std::max(0, p.cfar_guard_cells);
  std::vector<double> prefix(size_t(scan.num_bins) + 1);
  for (int a = 0; a < scan.num_azimuths; ++a) {
    const uint8_t* row = scan.row(a);
    prefix[0] = 0.0;
    for (int b = 0; b < scan.num_bins; ++b) prefix[b + 1] = prefix[b] + row[b];
    auto sum = [&](int lo, int hi) {  // inclusive, clamped
      lo = std::max(lo, 0);
      hi = std::min(hi, scan.num_bins - 1);
      return hi < lo ? std::make_pair(0.0, 0)
                     : std::make_pair(prefix[hi + 1] - prefix[lo], hi - lo + 1);
    };
    for (int b = first; b <= last; ++b) {
      const int v = row[b];
      if (v < p.cfar_min_power) continue;
      // Local maximum along the beam: one detection per return, not one per bin of its lobe.
      if ((b > 0 && row[b - 1] > v) || (b + 1 < scan.num_bins && row[b + 1] >= v)) continue;
      const auto left = sum(b - guard - train, b - guard - 1);
      const auto right = sum(b + guard + 1, b + guard + train);
      const int n = left.second + right.second;
      if (n == 0) continue;
      const double mean = (left.first + right.first) / n;
      if (v > p.cfar_scale * mean) out.push_back(makeFeature(scan, a, b, p));
    }
  }
  return out;
}

std::vector<RadarFeature> detectFeatures(const RadarPolarScan& scan, const RadarFeatureParams& p) {
  return p.detector == "cfar" ? detectCfar(scan, p) : detectKStrongest(scan, p);
}

std::vector<RadarFeature> thinFeatures(std::vector<RadarFeature> features,
                                       const RadarFeatureParams& p) {
  // Strongest first (ties: nearer first) so that the first feature per cell is the one kept.
  std::stable_sort(features.begin(), features.end(),
                   [](const RadarFeature& x, const RadarFeature& y) {
                     return x.power > y.power || (x.power == y.power && x.range < y.range);
                   });
  std::vector<RadarFeature> kept;
  if (p.thinning_cell <= 0.0) {
    kept = std::move(features);
  } else {
    std::unordered_map<int64_t, int> taken;
    taken.reserve(features.size());
    for (const RadarFeature& f : features) {
      const int64_t cx = int64_t(std::floor(f.point.x() / p.thinning_cell)) + (1 << 20);
      const int64_t cy = int64_t(std::floor(f.point.y() / p.thinning_cell)) + (1 << 20);
      if (taken.emplace((cx << 21) | cy, 1).second) kept.push_back(f);
    }
  }
  if (p.max_features > 0 && int(kept.size()) > p.max_features) kept.resize(p.max_features);
  return kept;
}

cv::Mat polarToCartesian(const RadarPolarScan& scan, const RadarFeatureParams& p) {
  const int half = int(std::ceil(p.max_range / p.cart_resolution));
  const int size = 2 * half + 1;
  // Polar image with the first row repeated at the end, so that interpolation wraps around.
  cv::Mat polar(scan.num_azimuths + 1, scan.num_bins, CV_8UC1);
  for (int a = 0; a <= scan.num_azimuths; ++a)
    std::copy(scan.row(a % scan.num_azimuths), scan.row(a % scan.num_azimuths) + scan.num_bins,
              polar.ptr<uint8_t>(a));
  const double az0 = scan.azimuths.front();
  const double step = 2.0 * M_PI / scan.num_azimuths;
  cv::Mat map_x(size, size, CV_32FC1), map_y(size, size, CV_32FC1);
  for (int row = 0; row < size; ++row) {
    float* mx = map_x.ptr<float>(row);
    float* my = map_y.ptr<float>(row);
    const double x = (half - row) * p.cart_resolution;
    for (int col = 0; col < size; ++col) {
      const double y = (half - col) * p.cart_resolution;
      double theta = std::atan2(p.azimuth_clockwise ? -y : y, x);
      double idx = (theta - az0) / step;
      idx = std::fmod(idx + 2.0 * scan.num_azimuths, double(scan.num_azimuths));
      mx[col] = float(std::hypot(x, y) / scan.range_resolution - 0.5);
      my[col] = float(idx);
    }
  }
  cv::Mat cart;
  cv::remap(polar, cart, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
  return cart;
}

cv::Point2f cartesianPixel(const Eigen::Vector2d& point, const RadarFeatureParams& p) {
  const int half = int(std::ceil(p.max_range / p.cart_resolution));
  return cv::Point2f(float(half - point.y() / p.cart_resolution),
                     float(half - point.x() / p.cart_resolution));
}

RadarFeatureSet extractFeatures(const RadarPolarScan& scan, const RadarFeatureParams& p,
                                cv::Mat* cartesian) {
  RadarFeatureSet set;
  std::vector<RadarFeature> detections = detectFeatures(scan, p);
  set.detections = int(detections.size());
  std::vector<RadarFeature> kept = thinFeatures(std::move(detections), p);
  cv::Mat cart = polarToCartesian(scan, p);
  std::vector<cv::KeyPoint> keypoints;
  keypoints.reserve(kept.size());
  for (size_t i = 0; i < kept.size(); ++i) {
    cv::KeyPoint kp(cartesianPixel(kept[i].point, p), float(p.orb_patch_size), 0.0f, kept[i].power,
                    0, int(i));
    keypoints.push_back(kp);
  }
  // One pyramid level; upright descriptors (angle 0 is kept for provided key points only when
  // orientation is not recomputed, so ORB is asked for nothing but the descriptor).
  cv::Ptr<cv::ORB> orb = cv::ORB::create(int(kept.size()) + 1, 1.2f, 1, p.orb_patch_size, 0, 2,
                                         cv::ORB::HARRIS_SCORE, p.orb_patch_size);
  cv::Mat descriptors;
  if (!keypoints.empty()) orb->compute(cart, keypoints, descriptors);
  set.features.reserve(keypoints.size());
  for (const cv::KeyPoint& kp : keypoints) set.features.push_back(kept[size_t(kp.class_id)]);
  set.descriptors = descriptors;
  if (cartesian) *cartesian = cart;
  return set;
}

std::vector<FeatureMatch> matchFeatures(const RadarFeatureSet& previous,
                                        const RadarFeatureSet& current, double ratio) {
  std::vector<FeatureMatch> out;
  if (previous.descriptors.empty() || current.descriptors.empty()) return out;
  cv::BFMatcher matcher(cv::NORM_HAMMING, false);
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(current.descriptors, previous.descriptors, knn, 2);
  for (const auto& m : knn) {
    if (m.empty()) continue;
    if (m.size() == 2 && !(m[0].distance < ratio * m[1].distance)) continue;
    out.push_back({m[0].trainIdx, m[0].queryIdx, m[0].distance});
  }
  return out;
}

}  // namespace osm_graph_slam::radar
