#pragma once
// MulRan sequence layout (Kim et al., ICRA 2020):
//   <root>/global_pose.csv                  stamp_ns, 12 values of the row-major 3x4 base pose
//   <root>/sensor_data/data_stamp.csv       stamp_ns,sensor (ouster | radar | gps | imu | ...)
//   <root>/sensor_data/gps.csv              stamp_ns, lat, lon, alt, 9 position covariances
//   <root>/sensor_data/xsens_imu.csv        stamp_ns, qx qy qz qw, euler xyz [, gyro xyz, acc
//                                           xyz, mag xyz] (8 or 17 values)
//   <root>/sensor_data/Ouster/<ns>.bin      float32 x y z intensity
//   <root>/sensor_data/radar/polar/<ns>.png 8-bit polar radar image
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace osm_graph_slam {

struct MulranStamp {
  int64_t stamp_ns = 0;
  std::string sensor;
};

struct MulranGps {
  int64_t stamp_ns = 0;
  double lat = 0, lon = 0, alt = 0;
  std::array<double, 9> covariance{};
};

struct MulranImu {
  int64_t stamp_ns = 0;
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  ///< from the x y z w columns
  Eigen::Vector3d euler = Eigen::Vector3d::Zero();
  bool has_rates = false;  ///< the 17-column format: gyro, acceleration and magnetometer
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();
  Eigen::Vector3d acc = Eigen::Vector3d::Zero();
  Eigen::Vector3d mag = Eigen::Vector3d::Zero();
};

struct MulranPose {
  int64_t stamp_ns = 0;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
};

struct MulranSequence {
  std::string root;
  std::vector<MulranStamp> stamps;  ///< data_stamp.csv in file order
  std::vector<MulranGps> gps;
  std::vector<MulranImu> imu;
  std::vector<MulranPose> poses;  ///< global_pose.csv (empty if absent)

  std::string ousterPath(int64_t stamp_ns) const;
  std::string radarPolarPath(int64_t stamp_ns) const;
};

/// Reads the CSV files of a MulRan sequence (scans and images stay on disk). data_stamp.csv,
/// gps.csv and xsens_imu.csv are required; global_pose.csv is optional. False with the first
/// missing or malformed file (and line) named in error.
bool readMulranSequence(const std::string& root, MulranSequence& sequence,
                        std::string* error = nullptr);

}  // namespace osm_graph_slam
