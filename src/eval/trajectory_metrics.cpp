#include "osm_graph_slam/eval/trajectory_metrics.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>

namespace osm_graph_slam {
namespace {

Eigen::Isometry3d toPlanar(const Eigen::Isometry3d& pose) {
  const Eigen::Matrix3d r = pose.rotation();
  const double yaw = std::atan2(r(1, 0), r(0, 0));
  Eigen::Isometry3d planar = Eigen::Isometry3d::Identity();
  planar.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  planar.translation() = Eigen::Vector3d(pose.translation().x(), pose.translation().y(), 0.0);
  return planar;
}

double rotationAngle(const Eigen::Isometry3d& delta) {
  return Eigen::AngleAxisd(delta.rotation()).angle();
}

/// KITTI devkit relative errors, over segments measured along the ground truth.
void kittiRelativeErrors(const std::vector<Eigen::Isometry3d>& est,
                         const std::vector<Eigen::Isometry3d>& gt,
                         const TrajectoryEvalOptions& options, TrajectoryErrors& out) {
  std::vector<double> dist(gt.size(), 0.0);
  for (size_t i = 1; i < gt.size(); ++i)
    dist[i] = dist[i - 1] + (gt[i].translation() - gt[i - 1].translation()).norm();
  double t_sum = 0.0, r_sum = 0.0;
  size_t n = 0;
  const size_t step = static_cast<size_t>(std::max(1, options.kitti_step));
  for (size_t first = 0; first < gt.size(); first += step) {
    for (double len : options.kitti_lengths) {
      const auto it = std::lower_bound(dist.begin() + first, dist.end(), dist[first] + len);
      if (it == dist.end()) continue;
      const size_t last = static_cast<size_t>(it - dist.begin());
      const Eigen::Isometry3d gt_rel = gt[first].inverse() * gt[last];
      const Eigen::Isometry3d est_rel = est[first].inverse() * est[last];
      const Eigen::Isometry3d delta = gt_rel.inverse() * est_rel;
      t_sum += delta.translation().norm() / len;
      r_sum += rotationAngle(delta) / len;
      ++n;
    }
  }
  out.kitti_segments = n;
  if (n > 0) {
    out.kitti_trans_percent = 100.0 * t_sum / static_cast<double>(n);
    out.kitti_rot_deg_per_100m = 100.0 * (r_sum / static_cast<double>(n)) * 180.0 / M_PI;
  }
}

}  // namespace

ErrorStats computeErrorStats(std::vector<double> values) {
  ErrorStats s;
  s.count = values.size();
  if (values.empty()) return s;
  double sum = 0.0, sq = 0.0;
  for (double v : values) {
    sum += v;
    sq += v * v;
    s.max = std::max(s.max, v);
  }
  const double n = static_cast<double>(values.size());
  s.mean = sum / n;
  s.rmse = std::sqrt(sq / n);
  s.std = std::sqrt(std::max(0.0, sq / n - s.mean * s.mean));
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + static_cast<long>(mid), values.end());
  s.median = values[mid];
  if (values.size() % 2 == 0) {
    const double lower = *std::max_element(values.begin(), values.begin() + static_cast<long>(mid));
    s.median = 0.5 * (s.median + lower);
  }
  return s;
}

std::vector<std::pair<size_t, size_t>> associateByStamp(const Trajectory& estimate,
                                                        const Trajectory& ground_truth,
                                                        double max_dt) {
  std::vector<std::pair<size_t, size_t>> pairs;
  size_t j = 0;
  for (size_t i = 0; i < estimate.size(); ++i) {
    const double t = estimate[i].stamp;
    while (j + 1 < ground_truth.size() &&
           std::abs(ground_truth[j + 1].stamp - t) <= std::abs(ground_truth[j].stamp - t)) {
      ++j;
    }
    if (j < ground_truth.size() && std::abs(ground_truth[j].stamp - t) <= max_dt &&
        (pairs.empty() || pairs.back().second != j)) {
      pairs.emplace_back(i, j);
    }
  }
  return pairs;
}

Eigen::Isometry3d alignUmeyama(const std::vector<Eigen::Vector3d>& a,
                               const std::vector<Eigen::Vector3d>& b) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  if (a.size() != b.size() || a.empty()) return T;
  Eigen::Vector3d ma = Eigen::Vector3d::Zero(), mb = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < a.size(); ++i) {
    ma += a[i];
    mb += b[i];
  }
  ma /= static_cast<double>(a.size());
  mb /= static_cast<double>(b.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < a.size(); ++i) cov += (b[i] - mb) * (a[i] - ma).transpose();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
  if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) S(2, 2) = -1.0;
  T.linear() = svd.matrixU() * S * svd.matrixV().transpose();
  T.translation() = mb - T.linear() * ma;
  return T;
}

TrajectoryErrors evaluateTrajectory(const Trajectory& estimate, const Trajectory& ground_truth,
                                    const TrajectoryEvalOptions& options) {
  TrajectoryErrors out;
  const auto pairs = associateByStamp(estimate, ground_truth, options.max_time_difference);
  out.associated = pairs.size();
  if (pairs.empty()) return out;

  std::vector<Eigen::Isometry3d> est, gt;
  for (const auto& [i, j] : pairs) {
    est.push_back(options.planar ? toPlanar(estimate[i].pose) : estimate[i].pose);
    gt.push_back(options.planar ? toPlanar(ground_truth[j].pose) : ground_truth[j].pose);
  }
  Eigen::Isometry3d align = Eigen::Isometry3d::Identity();
  if (options.alignment == TrajectoryAlignment::kFirstPose) {
    align = gt.front() * est.front().inverse();
  } else if (options.alignment == TrajectoryAlignment::kUmeyamaSE3) {
    std::vector<Eigen::Vector3d> a, b;
    for (size_t k = 0; k < est.size(); ++k) {
      a.push_back(est[k].translation());
      b.push_back(gt[k].translation());
    }
    align = alignUmeyama(a, b);
  }
  for (auto& pose : est) pose = align * pose;

  std::vector<double> ate, rpe_t, rpe_r, height, tilt;
  const double z0 = est.front().translation().z() - gt.front().translation().z();
  for (size_t k = 0; k < est.size(); ++k) {
    ate.push_back((gt[k].inverse() * est[k]).translation().norm());  // eq. 4.6-4.7
    height.push_back(std::abs(est[k].translation().z() - gt[k].translation().z() - z0));
    const Eigen::Vector3d up_est = est[k].linear().row(2), up_gt = gt[k].linear().row(2);
    tilt.push_back(std::acos(std::clamp(up_est.dot(up_gt), -1.0, 1.0)));
    if (k == 0) continue;
    const Eigen::Isometry3d est_rel = est[k - 1].inverse() * est[k];  // eq. 4.2
    const Eigen::Isometry3d gt_rel = gt[k - 1].inverse() * gt[k];
    const Eigen::Isometry3d delta = gt_rel.inverse() * est_rel;  // eq. 4.3
    rpe_t.push_back(delta.translation().norm());                 // eq. 4.4
    rpe_r.push_back(rotationAngle(delta));                       // eq. 4.5
  }
  double travelled = 0.0;
  for (size_t k = 0; k < est.size(); ++k) {
    if (k > 0) travelled += (gt[k].translation() - gt[k - 1].translation()).norm();
    out.estimate_positions.push_back(est[k].translation());
    out.ground_truth_positions.push_back(gt[k].translation());
    out.distance_along_path.push_back(travelled);
  }
  out.ate_per_pose = ate;
  out.ate = computeErrorStats(ate);
  out.rpe_trans = computeErrorStats(rpe_t);
  out.rpe_rot = computeErrorStats(rpe_r);
  out.height_drift = computeErrorStats(height);
  out.tilt = computeErrorStats(tilt);
  kittiRelativeErrors(est, gt, options, out);
  return out;
}

}  // namespace osm_graph_slam
