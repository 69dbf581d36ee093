#include "osm_graph_slam/radar/radar_scan.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/imgcodecs.hpp>

#include "osm_graph_slam/io/oxford_radar.h"

namespace fs = std::filesystem;

namespace osm_graph_slam::radar {
namespace {

uint32_t bigEndian32(const uint8_t* p) {
  return (uint32_t(p[0]) << 24) | (uint32_t(p[1]) << 16) | (uint32_t(p[2]) << 8) | uint32_t(p[3]);
}

/// Walks the PNG chunks before decoding, so that a truncated file is named as such (the decoder
/// would only say "cannot decode"). Fills width, height, bit depth and colour type from IHDR.
bool checkPng(const std::vector<uint8_t>& b, uint32_t& width, uint32_t& height, int& bit_depth,
              int& colour_type, std::string& reason) {
  static const uint8_t kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (b.size() < 8 || !std::equal(kSignature, kSignature + 8, b.begin())) {
    reason = "not a PNG (no PNG signature)";
    return false;
  }
  size_t pos = 8;
  bool ihdr = false;
  while (pos + 8 <= b.size()) {
    const uint32_t length = bigEndian32(&b[pos]);
    const std::string type(reinterpret_cast<const char*>(&b[pos + 4]), 4);
    const size_t need = size_t(length) + 12;
    if (pos + need > b.size()) {
      reason = "truncated PNG: chunk '" + type + "' at byte " + std::to_string(pos) + " needs " +
               std::to_string(need) + " bytes but the file ends at byte " +
               std::to_string(b.size());
      return false;
    }
    if (type == "IHDR" && length >= 13) {
      width = bigEndian32(&b[pos + 8]);
      height = bigEndian32(&b[pos + 12]);
      bit_depth = b[pos + 16];
      colour_type = b[pos + 17];
      ihdr = true;
    }
    if (type == "IEND") {
      if (!ihdr) {
        reason = "PNG without IHDR";
        return false;
      }
      return true;
    }
    pos += need;
  }
  reason = "truncated PNG: no IEND chunk (file ends at byte " + std::to_string(b.size()) + ")";
  return false;
}

}  // namespace

double RadarPolarScan::midTime() const {
  if (times.empty()) return stamp;
  return 0.5 * (times.front() + times.back());
}

RadarPolarScan fromOxford(const OxfordRadarScan& o, int64_t time_origin_us) {
  RadarPolarScan s;
  s.num_azimuths = o.num_azimuths;
  s.num_bins = o.num_bins;
  s.range_resolution = o.range_resolution;
  s.stamp = double(o.stamp_us - time_origin_us) * 1e-6;
  s.azimuths = o.azimuths;
  s.times.resize(o.azimuth_stamps_us.size());
  for (size_t i = 0; i < s.times.size(); ++i)
    s.times[i] = double(o.azimuth_stamps_us[i] - time_origin_us) * 1e-6;
  s.power = o.power;
  // Invalid rows carry no returns (the dataset marks dropped azimuths).
  for (int a = 0; a < s.num_azimuths; ++a)
    if (a < int(o.valid.size()) && !o.valid[a])
      std::fill(s.power.begin() + size_t(a) * s.num_bins,
                s.power.begin() + size_t(a + 1) * s.num_bins, 0);
  return s;
}

MulranPolarResult readMulranPolarPng(const std::string& path, int64_t stamp_ns,
                                     int64_t time_origin_ns, const MulranPolarLayout& layout) {
  MulranPolarResult r;
  const std::string prefix = "MulRan radar PNG '" + path + "': ";
  std::error_code ec;
  if (!fs::exists(path, ec)) {
    r.error = prefix + "missing file";
    return r;
  }
  if (!fs::is_regular_file(path, ec)) {
    r.error = prefix + "not a regular file";
    return r;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    r.error = prefix + "cannot open";
    return r;
  }
  std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                             std::istreambuf_iterator<char>());
  uint32_t width = 0, height = 0;
  int bit_depth = 0, colour_type = 0;
  std::string reason;
  if (!checkPng(bytes, width, height, bit_depth, colour_type, reason)) {
    r.error = prefix + reason;
    return r;
  }
  if (bit_depth != 8 || colour_type != 0) {
    r.error = prefix + "not 8-bit grey (bit depth " + std::to_string(bit_depth) + ", colour type " +
              std::to_string(colour_type) + ")";
    return r;
  }
  if ((layout.expected_azimuths > 0 && int(height) != layout.expected_azimuths) ||
      (layout.expected_bins > 0 && int(width) != layout.expected_bins)) {
    r.error = prefix + "wrong size " + std::to_string(width) + " x " + std::to_string(height) +
              ", the layout expects " + std::to_string(layout.expected_bins) + " bins x " +
              std::to_string(layout.expected_azimuths) + " azimuths";
    return r;
  }
  const cv::Mat buffer(1, int(bytes.size()), CV_8UC1, bytes.data());
  const cv::Mat image = cv::imdecode(buffer, cv::IMREAD_UNCHANGED);
  if (image.empty() || image.type() != CV_8UC1 || image.cols != int(width) ||
      image.rows != int(height)) {
    r.error = prefix + "the PNG decoder rejected the image data";
    return r;
  }
  PolarImageView view;
  view.data = image.data;
  view.rows = image.rows;
  view.cols = image.cols;
  view.step = image.step[0];
  view.size = view.step * size_t(image.rows);
  r = fromMulranImage(view, double(stamp_ns - time_origin_ns) * 1e-9, layout);
  if (!r.ok) r.error = prefix + r.error;
  return r;
}

MulranPolarResult fromMulranImage(const PolarImageView& image, double stamp,
                                  const MulranPolarLayout& layout) {
  MulranPolarResult r;
  if (image.rows <= 0 || image.cols <= 0 || image.data == nullptr) {
    r.error =
        "empty image (" + std::to_string(image.cols) + " x " + std::to_string(image.rows) + ")";
    return r;
  }
  if (image.encoding != "mono8" && image.encoding != "8UC1") {
    r.error = "encoding '" + image.encoding + "', expected mono8 (8-bit grey)";
    return r;
  }
  if ((layout.expected_azimuths > 0 && image.rows != layout.expected_azimuths) ||
      (layout.expected_bins > 0 && image.cols != layout.expected_bins)) {
    r.error = "wrong size " + std::to_string(image.cols) + " x " + std::to_string(image.rows) +
              ", the layout expects " + std::to_string(layout.expected_bins) + " bins x " +
              std::to_string(layout.expected_azimuths) + " azimuths";
    return r;
  }
  if (image.step < size_t(image.cols)) {
    r.error =
        "row step " + std::to_string(image.step) + " below the width " + std::to_string(image.cols);
    return r;
  }
  const size_t need = image.step * size_t(image.rows - 1) + size_t(image.cols);
  if (image.size < need) {
    r.error = "image data of " + std::to_string(image.size) + " bytes, " + std::to_string(need) +
              " needed";
    return r;
  }
  RadarPolarScan& s = r.scan;
  s.num_azimuths = image.rows;
  s.num_bins = image.cols;
  s.range_resolution = layout.range_resolution;
  s.stamp = stamp;
  s.azimuths.resize(s.num_azimuths);
  s.times.resize(s.num_azimuths);
  for (int a = 0; a < s.num_azimuths; ++a) {
    s.azimuths[a] = 2.0 * M_PI * a / s.num_azimuths;
    s.times[a] = s.stamp + layout.rotation_period * a / s.num_azimuths;
  }
  s.power.resize(size_t(s.num_azimuths) * s.num_bins);
  for (int a = 0; a < s.num_azimuths; ++a) {
    const uint8_t* row = image.data + image.step * size_t(a);
    std::copy(row, row + s.num_bins, s.power.begin() + size_t(a) * s.num_bins);
  }
  r.ok = true;
  return r;
}

bool writeMulranPolarPng(const std::string& path, const RadarPolarScan& scan, std::string* error) {
  if (scan.empty() || scan.power.size() != size_t(scan.num_azimuths) * scan.num_bins) {
    if (error) *error = "radar scan for '" + path + "' is empty or inconsistent";
    return false;
  }
  const cv::Mat image(scan.num_azimuths, scan.num_bins, CV_8UC1,
                      const_cast<uint8_t*>(scan.power.data()));
  const std::string tmp = path + ".tmp.png";
  if (!cv::imwrite(tmp, image, {cv::IMWRITE_PNG_COMPRESSION, 3})) {
    if (error) *error = "cannot write '" + tmp + "'";
    return false;
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    if (error) *error = "cannot rename '" + tmp + "' to '" + path + "': " + ec.message();
    return false;
  }
  return true;
}

}  // namespace osm_graph_slam::radar
