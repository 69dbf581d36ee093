// The Oxford Radar RobotCar readers (polar PNG scans, radar.timestamps, radar_odometry.csv) on the
// 11 real scans of ../shared/data/oxford_radar, plus malformed and truncated inputs.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <iterator>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "osm_graph_slam/io/oxford_radar.h"
#include "test_data.h"

using namespace osm_graph_slam;

namespace {

constexpr double kTwoPi = 2.0 * 3.14159265358979323846;

std::string radarDir() {
  return test::sharedDataPath("oxford_radar");
}

std::string tempPath(const std::string& name) {
  return ::testing::TempDir() + "/oxford_radar_test_" + name;
}

void writeText(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

bool contains(const std::string& haystack, const std::string& needle) {
  return haystack.find(needle) != std::string::npos;
}

/// A synthetic scan image in the dataset's layout: row r has timestamp t0 + 600 r, encoder count
/// 13 + 14 r (mod 5600), validity 255 except row 5, power (r + b) % 251.
cv::Mat syntheticScan(int rows, int bins, int64_t t0) {
  cv::Mat img(rows, 11 + bins, CV_8UC1);
  for (int r = 0; r < rows; ++r) {
    uint8_t* p = img.ptr<uint8_t>(r);
    const uint64_t t = static_cast<uint64_t>(t0 + 600 * r);
    for (int i = 0; i < 8; ++i) p[i] = static_cast<uint8_t>(t >> (8 * i));
    const int count = (13 + 14 * r) % 5600;
    p[8] = static_cast<uint8_t>(count & 0xff);
    p[9] = static_cast<uint8_t>(count >> 8);
    p[10] = r == 5 ? 0 : 255;
    for (int b = 0; b < bins; ++b) p[11 + b] = static_cast<uint8_t>((r + b) % 251);
  }
  return img;
}

/// The 11 scans with their radar.timestamps entries (empty when the data is absent).
struct RealScans {
  std::vector<OxfordRadarStamp> stamps;
  std::vector<OxfordRadarScan> scans;
};

const RealScans& realScans() {
  static const RealScans data = [] {
    RealScans d;
    auto stamps = readOxfordRadarTimestamps(radarDir() + "/radar.timestamps");
    if (!stamps) return d;
    d.stamps = stamps.value;
    for (const auto& s : d.stamps) {
      auto scan = readOxfordRadarPng(oxfordRadarPngPath(radarDir(), s.stamp_us));
      if (!scan) {
        ADD_FAILURE() << scan.error;
        continue;
      }
      d.scans.push_back(std::move(scan.value));
    }
    return d;
  }();
  return data;
}

}  // namespace

// ------------------------------------------------------------------------------------------------
// Real data
// ------------------------------------------------------------------------------------------------

TEST(OxfordRadar, ReadsTheElevenTimestamps) {
  const std::string path = radarDir() + "/radar.timestamps";
  OGS_REQUIRE_SHARED_FILE(path);
  const auto stamps = readOxfordRadarTimestamps(path);
  ASSERT_TRUE(stamps.ok) << stamps.error;
  ASSERT_EQ(stamps.value.size(), 11u);
  EXPECT_EQ(stamps.value.front().stamp_us, 1547131046353776);  // 2019-01-10
  EXPECT_EQ(stamps.value.back().stamp_us, 1547131048845472);
  double min_period = 1e9, max_period = 0;
  for (size_t i = 0; i + 1 < stamps.value.size(); ++i) {
    EXPECT_EQ(stamps.value[i].chunk, 1);
    const double period = (stamps.value[i + 1].stamp_us - stamps.value[i].stamp_us) * 1e-3;
    min_period = std::min(min_period, period);
    max_period = std::max(max_period, period);
  }
  // ~4 Hz (README); measured 247.2 .. 252.8 ms.
  EXPECT_GT(min_period, 240.0);
  EXPECT_LT(max_period, 260.0);
  std::cout << "[ measured ] scan period " << min_period << " .. " << max_period << " ms\n";
}

TEST(OxfordRadar, ReadsAllElevenScansInTheDocumentedLayout) {
  OGS_REQUIRE_SHARED_FILE(radarDir() + "/radar.timestamps");
  const RealScans& d = realScans();
  ASSERT_EQ(d.stamps.size(), 11u);
  ASSERT_EQ(d.scans.size(), 11u);
  const double step = kTwoPi / 400.0;
  for (size_t k = 0; k < d.scans.size(); ++k) {
    const OxfordRadarScan& s = d.scans[k];
    SCOPED_TRACE(s.path);
    // README: 400 azimuths x 3768 bins of 4.32 cm, encoder out of 5600.
    ASSERT_EQ(s.num_azimuths, 400);
    ASSERT_EQ(s.num_bins, 3768);
    ASSERT_EQ(s.power.size(), 400u * 3768u);
    EXPECT_DOUBLE_EQ(s.range_resolution, 0.0432);
    EXPECT_NEAR(s.maxRange(), 162.78, 0.01);
    EXPECT_NEAR(s.binRange(0), 0.0216, 1e-12);

    // The scan's stamp is its first azimuth's, its file name and its radar.timestamps entry.
    EXPECT_EQ(s.stamp_us, d.stamps[k].stamp_us);
    EXPECT_EQ(s.azimuth_stamps_us.front(), d.stamps[k].stamp_us);
    EXPECT_EQ(std::to_string(s.stamp_us) + ".png", s.path.substr(s.path.find_last_of('/') + 1));

    // Azimuths strictly increasing over [0, 2 pi), one full turn in 400 equal steps.
    int valid = 0;
    for (int a = 0; a < s.num_azimuths; ++a) {
      EXPECT_GE(s.azimuths[a], 0.0);
      EXPECT_LT(s.azimuths[a], kTwoPi);
      EXPECT_NEAR(s.azimuths[a], kTwoPi * s.encoder_counts[a] / 5600.0, 1e-12);
      if (a > 0) {
        EXPECT_GT(s.azimuths[a], s.azimuths[a - 1]);
        EXPECT_NEAR(s.azimuths[a] - s.azimuths[a - 1], step, 1e-9);  // 14 counts
        EXPECT_GT(s.azimuth_stamps_us[a], s.azimuth_stamps_us[a - 1]);
      }
      valid += s.valid[a];
    }
    EXPECT_LT(s.azimuths.front(), step);
    EXPECT_GT(s.azimuths.back(), kTwoPi - step);
    EXPECT_EQ(valid, 400);

    // Per-azimuth timestamps: one turn takes about one scan period and ends before the next scan
    // starts (measured span 246.9 .. 252.5 ms, 10 .. 382 us before the next scan).
    const double span_ms = (s.azimuth_stamps_us.back() - s.azimuth_stamps_us.front()) * 1e-3;
    EXPECT_GT(span_ms, 240.0);
    EXPECT_LT(span_ms, 260.0);
    // The stamps come in bursts (one per network packet, ~8 ms apart: measured 26-27 bursts
    // per scan) but stay within 10 ms of an even spread over the turn (measured <= 6.92 ms).
    int bursts = 1;
    double max_from_linear_ms = 0;
    for (int a = 0; a < s.num_azimuths; ++a) {
      if (a > 0 && s.azimuth_stamps_us[a] - s.azimuth_stamps_us[a - 1] > 1000) ++bursts;
      const double linear = s.azimuth_stamps_us.front() + span_ms * 1e3 * a / (s.num_azimuths - 1);
      max_from_linear_ms =
          std::max(max_from_linear_ms, std::abs(s.azimuth_stamps_us[a] - linear) * 1e-3);
    }
    EXPECT_LT(max_from_linear_ms, 10.0);
    if (k + 1 < d.stamps.size()) {
      EXPECT_LT(s.azimuth_stamps_us.back(), d.stamps[k + 1].stamp_us);
    }

    // Plausible power: 8-bit returns, mostly low, some strong targets (measured max 119..135).
    const auto max_power = *std::max_element(s.power.begin(), s.power.end());
    double mean = 0;
    for (uint8_t v : s.power) mean += v;
    mean /= s.power.size();
    EXPECT_GT(max_power, 60);
    EXPECT_GT(mean, 1.0);
    EXPECT_LT(mean, 60.0);
    std::cout << "[ measured ] " << s.stamp_us << ": encoder " << s.encoder_counts.front() << " .. "
              << s.encoder_counts.back() << ", span " << span_ms << " ms in " << bursts
              << " bursts, max " << max_from_linear_ms << " ms from an even spread, power max "
              << int(max_power) << " mean " << mean << "\n";
  }
}

TEST(OxfordRadar, OdometryHasTenConsecutivePairsMatchingTheScans) {
  const std::string path = radarDir() + "/radar_odometry.csv";
  OGS_REQUIRE_SHARED_FILE(path);
  OGS_REQUIRE_SHARED_FILE(radarDir() + "/radar.timestamps");
  const auto odom = readOxfordRadarOdometry(path);
  ASSERT_TRUE(odom.ok) << odom.error;
  ASSERT_EQ(odom.value.size(), 2249u);  // the whole drive, every line parsed
  // The file is one chain: each row starts where the previous one ended.
  for (size_t i = 0; i + 1 < odom.value.size(); ++i) {
    ASSERT_TRUE(odom.value[i].has_radar_stamps);
    ASSERT_EQ(odom.value[i + 1].destination_radar_stamp_us, odom.value[i].source_radar_stamp_us);
    ASSERT_EQ(odom.value[i + 1].destination_stamp_us, odom.value[i].source_stamp_us);
  }

  const RealScans& d = realScans();
  ASSERT_EQ(d.scans.size(), 11u);
  std::map<int64_t, size_t> index;
  for (size_t k = 0; k < d.scans.size(); ++k) index[d.scans[k].stamp_us] = k;
  int touching = 0;
  std::vector<const OxfordRadarOdometry*> pairs;
  for (const auto& o : odom.value) {
    const bool src = index.count(o.source_radar_stamp_us) > 0;
    const bool dst = index.count(o.destination_radar_stamp_us) > 0;
    touching += src || dst;
    if (src && dst) pairs.push_back(&o);
  }
  EXPECT_EQ(touching, 12);  // README: every one of the 11 scans appears
  ASSERT_EQ(pairs.size(), 10u);
  double path_length = 0, total_yaw = 0;
  for (size_t k = 0; k < pairs.size(); ++k) {
    const OxfordRadarOdometry& o = *pairs[k];
    SCOPED_TRACE("pair " + std::to_string(k));
    // Destination = the earlier scan, source = the next one.
    ASSERT_EQ(o.destination_radar_stamp_us, d.scans[k].stamp_us);
    ASSERT_EQ(o.source_radar_stamp_us, d.scans[k + 1].stamp_us);
    // The odometry's own timestamps are the scans' mid times (first + last azimuth) / 2.
    EXPECT_NEAR(double(o.destination_stamp_us), double(d.scans[k].midStampUs()), 2.0);
    EXPECT_NEAR(double(o.source_stamp_us), double(d.scans[k + 1].midStampUs()), 2.0);

    const double translation = std::hypot(o.x, o.y);
    const double dt = (o.source_radar_stamp_us - o.destination_radar_stamp_us) * 1e-6;
    // Urban driving at ~6-10 m/s, forward (x > 0), a gentle curve; planar (SE(2)) motion.
    EXPECT_GT(o.x, 0.5);
    EXPECT_LT(translation, 5.0);
    EXPECT_LT(translation / dt, 20.0);
    EXPECT_LT(std::abs(o.y), 0.2);
    EXPECT_LT(std::abs(o.yaw), 2.0 * kTwoPi / 360.0);
    EXPECT_LT(std::abs(o.z) + std::abs(o.roll) + std::abs(o.pitch), 1e-5);
    const Eigen::Isometry3d t = o.transform();
    EXPECT_NEAR(t.translation().x(), o.x, 1e-12);
    EXPECT_NEAR(std::atan2(t.linear()(1, 0), t.linear()(0, 0)), o.yaw, 1e-12);
    path_length += translation;
    total_yaw += o.yaw;
    std::cout << "[ measured ] pair " << k << "->" << k + 1 << ": x " << o.x << " y " << o.y
              << " yaw " << o.yaw * 360.0 / kTwoPi << " deg, " << translation << " m in "
              << dt * 1e3 << " ms (" << translation / dt << " m/s)\n";
  }
  std::cout << "[ measured ] 10 pairs: " << path_length << " m, yaw sum "
            << total_yaw * 360.0 / kTwoPi << " deg\n";
  EXPECT_GT(path_length, 10.0);
  EXPECT_LT(path_length, 40.0);
}

// ------------------------------------------------------------------------------------------------
// Synthetic images and error paths
// ------------------------------------------------------------------------------------------------

TEST(OxfordRadar, SyntheticScanRoundTripsExactly) {
  const std::string path = tempPath("synthetic.png");
  const int64_t t0 = 1547131046353776;
  ASSERT_TRUE(cv::imwrite(path, syntheticScan(400, 3768, t0)));
  const auto r = readOxfordRadarPng(path);
  ASSERT_TRUE(r.ok) << r.error;
  const OxfordRadarScan& s = r.value;
  EXPECT_EQ(s.stamp_us, t0);
  EXPECT_EQ(s.azimuth_stamps_us[399], t0 + 600 * 399);
  EXPECT_EQ(s.midStampUs(), t0 + 300 * 399);
  EXPECT_EQ(s.encoder_counts[0], 13);
  EXPECT_EQ(s.encoder_counts[399], 5599);
  EXPECT_NEAR(s.azimuths[1], kTwoPi * 27 / 5600.0, 1e-15);
  EXPECT_EQ(s.valid[4], 1);
  EXPECT_EQ(s.valid[5], 0);
  EXPECT_EQ(s.powerAt(7, 100), (7 + 100) % 251);
  EXPECT_EQ(s.row(399)[3767], (399 + 3767) % 251);

  // Another range resolution and any size when the layout does not fix it.
  OxfordRadarLayout any;
  any.expected_azimuths = 0;
  any.expected_bins = 0;
  any.range_resolution = 0.0438;
  ASSERT_TRUE(cv::imwrite(path, syntheticScan(8, 20, t0)));
  const auto small = readOxfordRadarPng(path, any);
  ASSERT_TRUE(small.ok) << small.error;
  EXPECT_EQ(small.value.num_azimuths, 8);
  EXPECT_EQ(small.value.num_bins, 20);
  EXPECT_DOUBLE_EQ(small.value.binRange(1), 1.5 * 0.0438);
  std::remove(path.c_str());
}

TEST(OxfordRadar, PngErrorsNameTheFileAndTheReason) {
  // Missing.
  auto r = readOxfordRadarPng("/nonexistent/radar/1.png");
  EXPECT_FALSE(r.ok);
  EXPECT_TRUE(contains(r.error, "'/nonexistent/radar/1.png'")) << r.error;
  EXPECT_TRUE(contains(r.error, "missing")) << r.error;

  // Not a PNG.
  const std::string text = tempPath("text.png");
  writeText(text, "timestamp,azimuth\n1,2\n");
  r = readOxfordRadarPng(text);
  EXPECT_FALSE(r.ok);
  EXPECT_TRUE(contains(r.error, text)) << r.error;
  EXPECT_TRUE(contains(r.error, "not a PNG")) << r.error;
  writeText(text, "");
  r = readOxfordRadarPng(text);
  EXPECT_TRUE(contains(r.error, "not a PNG")) << r.error;
  std::remove(text.c_str());

  // Wrong height, wrong width, colour, 16 bit.
  const std::string img = tempPath("wrong.png");
  ASSERT_TRUE(cv::imwrite(img, syntheticScan(399, 3768, 1)));
  r = readOxfordRadarPng(img);
  EXPECT_FALSE(r.ok);
  EXPECT_TRUE(contains(r.error, img)) << r.error;
  EXPECT_TRUE(contains(r.error, "wrong height: 399 rows")) << r.error;
  ASSERT_TRUE(cv::imwrite(img, syntheticScan(400, 100, 1)));
  r = readOxfordRadarPng(img);
  EXPECT_TRUE(contains(r.error, "wrong width: 111 columns")) << r.error;
  EXPECT_TRUE(contains(r.error, "3779")) << r.error;
  OxfordRadarLayout any;
  any.expected_bins = 0;
  ASSERT_TRUE(cv::imwrite(img, cv::Mat(400, 11, CV_8UC1, cv::Scalar(255))));
  r = readOxfordRadarPng(img, any);
  EXPECT_TRUE(contains(r.error, "no room for power bins")) << r.error;
  ASSERT_TRUE(cv::imwrite(img, cv::Mat(400, 3779, CV_8UC3, cv::Scalar(1, 2, 3))));
  r = readOxfordRadarPng(img);
  EXPECT_TRUE(contains(r.error, "not 8-bit grayscale")) << r.error;
  ASSERT_TRUE(cv::imwrite(img, cv::Mat(400, 3779, CV_16UC1, cv::Scalar(1000))));
  r = readOxfordRadarPng(img);
  EXPECT_TRUE(contains(r.error, "not 8-bit grayscale (bit depth 16")) << r.error;

  // An encoder count outside the turn.
  cv::Mat bad = syntheticScan(400, 3768, 1);
  bad.at<uint8_t>(17, 8) = 0xe0;  // 0x15e0 = 5600
  bad.at<uint8_t>(17, 9) = 0x15;
  ASSERT_TRUE(cv::imwrite(img, bad));
  r = readOxfordRadarPng(img);
  EXPECT_FALSE(r.ok);
  EXPECT_TRUE(contains(r.error, img)) << r.error;
  EXPECT_TRUE(contains(r.error, "row 17: azimuth encoder count 5600")) << r.error;
  std::remove(img.c_str());
}

TEST(OxfordRadar, TruncatedRealPngIsAnErrorNotACrash) {
  const std::string real = radarDir() + "/radar/1547131046353776.png";
  OGS_REQUIRE_SHARED_FILE(real);
  std::ifstream in(real, std::ios::binary);
  const std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  ASSERT_GT(bytes.size(), 100000u);
  const std::string cut = tempPath("truncated.png");
  writeText(cut, bytes.substr(0, bytes.size() / 2));
  auto r = readOxfordRadarPng(cut);
  EXPECT_FALSE(r.ok);
  EXPECT_TRUE(contains(r.error, cut)) << r.error;
  EXPECT_TRUE(contains(r.error, "truncated PNG")) << r.error;
  std::cout << "[ measured ] " << r.error << "\n";

  // Cut exactly at a chunk boundary (the IEND chunk dropped): still truncated.
  writeText(cut, bytes.substr(0, bytes.size() - 12));
  r = readOxfordRadarPng(cut);
  EXPECT_TRUE(contains(r.error, "truncated PNG")) << r.error;

  // Intact structure but corrupt image data: the decoder's failure is an error too.
  std::string corrupt = bytes;
  for (size_t i = bytes.size() / 3; i < bytes.size() / 3 + 2000; ++i) corrupt[i] ^= 0x5a;
  writeText(cut, corrupt);
  r = readOxfordRadarPng(cut);
  EXPECT_FALSE(r.ok);
  EXPECT_TRUE(contains(r.error, cut)) << r.error;
  std::remove(cut.c_str());
}

TEST(OxfordRadar, TimestampErrorsNameTheFileAndLine) {
  auto r = readOxfordRadarTimestamps("/nonexistent/radar.timestamps");
  EXPECT_FALSE(r.ok);
  EXPECT_TRUE(contains(r.error, "/nonexistent/radar.timestamps")) << r.error;
  EXPECT_TRUE(contains(r.error, "missing")) << r.error;

  const std::string path = tempPath("radar.timestamps");
  writeText(path, "1547131046353776 1\n\n1547131046606586 1\n1547131046858560 x\n");
  r = readOxfordRadarTimestamps(path);
  EXPECT_FALSE(r.ok);
  EXPECT_TRUE(contains(r.error, path + "' line 4")) << r.error;
  writeText(path, "1547131046353776 1\n1547131046606586\n");
  r = readOxfordRadarTimestamps(path);
  EXPECT_TRUE(contains(r.error, "line 2")) << r.error;
  writeText(path, "1547131046606586 1\n1547131046353776 1\n");
  r = readOxfordRadarTimestamps(path);
  EXPECT_TRUE(contains(r.error, "line 2")) << r.error;
  EXPECT_TRUE(contains(r.error, "not after the previous")) << r.error;
  writeText(path, "1547131046353776 1\r\n1547131046606586 2\r\n");  // CRLF is fine
  r = readOxfordRadarTimestamps(path);
  ASSERT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.value.size(), 2u);
  EXPECT_EQ(r.value[1].chunk, 2);
  std::remove(path.c_str());
}

TEST(OxfordRadar, OdometryErrorsNameTheFileAndLine) {
  auto r = readOxfordRadarOdometry("/nonexistent/radar_odometry.csv");
  EXPECT_FALSE(r.ok);
  EXPECT_TRUE(contains(r.error, "/nonexistent/radar_odometry.csv")) << r.error;

  const std::string header10 =
      "source_timestamp,destination_timestamp,x,y,z,roll,pitch,yaw,source_radar_timestamp,"
      "destination_radar_timestamp\n";
  const std::string good =
      "1547131046480034,1547131046227224,2.478813,-0.013214,-0.000000,"
      "-0.000000,-0.000000,-0.012238,1547131046353776,1547131046100947\n";
  const std::string path = tempPath("radar_odometry.csv");

  writeText(path, header10 + good + good +
                      "1547131046480034,1547131046227224,2.4,oops,0,0,0,0,"
                      "1547131046353776,1547131046100947\n");
  r = readOxfordRadarOdometry(path);
  EXPECT_FALSE(r.ok);
  EXPECT_TRUE(contains(r.error, path + "' line 4")) << r.error;
  EXPECT_TRUE(contains(r.error, "not a number")) << r.error;

  writeText(path, header10 + "1547131046480034,1547131046227224,2.4,0,0,0,0,0\n");
  r = readOxfordRadarOdometry(path);
  EXPECT_TRUE(contains(r.error, "line 2: expected 10 columns, got 8")) << r.error;

  writeText(path, header10 + good + good.substr(0, good.size() / 2) + "\n");
  r = readOxfordRadarOdometry(path);
  EXPECT_TRUE(contains(r.error, "line 3")) << r.error;

  writeText(path, good + good);  // no header
  r = readOxfordRadarOdometry(path);
  EXPECT_TRUE(contains(r.error, "line 1: expected the header")) << r.error;

  writeText(path, "");
  r = readOxfordRadarOdometry(path);
  EXPECT_TRUE(contains(r.error, "empty")) << r.error;

  writeText(path, header10 + good +
                      "1547131046480034,1547131046227224,2.4,0,nan,0,0,0,"
                      "1547131046353776,1547131046100947\n");
  r = readOxfordRadarOdometry(path);
  EXPECT_TRUE(contains(r.error, "line 3: a value is not a number")) << r.error;

  // The 8-column variant (no radar timestamps) and CRLF line ends.
  writeText(path,
            "source_timestamp,destination_timestamp,x,y,z,roll,pitch,yaw\r\n"
            "2,1,1.5,-0.25,0,0,0,0.1\r\n");
  r = readOxfordRadarOdometry(path);
  ASSERT_TRUE(r.ok) << r.error;
  ASSERT_EQ(r.value.size(), 1u);
  EXPECT_FALSE(r.value[0].has_radar_stamps);
  EXPECT_EQ(r.value[0].source_stamp_us, 2);
  EXPECT_DOUBLE_EQ(r.value[0].y, -0.25);
  EXPECT_DOUBLE_EQ(r.value[0].yaw, 0.1);
  std::remove(path.c_str());
}
