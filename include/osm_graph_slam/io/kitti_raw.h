#pragma once
// KITTI raw ("<date>_drive_<n>_sync") and KITTI odometry ("sequences/NN") layouts: readers that
// name the first missing or malformed file, and the writers the simulator uses for its output.
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace osm_graph_slam {

/// pos_accuracy [m] at or above which an OXTS record carries no GNSS fix. The simulator's
/// outages write it (with numsats = posmode = 0); kitti2bag then publishes STATUS_NO_FIX and
/// offline_slam --kitti-raw ignores the position. Real KITTI records report a few centimetres.
constexpr double kOxtsNoFixAccuracy = 1.0e4;

/// One OXTS record (oxts/data/NNNNNNNNNN.txt), the 30 values of the KITTI raw devkit, in order.
struct OxtsRecord {
  double lat = 0, lon = 0, alt = 0;     ///< deg, deg, m
  double roll = 0, pitch = 0, yaw = 0;  ///< rad; yaw 0 = east, counter-clockwise
  double vn = 0, ve = 0;                ///< velocity north/east [m/s]
  double vf = 0, vl = 0, vu = 0;        ///< velocity forward/left/up [m/s]
  double ax = 0, ay = 0, az = 0;        ///< acceleration in the body x/y/z [m/s^2] (incl. gravity)
  double af = 0, al = 0, au = 0;        ///< acceleration forward/left/up [m/s^2] (incl. gravity)
  double wx = 0, wy = 0, wz = 0;        ///< angular rate around body x/y/z [rad/s]
  double wf = 0, wl = 0, wu = 0;        ///< angular rate around forward/left/up [rad/s]
  double pos_accuracy = 0, vel_accuracy = 0;
  int navstat = 0, numsats = 0, posmode = 0, velmode = 0, orimode = 0;

  static constexpr int kNumFields = 30;
  std::array<double, kNumFields> toArray() const;
  /// False for a record without a GNSS position fix (pos_accuracy >= kOxtsNoFixAccuracy, or a
  /// non-finite position): its INS fields (attitude, rates) stay valid, its position does not.
  bool hasGnssFix() const;
  static OxtsRecord fromArray(const std::array<double, kNumFields>& v);
};

/// Nanoseconds since the Unix epoch (UTC). Kept as an integer so stamps survive bit-exactly.
using StampNs = int64_t;

/// Parses "2011-09-26 13:02:25.964389445" (KITTI raw timestamps.txt). Returns false if malformed.
bool parseKittiTimestamp(const std::string& text, StampNs& stamp);
std::string formatKittiTimestamp(StampNs stamp);

/// Sorted regular files of dir ending in ext (e.g. ".bin"); empty when dir is unreadable.
std::vector<std::string> listFiles(const std::string& dir, const std::string& ext);

/// Reads a KITTI raw timestamps.txt (one stamp per line).
bool readKittiTimestamps(const std::string& path, std::vector<StampNs>& stamps,
                         std::string* error = nullptr);
bool writeKittiTimestamps(const std::string& path, const std::vector<StampNs>& stamps,
                          std::string* error = nullptr);

bool readOxtsFile(const std::string& path, OxtsRecord& record, std::string* error = nullptr);
bool writeOxtsFile(const std::string& path, const OxtsRecord& record, std::string* error = nullptr);

/// Reads a raw calibration file with "R: 9 values" and "T: 3 values" (calib_imu_to_velo.txt,
/// calib_velo_to_cam.txt). The result maps points of the first frame into the second.
bool readKittiRigidCalib(const std::string& path, Eigen::Isometry3d& transform,
                         std::string* error = nullptr);
bool writeKittiRigidCalib(const std::string& path, const Eigen::Isometry3d& transform,
                          std::string* error = nullptr);
/// Reads one "KEY: 12 values" (row-major 3x4) entry of a calibration file in the KITTI tracking
/// layout (P0..P3, R0_rect, Tr_velo_to_cam, Tr_imu_to_velo), e.g. key "Tr_imu_to_velo".
bool readKittiTrackingCalib(const std::string& path, const std::string& key,
                            Eigen::Isometry3d& transform, std::string* error = nullptr);

/// Reads a whole file of little-endian float32 values (a KITTI/MulRan .bin scan) without any
/// conversion, so it can be copied bit-exactly. Fails if the size is not a multiple of 16 bytes.
bool readFloat32Records(const std::string& path, std::vector<float>& values,
                        std::string* error = nullptr);

/// The LiDAR mounting p_velo = T_velo_imu p_imu from either calib_imu_to_velo.txt ("R:"/"T:")
/// or a calibration file in the KITTI tracking layout ("Tr_imu_to_velo:").
bool readImuToVeloCalib(const std::string& path, Eigen::Isometry3d& T_velo_imu,
                        std::string* error = nullptr);

/// The georeference of a folder of scans without per-scan OXTS (offline_slam --scans and
/// kitti2bag --scans, e.g. ../shared/data/kitti_raw_0005): the first scan's position, and its
/// attitude when known.
struct ScanFolderOrigin {
  double lat = 0, lon = 0, alt = 0;  ///< deg, deg, m
  std::optional<double> yaw;         ///< [rad] ENU, 0 = east, counter-clockwise
  std::optional<OxtsRecord> oxts;    ///< the whole record (roll, pitch, rates) with an OXTS file
};

/// Exactly one of oxts_path (a KITTI OXTS record of the first scan: position and roll/pitch/yaw)
/// and origin_text ("LAT,LON,ALT[,YAW_DEG]", yaw in degrees, ENU) must be non-empty. False with
/// a message for both/neither, a malformed record or text, or a record without a GNSS fix.
bool readScanFolderOrigin(const std::string& oxts_path, const std::string& origin_text,
                          ScanFolderOrigin& origin, std::string* error = nullptr);

/// A KITTI raw drive: files listed and timestamps/calibration read; scans and OXTS records are
/// read one at a time by the consumer.
struct KittiRawDrive {
  std::string drive_dir;
  std::vector<std::string> scan_files;  ///< velodyne_points/data/*.bin, sorted
  std::vector<StampNs> scan_stamps;     ///< velodyne_points/timestamps.txt
  std::vector<std::string> oxts_files;  ///< oxts/data/*.txt, sorted
  std::vector<StampNs> oxts_stamps;     ///< oxts/timestamps.txt
  /// oxts_true/data/*.txt and its timestamps.txt when the drive has them (simulate_urban: the
  /// exact records, while oxts/ holds what the GNSS/INS measured); empty otherwise.
  std::vector<std::string> truth_oxts_files;
  std::vector<StampNs> truth_oxts_stamps;
  Eigen::Isometry3d T_velo_imu = Eigen::Isometry3d::Identity();  ///< p_velo = T * p_imu
  Eigen::Isometry3d T_cam_velo = Eigen::Isometry3d::Identity();  ///< p_cam0 = T * p_velo
};

/// Opens drive_dir; the calibration files are looked up in calib_dir, or if empty in drive_dir
/// and then its parent (the KITTI "<date>/" folder). False with the first offending file named.
bool openKittiRawDrive(const std::string& drive_dir, const std::string& calib_dir,
                       KittiRawDrive& drive, std::string* error = nullptr);

/// A KITTI odometry sequence (sequences/NN).
struct KittiOdometrySequence {
  std::string sequence_dir;
  std::vector<std::string> scan_files;                   ///< velodyne/*.bin, sorted
  std::vector<double> times;                             ///< times.txt [s since sequence start]
  Eigen::Isometry3d Tr = Eigen::Isometry3d::Identity();  ///< calib.txt "Tr": p_cam0 = Tr p_velo
  std::vector<Eigen::Isometry3d> camera_poses;  ///< poses file (camera 0 frame), may be empty
  /// LiDAR poses in the first LiDAR frame: inv(Tr) * P * Tr (empty without a poses file).
  std::vector<Eigen::Isometry3d> lidarPoses() const;
};

/// Opens sequence_dir. poses_path: explicit poses file; if empty, ../../poses/NN.txt is used when
/// present (the KITTI odometry layout) and poses stay empty otherwise.
bool openKittiOdometrySequence(const std::string& sequence_dir, const std::string& poses_path,
                               KittiOdometrySequence& sequence, std::string* error = nullptr);

/// KITTI pose files: 12 values per line (row-major 3x4).
bool readKittiPoses(const std::string& path, std::vector<Eigen::Isometry3d>& poses,
                    std::string* error = nullptr);
bool writeKittiPoses(const std::string& path, const std::vector<Eigen::Isometry3d>& poses,
                     std::string* error = nullptr);

// Text files are written with writeFileAtomically (io/trajectory_io.h).

}  // namespace osm_graph_slam
