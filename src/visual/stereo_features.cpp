#include "osm_graph_slam/visual/stereo_features.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

namespace osm_graph_slam {
namespace {

/// ORB's descriptor needs this margin around a keypoint (its default edge threshold).
constexpr int kBorder = 31;

/// FAST corners, the strongest corners_per_cell of every grid cell: corners cluster on texture,
/// and a pose from one cluster is poorly conditioned.
std::vector<cv::KeyPoint> gridCorners(const cv::Mat& image, const StereoFeatureParams& p) {
  std::vector<cv::KeyPoint> out;
  const int cols = std::max(1, p.grid_cols), rows = std::max(1, p.grid_rows);
  const int w = image.cols - 2 * kBorder, h = image.rows - 2 * kBorder;
  if (w <= 0 || h <= 0) return out;
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const cv::Rect cell(kBorder + c * w / cols, kBorder + r * h / rows, w / cols, h / rows);
      std::vector<cv::KeyPoint> found;
      for (int threshold : {p.fast_threshold, p.fast_threshold / 2}) {
        cv::FAST(image(cell), found, std::max(1, threshold), true);
        if (!found.empty()) break;
      }
      const size_t keep = std::min(found.size(), static_cast<size_t>(p.corners_per_cell));
      std::partial_sort(
          found.begin(), found.begin() + keep, found.end(),
          [](const cv::KeyPoint& a, const cv::KeyPoint& b) { return a.response > b.response; });
      for (size_t i = 0; i < keep; ++i) {
        found[i].pt.x += cell.x;
        found[i].pt.y += cell.y;
        out.push_back(found[i]);
      }
    }
  return out;
}

/// Sum of absolute differences of the (2r+1)^2 windows at (xl, y) and (xr, y).
double blockCost(const cv::Mat& left, const cv::Mat& right, int xl, int xr, int y, int r) {
  double sum = 0.0;
  for (int dy = -r; dy <= r; ++dy) {
    const uint8_t* a = left.ptr<uint8_t>(y + dy);
    const uint8_t* b = right.ptr<uint8_t>(y + dy);
    for (int dx = -r; dx <= r; ++dx) sum += std::abs(int(a[xl + dx]) - int(b[xr + dx]));
  }
  return sum;
}

/// The right x of a matched corner, refined to a sub-pixel by a parabola through the block costs
/// at -1, 0, +1 px (FAST corners sit on whole pixels: +-0.5 px is +-5 % of depth at 10 px).
double refineRightX(const cv::Mat& left, const cv::Mat& right, const cv::Point2f& pl, float xr,
                    int r) {
  const int y = cvRound(pl.y), xl = cvRound(pl.x), x0 = cvRound(xr);
  if (y - r < 0 || y + r >= left.rows || xl - r < 0 || xl + r >= left.cols || x0 - r - 2 < 0 ||
      x0 + r + 2 >= right.cols)
    return xr;
  int best = 0;
  double cost[5];
  for (int k = -2; k <= 2; ++k) {
    cost[k + 2] = blockCost(left, right, xl, x0 + k, y, r);
    if (cost[k + 2] < cost[best + 2]) best = k;
  }
  if (best == -2 || best == 2) return x0 + best;
  const double c_minus = cost[best + 1], c0 = cost[best + 2], c_plus = cost[best + 3];
  const double denominator = c_minus - 2.0 * c0 + c_plus;
  const double offset = denominator > 1e-9 ? 0.5 * (c_minus - c_plus) / denominator : 0.0;
  return x0 + best + std::clamp(offset, -0.5, 0.5);
}

}  // namespace

size_t StereoFrame::stereoMatches() const {
  return static_cast<size_t>(std::count(has_depth.begin(), has_depth.end(), true));
}

StereoFrame extractStereoFrame(const cv::Mat& left, const cv::Mat& right,
                               const StereoCamera& camera, const StereoFeatureParams& p) {
  StereoFrame f;
  const cv::Ptr<cv::ORB> orb = cv::ORB::create();
  f.keypoints = gridCorners(left, p);
  orb->compute(left, f.keypoints, f.descriptors);
  std::vector<cv::KeyPoint> right_keypoints = gridCorners(right, p);
  cv::Mat right_descriptors;
  orb->compute(right, right_keypoints, right_descriptors);

  // The right corners by row, so a left corner looks at its own rows only.
  std::vector<std::vector<int>> by_row(static_cast<size_t>(right.rows));
  for (size_t i = 0; i < right_keypoints.size(); ++i) {
    const float y = right_keypoints[i].pt.y;
    const int lo = std::max(0, static_cast<int>(std::floor(y - p.row_tolerance)));
    const int hi = std::min(right.rows - 1, static_cast<int>(std::ceil(y + p.row_tolerance)));
    for (int row = lo; row <= hi; ++row) by_row[static_cast<size_t>(row)].push_back(int(i));
  }
  const size_t n = f.keypoints.size();
  f.has_depth.assign(n, false);
  f.disparity.assign(n, 0.0f);
  f.points.assign(n, Eigen::Vector3d::Zero());
  for (size_t i = 0; i < n; ++i) {
    const cv::Point2f& pl = f.keypoints[i].pt;
    const int row = cvRound(pl.y);
    if (row < 0 || row >= right.rows) continue;
    int best = -1, best_distance = std::numeric_limits<int>::max(), second = best_distance;
    for (int j : by_row[static_cast<size_t>(row)]) {
      const cv::Point2f& pr = right_keypoints[static_cast<size_t>(j)].pt;
      const double d = pl.x - pr.x;
      if (std::abs(pr.y - pl.y) > p.row_tolerance || d < p.min_disparity || d > p.max_disparity)
        continue;
      const int distance =
          cv::norm(f.descriptors.row(int(i)), right_descriptors.row(j), cv::NORM_HAMMING);
      if (distance < best_distance) {
        second = best_distance;
        best_distance = distance;
        best = j;
      } else if (distance < second) {
        second = distance;
      }
    }
    if (best < 0 || best_distance > p.max_descriptor_distance ||
        best_distance > p.match_ratio * second)
      continue;
    const double xr =
        p.block_radius > 0
            ? refineRightX(left, right, pl, right_keypoints[size_t(best)].pt.x, p.block_radius)
            : right_keypoints[size_t(best)].pt.x;
    const double disparity = pl.x - xr;
    if (disparity < p.min_disparity) continue;
    const Eigen::Vector3d point = camera.triangulate(pl.x, pl.y, disparity);
    if (point.z() > p.max_depth) continue;
    f.has_depth[i] = true;
    f.disparity[i] = static_cast<float>(disparity);
    f.points[i] = point;
  }
  return f;
}

}  // namespace osm_graph_slam
