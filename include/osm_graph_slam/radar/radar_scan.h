#pragma once
// One spinning-radar sweep in polar form, sensor-independent: the power per (azimuth, range
// bin) with each azimuth's angle and time. Built from an Oxford Radar RobotCar scan (per-row
// timestamps and encoder counts in the PNG) or from a MulRan polar PNG (no per-row metadata: the
// azimuths are evenly spread over the turn, the time of each row is interpolated over the
// rotation period; see doc/radar.md for the layout and its source).
#include <cstdint>
#include <string>
#include <vector>

namespace osm_graph_slam {

struct OxfordRadarScan;

namespace radar {

struct RadarPolarScan {
  int num_azimuths = 0;
  int num_bins = 0;
  double range_resolution = 0.0432;  ///< [m/bin]; bin b is the range (b + 0.5) * resolution
  double stamp = 0.0;                ///< the scan's time [s] (the first azimuth's time)
  std::vector<double> azimuths;      ///< [rad] per row
  std::vector<double> times;         ///< [s] per row, same clock as stamp
  std::vector<uint8_t> power;        ///< num_azimuths x num_bins, row-major

  const uint8_t* row(int a) const { return power.data() + static_cast<size_t>(a) * num_bins; }
  double binRange(int b) const { return (b + 0.5) * range_resolution; }
  /// (first + last row time) / 2: the time Oxford's radar odometry keys a scan by.
  double midTime() const;
  bool empty() const { return num_azimuths == 0 || num_bins == 0; }
};

/// Oxford: times from the per-row UNIX microseconds, relative to time_origin_us (keeps doubles
/// exact to the microsecond).
RadarPolarScan fromOxford(const OxfordRadarScan& scan, int64_t time_origin_us);

/// The MulRan polar layout (doc/radar.md): 8-bit grey, one row per azimuth, one column per range
/// bin, no metadata columns; row a is the azimuth 2 pi a / rows; the file name is the scan's
/// stamp [ns] (the start of the sweep); rows are spread evenly over rotation_period.
struct MulranPolarLayout {
  int expected_azimuths = 400;
  int expected_bins = 3360;
  double range_resolution = 0.0595238;  ///< [m/bin] = 200 m / 3360 bins
  double rotation_period = 0.25;        ///< [s] 4 Hz
};

struct MulranPolarResult {
  bool ok = false;
  std::string error;  ///< names the file and the reason
  RadarPolarScan scan;
  explicit operator bool() const { return ok; }
};

/// Reads <stamp_ns>.png; time = (stamp_ns - time_origin_ns) * 1e-9. Errors (file and reason):
/// missing file, not a PNG, truncated (a chunk runs past the end or no IEND), not 8-bit grey,
/// wrong size, undecodable data.
MulranPolarResult readMulranPolarPng(const std::string& path, int64_t stamp_ns,
                                     int64_t time_origin_ns, const MulranPolarLayout& layout = {});

/// An 8-bit polar image in memory, one row per azimuth (e.g. the buffer of a radar/polar
/// sensor_msgs/Image that mulran2bag writes).
struct PolarImageView {
  const uint8_t* data = nullptr;
  size_t size = 0;                 ///< bytes available at data
  int rows = 0;                    ///< azimuths
  int cols = 0;                    ///< range bins
  size_t step = 0;                 ///< bytes per row (>= cols)
  std::string encoding = "mono8";  ///< "mono8" or "8UC1"; anything else is refused
};

/// The MulRan layout from memory: the conversion readMulranPolarPng applies after decoding
/// (azimuths evenly spread, row times over rotation_period from stamp [s]). Errors (the reason,
/// no prefix): empty image, encoding, wrong size, a row step below the width, too few bytes.
MulranPolarResult fromMulranImage(const PolarImageView& image, double stamp,
                                  const MulranPolarLayout& layout = {});

/// Writes a scan in the MulRan layout (8-bit grey PNG, rows = azimuths). Temp file + rename.
bool writeMulranPolarPng(const std::string& path, const RadarPolarScan& scan, std::string* error);

}  // namespace radar
}  // namespace osm_graph_slam
