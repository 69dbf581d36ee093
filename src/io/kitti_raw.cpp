#include "osm_graph_slam/io/kitti_raw.h"

#include "osm_graph_slam/io/trajectory_io.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>

namespace fs = std::filesystem;

namespace osm_graph_slam {
namespace {

bool fail(std::string* error, const std::string& msg) {
  if (error) *error = msg;
  return false;
}

/// Parses every whitespace-separated number of text; false if any token is not a number.
bool parseNumbers(const std::string& text, std::vector<double>& values) {
  std::istringstream in(text);
  std::string token;
  values.clear();
  while (in >> token) {
    char* end = nullptr;
    const double v = std::strtod(token.c_str(), &end);
    if (end == token.c_str() || *end != '\0') return false;
    values.push_back(v);
  }
  return true;
}

std::string formatDouble(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.17g", v);
  return buf;
}

/// Rigid transform from a row-major 3x4 matrix.
Eigen::Isometry3d fromRowMajor3x4(const double* m) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) T.linear()(r, c) = m[4 * r + c];
    T.translation()(r) = m[4 * r + 3];
  }
  return T;
}

std::string toRowMajor3x4(const Eigen::Isometry3d& T) {
  std::ostringstream out;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c) {
      if (r || c) out << ' ';
      out << formatDouble(c < 3 ? T.linear()(r, c) : T.translation()(r));
    }
  }
  return out.str();
}

std::string firstExisting(const std::vector<fs::path>& candidates) {
  for (const auto& c : candidates) {
    if (fs::exists(c)) return c.string();
  }
  return candidates.front().string();
}

}  // namespace

std::array<double, OxtsRecord::kNumFields> OxtsRecord::toArray() const {
  return {lat,
          lon,
          alt,
          roll,
          pitch,
          yaw,
          vn,
          ve,
          vf,
          vl,
          vu,
          ax,
          ay,
          az,
          af,
          al,
          au,
          wx,
          wy,
          wz,
          wf,
          wl,
          wu,
          pos_accuracy,
          vel_accuracy,
          double(navstat),
          double(numsats),
          double(posmode),
          double(velmode),
          double(orimode)};
}

bool OxtsRecord::hasGnssFix() const {
  return std::isfinite(lat) && std::isfinite(lon) && std::isfinite(alt) &&
         !(pos_accuracy >= kOxtsNoFixAccuracy);
}

OxtsRecord OxtsRecord::fromArray(const std::array<double, kNumFields>& v) {
  OxtsRecord r;
  double* dst[] = {&r.lat, &r.lon, &r.alt,          &r.roll,        &r.pitch, &r.yaw, &r.vn,
                   &r.ve,  &r.vf,  &r.vl,           &r.vu,          &r.ax,    &r.ay,  &r.az,
                   &r.af,  &r.al,  &r.au,           &r.wx,          &r.wy,    &r.wz,  &r.wf,
                   &r.wl,  &r.wu,  &r.pos_accuracy, &r.vel_accuracy};
  for (int i = 0; i < 25; ++i) *dst[i] = v[i];
  r.navstat = static_cast<int>(v[25]);
  r.numsats = static_cast<int>(v[26]);
  r.posmode = static_cast<int>(v[27]);
  r.velmode = static_cast<int>(v[28]);
  r.orimode = static_cast<int>(v[29]);
  return r;
}

std::vector<std::string> listFiles(const std::string& dir, const std::string& ext) {
  std::vector<std::string> files;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    if (entry.is_regular_file() && entry.path().extension() == ext) {
      files.push_back(entry.path().string());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

bool parseKittiTimestamp(const std::string& text, StampNs& stamp) {
  int Y, M, D, h, m, s, consumed = 0;
  if (std::sscanf(text.c_str(), "%d-%d-%d %d:%d:%d%n", &Y, &M, &D, &h, &m, &s, &consumed) != 6) {
    return false;
  }
  // Years outside [1970, 2261] are refused: ROS stamps cannot be negative and nanoseconds since
  // 1970 overflow int64 in 2262 (a fuzzed year of 10^11 was signed overflow, issue 22).
  if (Y < 1970 || Y > 2261) return false;
  if (M < 1 || M > 12 || D < 1 || D > 31 || h < 0 || h > 23 || m < 0 || m > 59 || s < 0 || s > 60)
    return false;
  int64_t frac_ns = 0;
  const char* p = text.c_str() + consumed;
  if (*p == '.') {
    ++p;
    int digits = 0;
    while (*p >= '0' && *p <= '9') {
      if (digits < 9) frac_ns = frac_ns * 10 + (*p - '0');
      ++digits;
      ++p;
    }
    if (digits == 0) return false;
    for (int d = digits; d < 9; ++d) frac_ns *= 10;
  }
  while (*p == ' ' || *p == '\r' || *p == '\t') ++p;
  if (*p != '\0') return false;
  std::tm tm{};
  tm.tm_year = Y - 1900;
  tm.tm_mon = M - 1;
  tm.tm_mday = D;
  tm.tm_hour = h;
  tm.tm_min = m;
  tm.tm_sec = s;
  const time_t secs = timegm(&tm);
  stamp = static_cast<StampNs>(secs) * 1000000000LL + frac_ns;
  return true;
}

std::string formatKittiTimestamp(StampNs stamp) {
  const time_t secs = static_cast<time_t>(stamp / 1000000000LL);
  const int64_t ns = stamp % 1000000000LL;
  std::tm tm{};
  gmtime_r(&secs, &tm);
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%04d-%02d-%02d %02d:%02d:%02d.%09lld", tm.tm_year + 1900,
                tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec,
                static_cast<long long>(ns));
  return buf;
}

bool readKittiTimestamps(const std::string& path, std::vector<StampNs>& stamps,
                         std::string* error) {
  std::ifstream in(path);
  if (!in) return fail(error, "cannot open timestamps file '" + path + "'");
  stamps.clear();
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    StampNs s;
    if (!parseKittiTimestamp(line, s)) {
      return fail(error, "malformed timestamp in '" + path + "' line " + std::to_string(line_no) +
                             ": '" + line + "'");
    }
    stamps.push_back(s);
  }
  return true;
}

bool writeKittiTimestamps(const std::string& path, const std::vector<StampNs>& stamps,
                          std::string* error) {
  std::string text;
  for (StampNs s : stamps) text += formatKittiTimestamp(s) + "\n";
  return writeFileAtomically(path, text, error);
}

bool readOxtsFile(const std::string& path, OxtsRecord& record, std::string* error) {
  std::ifstream in(path);
  if (!in) return fail(error, "cannot open OXTS file '" + path + "'");
  std::stringstream buffer;
  buffer << in.rdbuf();
  std::vector<double> values;
  if (!parseNumbers(buffer.str(), values) || values.size() != OxtsRecord::kNumFields) {
    return fail(error, "malformed OXTS file '" + path + "': expected 30 numbers, found " +
                           std::to_string(values.size()) + " valid ones");
  }
  std::array<double, OxtsRecord::kNumFields> a;
  std::copy(values.begin(), values.end(), a.begin());
  record = OxtsRecord::fromArray(a);
  return true;
}

bool writeOxtsFile(const std::string& path, const OxtsRecord& record, std::string* error) {
  const auto a = record.toArray();
  std::ostringstream out;
  for (int i = 0; i < OxtsRecord::kNumFields; ++i) {
    if (i) out << ' ';
    if (i >= 25) {
      out << static_cast<int>(a[i]);
    } else {
      out << formatDouble(a[i]);
    }
  }
  out << '\n';
  return writeFileAtomically(path, out.str(), error);
}

bool readKittiRigidCalib(const std::string& path, Eigen::Isometry3d& transform,
                         std::string* error) {
  std::ifstream in(path);
  if (!in) return fail(error, "cannot open calibration file '" + path + "'");
  std::vector<double> R, T;
  std::string line;
  while (std::getline(in, line)) {
    const auto colon = line.find(':');
    if (colon == std::string::npos) continue;
    const std::string key = line.substr(0, colon);
    std::vector<double> values;
    if (key == "R" || key == "T") {
      if (!parseNumbers(line.substr(colon + 1), values)) {
        return fail(error, "malformed calibration file '" + path + "': bad number in " + key);
      }
      (key == "R" ? R : T) = values;
    }
  }
  if (R.size() != 9 || T.size() != 3) {
    return fail(error, "malformed calibration file '" + path +
                           "': expected 'R:' with 9 and 'T:' with 3 numbers");
  }
  transform = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) transform.linear()(r, c) = R[3 * r + c];
    transform.translation()(r) = T[r];
  }
  return true;
}

bool readKittiTrackingCalib(const std::string& path, const std::string& key,
                            Eigen::Isometry3d& transform, std::string* error) {
  std::ifstream in(path);
  if (!in) return fail(error, "cannot open calibration file '" + path + "'");
  std::string line;
  while (std::getline(in, line)) {
    const auto colon = line.find(':');
    if (colon == std::string::npos || line.substr(0, colon) != key) continue;
    std::vector<double> v;
    if (!parseNumbers(line.substr(colon + 1), v) || v.size() != 12)
      return fail(error, "malformed calibration file '" + path + "': '" + key +
                             "' needs 12 numbers (row-major 3x4)");
    transform = Eigen::Isometry3d::Identity();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) transform.linear()(r, c) = v[4 * r + c];
      transform.translation()(r) = v[4 * r + 3];
    }
    return true;
  }
  return fail(error, "calibration file '" + path + "' has no '" + key + ":' entry");
}

bool writeKittiRigidCalib(const std::string& path, const Eigen::Isometry3d& transform,
                          std::string* error) {
  std::ostringstream out;
  out << "calib_time: 01-Jan-2020 00:00:00\nR:";
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out << ' ' << formatDouble(transform.linear()(r, c));
  }
  out << "\nT:";
  for (int r = 0; r < 3; ++r) out << ' ' << formatDouble(transform.translation()(r));
  out << '\n';
  return writeFileAtomically(path, out.str(), error);
}

bool readFloat32Records(const std::string& path, std::vector<float>& values, std::string* error) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) return fail(error, "cannot open scan '" + path + "'");
  const std::streamsize bytes = in.tellg();
  if (bytes < 0 || bytes % 16 != 0) {
    return fail(error, "scan '" + path + "' has " + std::to_string(bytes) +
                           " bytes, not a multiple of 16 (x, y, z, intensity float32)");
  }
  values.resize(static_cast<size_t>(bytes) / sizeof(float));
  in.seekg(0);
  if (bytes > 0 && !in.read(reinterpret_cast<char*>(values.data()), bytes)) {
    return fail(error, "short read on scan '" + path + "'");
  }
  return true;
}

bool readImuToVeloCalib(const std::string& path, Eigen::Isometry3d& T_velo_imu,
                        std::string* error) {
  std::string rigid_error, tracking_error;
  if (readKittiRigidCalib(path, T_velo_imu, &rigid_error)) return true;
  if (readKittiTrackingCalib(path, "Tr_imu_to_velo", T_velo_imu, &tracking_error)) return true;
  if (!fs::exists(path)) return fail(error, "cannot open calibration file '" + path + "'");
  return fail(error, "calibration file '" + path +
                         "' is neither calib_imu_to_velo.txt (R:, T:) nor a tracking-layout file "
                         "with Tr_imu_to_velo (" +
                         rigid_error + "; " + tracking_error + ")");
}

bool readScanFolderOrigin(const std::string& oxts_path, const std::string& origin_text,
                          ScanFolderOrigin& origin, std::string* error) {
  if (oxts_path.empty() == origin_text.empty())
    return fail(error,
                "--scans needs exactly one of --origin-oxts FILE and --origin "
                "LAT,LON,ALT[,YAW_DEG]");
  origin = ScanFolderOrigin();
  if (!oxts_path.empty()) {
    OxtsRecord r;
    if (!readOxtsFile(oxts_path, r, error)) return false;
    if (!r.hasGnssFix())
      return fail(error, "OXTS file '" + oxts_path + "' has no GNSS fix (pos_accuracy " +
                             formatDouble(r.pos_accuracy) + " m): no georeference");
    origin.lat = r.lat;
    origin.lon = r.lon;
    origin.alt = r.alt;
    origin.yaw = r.yaw;
    origin.oxts = r;
    return true;
  }
  // LAT,LON,ALT[,YAW_DEG]: each field one number, nothing else.
  std::vector<double> v;
  std::stringstream in(origin_text);
  std::string field;
  bool ok = true;
  while (ok && std::getline(in, field, ',')) {
    char* end = nullptr;
    const double x = std::strtod(field.c_str(), &end);
    ok = end != field.c_str() && *end == '\0' && std::isfinite(x);
    v.push_back(x);
  }
  if (!ok || v.size() < 3 || v.size() > 4 || origin_text.back() == ',' || std::abs(v[0]) > 90.0 ||
      std::abs(v[1]) > 180.0)
    return fail(error,
                "--origin takes LAT,LON,ALT[,YAW_DEG] (degrees; yaw: ENU, 0 = east, "
                "counter-clockwise), not '" +
                    origin_text + "'");
  origin.lat = v[0];
  origin.lon = v[1];
  origin.alt = v[2];
  if (v.size() == 4) origin.yaw = v[3] * M_PI / 180.0;
  return true;
}

bool openKittiRawDrive(const std::string& drive_dir, const std::string& calib_dir,
                       KittiRawDrive& drive, std::string* error) {
  const fs::path root(drive_dir);
  if (!fs::is_directory(root)) return fail(error, "KITTI raw drive '" + drive_dir + "' is missing");
  drive = KittiRawDrive();
  drive.drive_dir = drive_dir;
  const fs::path velo = root / "velodyne_points";
  const fs::path oxts = root / "oxts";
  if (!fs::is_directory(velo / "data")) {
    return fail(error, "missing folder '" + (velo / "data").string() + "'");
  }
  if (!fs::is_directory(oxts / "data")) {
    return fail(error, "missing folder '" + (oxts / "data").string() + "'");
  }
  drive.scan_files = listFiles((velo / "data").string(), ".bin");
  drive.oxts_files = listFiles((oxts / "data").string(), ".txt");
  if (drive.scan_files.empty()) {
    return fail(error, "no .bin scans in '" + (velo / "data").string() + "'");
  }
  if (!readKittiTimestamps((velo / "timestamps.txt").string(), drive.scan_stamps, error)) {
    return false;
  }
  if (!readKittiTimestamps((oxts / "timestamps.txt").string(), drive.oxts_stamps, error)) {
    return false;
  }
  if (drive.scan_stamps.size() != drive.scan_files.size()) {
    return fail(error, "'" + (velo / "timestamps.txt").string() + "' has " +
                           std::to_string(drive.scan_stamps.size()) + " stamps for " +
                           std::to_string(drive.scan_files.size()) + " scans");
  }
  if (drive.oxts_stamps.size() != drive.oxts_files.size()) {
    return fail(error, "'" + (oxts / "timestamps.txt").string() + "' has " +
                           std::to_string(drive.oxts_stamps.size()) + " stamps for " +
                           std::to_string(drive.oxts_files.size()) + " OXTS files");
  }
  const fs::path truth = root / "oxts_true";
  if (fs::is_directory(truth / "data")) {
    drive.truth_oxts_files = listFiles((truth / "data").string(), ".txt");
    if (!readKittiTimestamps((truth / "timestamps.txt").string(), drive.truth_oxts_stamps, error)) {
      return false;
    }
    if (drive.truth_oxts_stamps.size() != drive.truth_oxts_files.size()) {
      return fail(error, "'" + (truth / "timestamps.txt").string() + "' has " +
                             std::to_string(drive.truth_oxts_stamps.size()) + " stamps for " +
                             std::to_string(drive.truth_oxts_files.size()) + " OXTS files");
    }
  }
  std::vector<fs::path> dirs;
  if (!calib_dir.empty()) {
    dirs = {fs::path(calib_dir)};
  } else {
    dirs = {root, fs::absolute(root).lexically_normal().parent_path()};
    if (dirs[1].filename().empty()) dirs[1] = dirs[1].parent_path().parent_path();
  }
  auto calibPath = [&](const std::string& name) {
    std::vector<fs::path> c;
    for (const auto& d : dirs) c.push_back(d / name);
    return firstExisting(c);
  };
  if (!readKittiRigidCalib(calibPath("calib_imu_to_velo.txt"), drive.T_velo_imu, error)) {
    return false;
  }
  return readKittiRigidCalib(calibPath("calib_velo_to_cam.txt"), drive.T_cam_velo, error);
}

std::vector<Eigen::Isometry3d> KittiOdometrySequence::lidarPoses() const {
  std::vector<Eigen::Isometry3d> out;
  out.reserve(camera_poses.size());
  const Eigen::Isometry3d Tr_inv = Tr.inverse();
  for (const auto& P : camera_poses) out.push_back(Tr_inv * P * Tr);
  return out;
}

bool openKittiOdometrySequence(const std::string& sequence_dir, const std::string& poses_path,
                               KittiOdometrySequence& seq, std::string* error) {
  const fs::path root(sequence_dir);
  if (!fs::is_directory(root)) {
    return fail(error, "KITTI odometry sequence '" + sequence_dir + "' is missing");
  }
  seq = KittiOdometrySequence();
  seq.sequence_dir = sequence_dir;
  if (!fs::is_directory(root / "velodyne")) {
    return fail(error, "missing folder '" + (root / "velodyne").string() + "'");
  }
  seq.scan_files = listFiles((root / "velodyne").string(), ".bin");
  if (seq.scan_files.empty()) {
    return fail(error, "no .bin scans in '" + (root / "velodyne").string() + "'");
  }
  const std::string times_path = (root / "times.txt").string();
  std::ifstream times(times_path);
  if (!times) return fail(error, "cannot open '" + times_path + "'");
  std::string line;
  int line_no = 0;
  while (std::getline(times, line)) {
    ++line_no;
    std::vector<double> v;
    if (!parseNumbers(line, v) || v.size() > 1) {
      return fail(error, "malformed '" + times_path + "' line " + std::to_string(line_no));
    }
    if (!v.empty()) seq.times.push_back(v[0]);
  }
  if (seq.times.size() != seq.scan_files.size()) {
    return fail(error, "'" + times_path + "' has " + std::to_string(seq.times.size()) +
                           " times for " + std::to_string(seq.scan_files.size()) + " scans");
  }
  const std::string calib_path = (root / "calib.txt").string();
  std::ifstream calib(calib_path);
  if (!calib) return fail(error, "cannot open '" + calib_path + "'");
  bool have_tr = false;
  while (std::getline(calib, line)) {
    if (line.rfind("Tr:", 0) != 0) continue;
    std::vector<double> v;
    if (!parseNumbers(line.substr(3), v) || v.size() != 12) {
      return fail(error, "malformed 'Tr:' line in '" + calib_path + "' (expected 12 numbers)");
    }
    seq.Tr = fromRowMajor3x4(v.data());
    have_tr = true;
  }
  if (!have_tr) return fail(error, "no 'Tr:' line in '" + calib_path + "'");

  std::string poses = poses_path;
  if (poses.empty()) {
    const fs::path abs = fs::absolute(root).lexically_normal();
    const fs::path seq_name =
        abs.filename().empty() ? abs.parent_path().filename() : abs.filename();
    const fs::path base = abs.filename().empty() ? abs.parent_path() : abs;
    const fs::path guess =
        base.parent_path().parent_path() / "poses" / (seq_name.string() + ".txt");
    if (fs::exists(guess)) poses = guess.string();
  }
  if (!poses.empty()) {
    if (!readKittiPoses(poses, seq.camera_poses, error)) return false;
    if (seq.camera_poses.size() != seq.scan_files.size()) {
      return fail(error, "poses file '" + poses + "' has " +
                             std::to_string(seq.camera_poses.size()) + " poses for " +
                             std::to_string(seq.scan_files.size()) + " scans");
    }
  }
  return true;
}

bool readKittiPoses(const std::string& path, std::vector<Eigen::Isometry3d>& poses,
                    std::string* error) {
  std::ifstream in(path);
  if (!in) return fail(error, "cannot open poses file '" + path + "'");
  poses.clear();
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    std::vector<double> v;
    if (!parseNumbers(line, v)) {
      return fail(error, "malformed poses file '" + path + "' line " + std::to_string(line_no));
    }
    if (v.empty()) continue;
    if (v.size() != 12) {
      return fail(error, "malformed poses file '" + path + "' line " + std::to_string(line_no) +
                             ": expected 12 numbers, found " + std::to_string(v.size()));
    }
    poses.push_back(fromRowMajor3x4(v.data()));
  }
  return true;
}

bool writeKittiPoses(const std::string& path, const std::vector<Eigen::Isometry3d>& poses,
                     std::string* error) {
  std::string text;
  for (const auto& T : poses) text += toRowMajor3x4(T) + "\n";
  return writeFileAtomically(path, text, error);
}

}  // namespace osm_graph_slam
