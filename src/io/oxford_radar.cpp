#include "osm_graph_slam/io/oxford_radar.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

namespace fs = std::filesystem;

namespace osm_graph_slam {
namespace {

constexpr double kPi = 3.14159265358979323846;

template <typename T>
OxfordRadarResult<T> failure(const std::string& msg) {
  OxfordRadarResult<T> r;
  r.error = msg;
  return r;
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  const auto e = s.find_last_not_of(" \t\r");
  return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
}

std::vector<std::string> splitCsv(const std::string& line) {
  std::vector<std::string> out;
  std::string cell;
  std::istringstream in(line);
  while (std::getline(in, cell, ',')) out.push_back(trim(cell));
  if (!line.empty() && line.back() == ',') out.emplace_back();  // a trailing empty cell
  return out;
}

bool toInt64(const std::string& s, int64_t& v) {
  if (s.empty()) return false;
  char* end = nullptr;
  errno = 0;
  v = std::strtoll(s.c_str(), &end, 10);
  return end != s.c_str() && *end == '\0' && errno == 0;
}

bool toFiniteDouble(const std::string& s, double& v) {
  if (s.empty()) return false;
  char* end = nullptr;
  v = std::strtod(s.c_str(), &end);
  return end != s.c_str() && *end == '\0' && std::isfinite(v);
}

uint32_t bigEndian32(const uint8_t* p) {
  return (uint32_t(p[0]) << 24) | (uint32_t(p[1]) << 16) | (uint32_t(p[2]) << 8) | uint32_t(p[3]);
}

int64_t littleEndianInt64(const uint8_t* p) {
  uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return static_cast<int64_t>(v);
}

/// Reads a whole file; error is "<what> '<path>' is missing" etc.
bool readWholeFile(const std::string& what, const std::string& path, std::vector<uint8_t>& bytes,
                   std::string& error) {
  std::error_code ec;
  if (!fs::exists(path, ec)) {
    error = what + " '" + path + "' is missing";
    return false;
  }
  if (!fs::is_regular_file(path, ec)) {
    error = what + " '" + path + "' is not a regular file";
    return false;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    error = "cannot open " + what + " '" + path + "'";
    return false;
  }
  bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  if (in.bad()) {
    error = "cannot read " + what + " '" + path + "'";
    return false;
  }
  return true;
}

struct PngHeader {
  uint32_t width = 0, height = 0;
  int bit_depth = 0, colour_type = 0;
};

/// Walks the PNG chunks (signature, IHDR first, ..., IEND) without decoding, so that a file cut
/// short is reported as truncated with the byte offset rather than as a vague decoder failure.
bool checkPngStructure(const std::vector<uint8_t>& b, PngHeader& header, std::string& reason) {
  static const uint8_t kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (b.size() < 8 || !std::equal(kSignature, kSignature + 8, b.begin())) {
    reason = "not a PNG (no PNG signature in the first 8 bytes; file size " +
             std::to_string(b.size()) + " bytes)";
    return false;
  }
  size_t pos = 8;
  bool first = true;
  while (true) {
    if (pos + 8 > b.size()) {
      reason = "truncated PNG: the file ends at byte " + std::to_string(b.size()) +
               " before the IEND chunk";
      return false;
    }
    const uint32_t length = bigEndian32(&b[pos]);
    const std::string type(reinterpret_cast<const char*>(&b[pos + 4]), 4);
    if (length > 0x7fffffffu) {
      reason = "corrupt PNG: chunk at byte " + std::to_string(pos) + " declares length " +
               std::to_string(length);
      return false;
    }
    if (pos + 12 + length > b.size()) {
      reason = "truncated PNG: chunk '" + type + "' at byte " + std::to_string(pos) + " needs " +
               std::to_string(12 + length) + " bytes but the file ends at byte " +
               std::to_string(b.size());
      return false;
    }
    if (first) {
      if (type != "IHDR" || length != 13) {
        reason = "corrupt PNG: the first chunk is '" + type + "', not IHDR";
        return false;
      }
      header.width = bigEndian32(&b[pos + 8]);
      header.height = bigEndian32(&b[pos + 12]);
      header.bit_depth = b[pos + 16];
      header.colour_type = b[pos + 17];
      first = false;
    }
    if (type == "IEND") return true;
    pos += 12 + length;
  }
}

}  // namespace

int64_t OxfordRadarScan::midStampUs() const {
  if (azimuth_stamps_us.empty()) return stamp_us;
  return (azimuth_stamps_us.front() + azimuth_stamps_us.back()) / 2;
}

Eigen::Isometry3d OxfordRadarOdometry::transform() const {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  t.translation() = Eigen::Vector3d(x, y, z);
  return t;
}

std::string oxfordRadarPngPath(const std::string& drive_dir, int64_t stamp_us) {
  return (fs::path(drive_dir) / "radar" / (std::to_string(stamp_us) + ".png")).string();
}

OxfordRadarResult<OxfordRadarScan> readOxfordRadarPng(const std::string& path,
                                                      const OxfordRadarLayout& layout) {
  using Result = OxfordRadarResult<OxfordRadarScan>;
  const std::string what = "Oxford radar PNG";
  const std::string prefix = what + " '" + path + "': ";
  std::vector<uint8_t> bytes;
  std::string error;
  if (!readWholeFile(what, path, bytes, error)) return failure<OxfordRadarScan>(error);
  if (layout.metadata_columns < 11 || layout.encoder_size <= 0 ||
      !(layout.range_resolution > 0.0)) {
    return failure<OxfordRadarScan>(prefix + "invalid layout (metadata_columns " +
                                    std::to_string(layout.metadata_columns) + ", encoder_size " +
                                    std::to_string(layout.encoder_size) + ")");
  }

  PngHeader header;
  std::string reason;
  if (!checkPngStructure(bytes, header, reason)) return failure<OxfordRadarScan>(prefix + reason);
  if (header.bit_depth != 8 || header.colour_type != 0) {
    return failure<OxfordRadarScan>(prefix + "not 8-bit grayscale (bit depth " +
                                    std::to_string(header.bit_depth) + ", colour type " +
                                    std::to_string(header.colour_type) + ")");
  }
  const std::string dims = std::to_string(header.width) + " x " + std::to_string(header.height);
  if (layout.expected_azimuths > 0 && header.height != uint32_t(layout.expected_azimuths)) {
    return failure<OxfordRadarScan>(prefix + "wrong height: " + std::to_string(header.height) +
                                    " rows (image " + dims + "), the layout expects " +
                                    std::to_string(layout.expected_azimuths) + " azimuths");
  }
  if (header.width <= uint32_t(layout.metadata_columns)) {
    return failure<OxfordRadarScan>(prefix + "wrong width: " + std::to_string(header.width) +
                                    " columns (image " + dims + ") leave no room for power bins" +
                                    " after " + std::to_string(layout.metadata_columns) +
                                    " metadata columns");
  }
  if (layout.expected_bins > 0 &&
      header.width != uint32_t(layout.metadata_columns + layout.expected_bins)) {
    return failure<OxfordRadarScan>(
        prefix + "wrong width: " + std::to_string(header.width) + " columns (image " + dims +
        "), the layout expects " + std::to_string(layout.metadata_columns) + " metadata + " +
        std::to_string(layout.expected_bins) +
        " bins = " + std::to_string(layout.metadata_columns + layout.expected_bins));
  }
  if (header.height == 0) return failure<OxfordRadarScan>(prefix + "no rows (image " + dims + ")");

  cv::Mat image;
  try {
    const cv::Mat buffer(1, static_cast<int>(bytes.size()), CV_8UC1, bytes.data());
    image = cv::imdecode(buffer, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    return failure<OxfordRadarScan>(prefix + "PNG decoding failed: " + e.what());
  }
  if (image.empty()) {
    return failure<OxfordRadarScan>(prefix + "PNG data could not be decoded (corrupt image data)");
  }
  if (image.type() != CV_8UC1 || image.cols != int(header.width) ||
      image.rows != int(header.height)) {
    return failure<OxfordRadarScan>(prefix + "decoded image is not " + dims + " 8-bit grayscale");
  }

  Result result;
  OxfordRadarScan& scan = result.value;
  scan.path = path;
  scan.num_azimuths = image.rows;
  scan.num_bins = image.cols - layout.metadata_columns;
  scan.range_resolution = layout.range_resolution;
  const size_t n = static_cast<size_t>(scan.num_azimuths);
  scan.azimuth_stamps_us.resize(n);
  scan.encoder_counts.resize(n);
  scan.azimuths.resize(n);
  scan.valid.resize(n);
  scan.power.resize(n * static_cast<size_t>(scan.num_bins));
  for (int r = 0; r < image.rows; ++r) {
    const uint8_t* p = image.ptr<uint8_t>(r);
    scan.azimuth_stamps_us[r] = littleEndianInt64(p);
    const uint16_t count = static_cast<uint16_t>(p[8] | (p[9] << 8));
    if (count >= layout.encoder_size) {
      return failure<OxfordRadarScan>(prefix + "row " + std::to_string(r) + ": azimuth encoder " +
                                      "count " + std::to_string(count) + " >= encoder size " +
                                      std::to_string(layout.encoder_size));
    }
    scan.encoder_counts[r] = count;
    scan.azimuths[r] = 2.0 * kPi * count / layout.encoder_size;
    scan.valid[r] = p[10] == 255 ? 1 : 0;
    std::copy(p + layout.metadata_columns, p + image.cols,
              scan.power.begin() + static_cast<size_t>(r) * scan.num_bins);
  }
  scan.stamp_us = scan.azimuth_stamps_us.front();
  result.ok = true;
  return result;
}

OxfordRadarResult<std::vector<OxfordRadarStamp>> readOxfordRadarTimestamps(
    const std::string& path) {
  using Stamps = std::vector<OxfordRadarStamp>;
  const std::string what = "Oxford radar timestamps file";
  if (!fs::exists(path)) return failure<Stamps>(what + " '" + path + "' is missing");
  std::ifstream in(path);
  if (!in) return failure<Stamps>("cannot open " + what + " '" + path + "'");
  OxfordRadarResult<Stamps> result;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const std::string t = trim(line);
    if (t.empty()) continue;
    std::istringstream tokens(t);
    std::vector<std::string> cells{std::istream_iterator<std::string>(tokens),
                                   std::istream_iterator<std::string>()};
    OxfordRadarStamp s;
    int64_t chunk = 0;
    const std::string where = what + " '" + path + "' line " + std::to_string(line_no) + ": ";
    if (cells.size() != 2 || !toInt64(cells[0], s.stamp_us) || !toInt64(cells[1], chunk) ||
        s.stamp_us <= 0 || chunk < 0 || chunk > 1000000) {
      return failure<Stamps>(where + "expected '<stamp_us> <chunk>', got '" + t + "'");
    }
    s.chunk = static_cast<int>(chunk);
    if (!result.value.empty() && s.stamp_us <= result.value.back().stamp_us) {
      return failure<Stamps>(where + "timestamp " + std::to_string(s.stamp_us) +
                             " is not after the previous one (" +
                             std::to_string(result.value.back().stamp_us) + ")");
    }
    result.value.push_back(s);
  }
  if (in.bad()) return failure<Stamps>("cannot read " + what + " '" + path + "'");
  result.ok = true;
  return result;
}

OxfordRadarResult<std::vector<OxfordRadarOdometry>> readOxfordRadarOdometry(
    const std::string& path) {
  using Rows = std::vector<OxfordRadarOdometry>;
  const std::string what = "Oxford radar odometry file";
  static const std::vector<std::string> kColumns = {
      "source_timestamp",       "destination_timestamp",      "x", "y", "z", "roll", "pitch", "yaw",
      "source_radar_timestamp", "destination_radar_timestamp"};
  if (!fs::exists(path)) return failure<Rows>(what + " '" + path + "' is missing");
  std::ifstream in(path);
  if (!in) return failure<Rows>("cannot open " + what + " '" + path + "'");

  std::string line;
  int line_no = 0;
  size_t columns = 0;
  OxfordRadarResult<Rows> result;
  while (std::getline(in, line)) {
    ++line_no;
    if (trim(line).empty()) continue;
    const auto cells = splitCsv(trim(line));
    const std::string where = what + " '" + path + "' line " + std::to_string(line_no) + ": ";
    if (columns == 0) {  // the header
      const bool known_size = cells.size() == 8 || cells.size() == 10;
      if (!known_size || !std::equal(cells.begin(), cells.end(), kColumns.begin())) {
        return failure<Rows>(where + "expected the header '" +
                             "source_timestamp,destination_timestamp,x,y,z,roll,pitch,yaw"
                             "[,source_radar_timestamp,destination_radar_timestamp]', got '" +
                             trim(line) + "'");
      }
      columns = cells.size();
      continue;
    }
    if (cells.size() != columns) {
      return failure<Rows>(where + "expected " + std::to_string(columns) + " columns, got " +
                           std::to_string(cells.size()) + ": '" + trim(line) + "'");
    }
    OxfordRadarOdometry o;
    double* values[6] = {&o.x, &o.y, &o.z, &o.roll, &o.pitch, &o.yaw};
    bool ok = toInt64(cells[0], o.source_stamp_us) && toInt64(cells[1], o.destination_stamp_us);
    for (int i = 0; i < 6 && ok; ++i) ok = toFiniteDouble(cells[2 + i], *values[i]);
    if (ok && columns == 10) {
      o.has_radar_stamps = true;
      ok = toInt64(cells[8], o.source_radar_stamp_us) &&
           toInt64(cells[9], o.destination_radar_stamp_us);
    }
    if (!ok) return failure<Rows>(where + "a value is not a number: '" + trim(line) + "'");
    result.value.push_back(o);
  }
  if (in.bad()) return failure<Rows>("cannot read " + what + " '" + path + "'");
  if (columns == 0) return failure<Rows>(what + " '" + path + "' is empty (no header line)");
  result.ok = true;
  return result;
}

}  // namespace osm_graph_slam
