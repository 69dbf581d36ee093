#pragma once
// Oxford Radar RobotCar (Barnes et al., ICRA 2020), Navtech CTS350-X radar, dataset layout:
//   <drive>/radar/<stamp_us>.png     one scan in polar form, 8-bit grayscale, one row per azimuth:
//                                    bytes 0-7   int64 little-endian UNIX timestamp [us]
//                                    bytes 8-9   uint16 little-endian azimuth encoder count
//                                                (0 .. encoder_size-1, a full turn = 5600)
//                                    byte  10    validity (255 = valid)
//                                    bytes 11..  power per range bin (8-bit), bin b covers
//                                                the range (b + 0.5) * 0.0432 m (SDK convention)
//                                    (400 azimuths x 3768 bins, 3779 columns, in the 2019 drives)
//   <drive>/radar.timestamps         "<stamp_us> <chunk>" per scan; stamp = the PNG's file name
//   <drive>/gt/radar_odometry.csv    relative motion between consecutive scans (header line,
//                                    then source_timestamp, destination_timestamp, x, y, z, roll,
//                                    pitch, yaw[, source_radar_timestamp,
//                                    destination_radar_timestamp])
// No OpenCV in this header: the power matrix is a plain row-major byte vector.
// See doc/radar.md.
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

namespace osm_graph_slam {

/// The outcome of a reader: ok, else error names the file and the reason (nothing throws).
template <typename T>
struct OxfordRadarResult {
  bool ok = false;
  std::string error;
  T value{};

  explicit operator bool() const { return ok; }
};

/// The polar image layout. Defaults: the CTS350-X of the Oxford Radar RobotCar dataset.
struct OxfordRadarLayout {
  double range_resolution = 0.0432;  ///< [m/bin]
  int encoder_size = 5600;           ///< encoder counts per full turn
  int metadata_columns = 11;         ///< 8 timestamp + 2 encoder + 1 valid byte
  int expected_azimuths = 400;       ///< image height; 0 accepts any
  int expected_bins = 3768;          ///< image width - metadata_columns; 0 accepts any
};

/// One polar scan. Row a of every per-azimuth vector is row a of the image.
struct OxfordRadarScan {
  std::string path;
  int64_t stamp_us = 0;  ///< the scan's radar timestamp: the first azimuth's timestamp [us]
  int num_azimuths = 0;
  int num_bins = 0;
  double range_resolution = 0.0432;        ///< [m/bin]
  std::vector<int64_t> azimuth_stamps_us;  ///< UNIX time [us] per azimuth
  std::vector<uint16_t> encoder_counts;    ///< raw azimuth encoder value per azimuth
  std::vector<double> azimuths;            ///< [rad] in [0, 2*pi): 2*pi*count/encoder_size
  std::vector<uint8_t> valid;              ///< 1 if the row's validity byte is 255, else 0
  std::vector<uint8_t> power;              ///< num_azimuths x num_bins, row-major

  uint8_t powerAt(int azimuth, int bin) const {
    return power[static_cast<size_t>(azimuth) * num_bins + bin];
  }
  const uint8_t* row(int azimuth) const {
    return power.data() + static_cast<size_t>(azimuth) * num_bins;
  }
  /// Range of the centre of bin b [m] (the dataset SDK's convention: (b + 0.5) * resolution).
  double binRange(int bin) const { return (bin + 0.5) * range_resolution; }
  double maxRange() const { return num_bins * range_resolution; }
  /// (first + last azimuth timestamp) / 2 [us]: radar_odometry.csv's source/destination
  /// timestamp of this scan (measured equal to within 1 us on the 2019-01-10 drive).
  int64_t midStampUs() const;
};

/// One line of radar.timestamps.
struct OxfordRadarStamp {
  int64_t stamp_us = 0;  ///< UNIX time [us], the scan's PNG file name
  int chunk = 0;         ///< the dataset's download chunk
};

/// One line of radar_odometry.csv: the motion from the destination scan (the earlier one) to
/// the source scan (the later one), i.e. the source scan's pose in the destination scan's frame
/// (the SDK chains absolute = absolute * relative). Planar (z, roll, pitch are 0) in this file.
struct OxfordRadarOdometry {
  int64_t source_stamp_us = 0;          ///< the later scan's mid-scan time [us]
  int64_t destination_stamp_us = 0;     ///< the earlier scan's mid-scan time [us]
  double x = 0, y = 0, z = 0;           ///< [m]
  double roll = 0, pitch = 0, yaw = 0;  ///< [rad]
  bool has_radar_stamps = false;        ///< the 10-column variant of the file
  int64_t source_radar_stamp_us = -1;   ///< the later scan's radar timestamp (PNG name) [us]
  int64_t destination_radar_stamp_us = -1;

  /// Translation (x, y, z), rotation Rz(yaw) * Ry(pitch) * Rx(roll) (the SDK's
  /// build_se3_transform).
  Eigen::Isometry3d transform() const;
};

/// Reads one polar scan PNG. Errors (file and reason): missing or unreadable file, not a PNG,
/// truncated PNG (a chunk runs past the end of the file, or no IEND), not 8-bit grayscale, width
/// or height other than the layout's, undecodable data, encoder count >= encoder_size.
OxfordRadarResult<OxfordRadarScan> readOxfordRadarPng(const std::string& path,
                                                      const OxfordRadarLayout& layout = {});

/// <drive>/radar/<stamp_us>.png
std::string oxfordRadarPngPath(const std::string& drive_dir, int64_t stamp_us);

/// Reads radar.timestamps ("<stamp_us> <chunk>" per line, blank lines skipped). Errors: missing
/// file, malformed line, timestamps not strictly increasing (each with its line number).
OxfordRadarResult<std::vector<OxfordRadarStamp>> readOxfordRadarTimestamps(const std::string& path);

/// Reads radar_odometry.csv. The first line must be the header (8 columns, or 10 with the
/// radar timestamps); every data line must have the header's column count and be numeric.
/// Errors name the file and the line number.
OxfordRadarResult<std::vector<OxfordRadarOdometry>> readOxfordRadarOdometry(
    const std::string& path);

}  // namespace osm_graph_slam
