#pragma once
// IMU samples by time, for the tracker's imu guess: the orientation at a scan's stamp, slerped
// between the two samples around it. Samples with an orientation (an INS, KITTI's OXTS, MulRan's
// Xsens) give it directly; samples with angular velocity only (REP-145: orientation covariance
// -1) are integrated, so only the change between two stamps is meaningful — which is all the
// tracker uses. ROS-free; the scan_matching nodelet feeds it from imu/data.
#include <Eigen/Geometry>
#include <deque>
#include <optional>

namespace osm_graph_slam {

class ImuOrientationBuffer {
 public:
  /// max_gap: [s] a stamp farther than this from the samples around it has no orientation.
  explicit ImuOrientationBuffer(double max_gap = 0.1, size_t capacity = 2000);

  /// A sample with an orientation (body in a fixed frame).
  void addOrientation(double stamp, const Eigen::Quaterniond& orientation);
  /// A sample with angular velocity only [rad/s, body frame], integrated from the last sample.
  void addAngularVelocity(double stamp, const Eigen::Vector3d& angular_velocity);

  std::optional<Eigen::Quaterniond> orientationAt(double stamp) const;
  size_t size() const { return samples_.size(); }
  /// [s] a stamp farther than this from the samples around it has no orientation.
  double maxGap() const { return max_gap_; }
  /// [s] of the newest sample (0 when empty).
  double newestStamp() const { return samples_.empty() ? 0.0 : samples_.back().stamp; }
  /// Forgets every sample (the time jumped back: later samples would be refused as out of order).
  void clear();

 private:
  struct Sample {
    double stamp;
    Eigen::Quaterniond orientation;
  };
  void push(double stamp, const Eigen::Quaterniond& q);

  double max_gap_;
  size_t capacity_;
  std::deque<Sample> samples_;
  std::optional<Eigen::Vector3d> last_rate_;
};

}  // namespace osm_graph_slam
