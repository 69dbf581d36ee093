#include "osm_graph_slam/sim/radar_sim.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>

#include "osm_graph_slam/sim/sim_random.h"

namespace fs = std::filesystem;

namespace osm_graph_slam::sim {
namespace {

/// Body angular rate of a rotation path at t (central difference, h = 5 ms).
Eigen::Vector3d bodyRate(const std::function<Eigen::Matrix3d(double)>& R, double t) {
  const double h = 0.005;
  const Eigen::AngleAxisd d(R(t - h).transpose() * R(t + h));
  return d.axis() * d.angle() / (2 * h);
}

constexpr uint64_t kImuRowsTag = 0x696d753130304856ULL;  // "imu100HV"
constexpr int kImuRowsPerEpoch = 10;                     // 100 Hz, as MulRan's Xsens

/// Radar reflectivity relative to the LiDAR one: metal (cars, poles) reflects far more at
/// 77 GHz, foliage less.
double radarGain(SimLabel label) {
  switch (label) {
    case SimLabel::kCar:
    case SimLabel::kMoving:
      return 2.5;
    case SimLabel::kPole:
      return 2.0;
    case SimLabel::kFence:
      return 1.5;
    case SimLabel::kTree:
      return 0.7;
    case SimLabel::kGround:
      return 0.5;
    default:
      return 1.0;
  }
}

/// Approximately normal noise from four 16-bit uniforms of one draw (Irwin-Hall, fast and
/// deterministic; the floor needs 1.3 million values per sweep).
double cheapGaussian(SimRng& rng) {
  const uint64_t x = rng.next();
  const double s = double(x & 0xffff) + double((x >> 16) & 0xffff) + double((x >> 32) & 0xffff) +
                   double(x >> 48);
  return (s / 65536.0 - 2.0) * 1.7320508075688772;  // variance of the sum of 4 U(0,1) = 1/3
}

/// Adds a return of peak power at range r to the row (max in the power domain).
void addReturn(std::vector<float>& row, double r, double peak, double resolution,
               double lobe_sigma) {
  if (peak <= 0.0) return;
  const int centre = int(std::floor(r / resolution));
  const int span = int(std::ceil(3.0 * lobe_sigma / resolution));
  for (int b = std::max(0, centre - span); b <= std::min(int(row.size()) - 1, centre + span); ++b) {
    const double d = ((b + 0.5) * resolution - r) / lobe_sigma;
    const double v = peak - 6.0 * d * d;
    if (v > row[size_t(b)]) row[size_t(b)] = float(v);
  }
}

bool failWith(std::string* error, const std::string& message) {
  if (error) *error = message;
  return false;
}

}  // namespace

size_t RadarSimulator::numScans() const {
  const double duration = sim_.trajectory().duration() - model_.rotation_period;
  return duration <= 0.0 ? 0 : size_t(std::floor(duration / model_.rotation_period)) + 1;
}

Eigen::Isometry3d RadarSimulator::radarPose(double t) const {
  Eigen::Isometry3d mount = Eigen::Isometry3d::Identity();
  mount.translation().z() = model_.mount_height;
  return sim_.basePose(t) * mount;
}

Eigen::Vector3d RadarSimulator::radarVelocity(double t) const {
  const double h = 1e-3;
  const Eigen::Isometry3d pose = radarPose(t);
  const Eigen::Vector3d world_v =
      (radarPose(t + h).translation() - radarPose(t - h).translation()) / (2 * h);
  return pose.linear().transpose() * world_v;
}

radar::RadarPolarScan RadarSimulator::simulate(size_t k, size_t* hits) const {
  const NavtechModel& m = model_;
  radar::RadarPolarScan scan;
  scan.num_azimuths = m.azimuths;
  scan.num_bins = m.bins;
  scan.range_resolution = m.range_resolution;
  scan.stamp = sweepStart(k);
  scan.azimuths.resize(size_t(m.azimuths));
  scan.times.resize(size_t(m.azimuths));
  scan.power.resize(size_t(m.azimuths) * m.bins);
  const World& world = sim_.scene().world;
  const std::vector<Primitive> moving = world.movingSnapshot(scan.stamp);
  const double max_range = m.bins * m.range_resolution;
  SimRng noise_rng(hashCombine(seed_, hashCombine(0x7261646172ULL, k)));  // "radar"
  SimRng ray_rng(hashCombine(seed_, hashCombine(0x7261797321ULL, k)));
  std::vector<float> row(size_t(m.bins));
  size_t placed = 0;
  for (int a = 0; a < m.azimuths; ++a) {
    const double theta = 2.0 * M_PI * a / m.azimuths;
    const double t = scan.stamp + m.rotation_period * a / m.azimuths;
    scan.azimuths[size_t(a)] = theta;
    scan.times[size_t(a)] = t;
    const double t_pose = m.motion_skew ? t : scan.stamp;
    const Eigen::Isometry3d pose = radarPose(t_pose);
    const Eigen::Vector3d v = radarVelocity(t_pose);
    for (float& p : row) p = float(m.noise_mean + m.noise_sigma * cheapGaussian(noise_rng));
    for (int i = 0; i < m.rays_across; ++i) {
      const double offset =
          m.rays_across > 1 ? (double(i) / (m.rays_across - 1) - 0.5) * m.beam_width_deg : 0.0;
      const double az = theta + offset * M_PI / 180.0;
      // Navtech azimuths turn clockwise seen from above: x forward, y left.
      const Eigen::Vector2d u(std::cos(az), -std::sin(az));
      for (double elevation_deg : m.elevations_deg) {
        const double el = elevation_deg * M_PI / 180.0;
        const Eigen::Vector3d dir_sensor(u.x() * std::cos(el), u.y() * std::cos(el), std::sin(el));
        RayHit hit;
        if (!world.castRay(pose.translation(), pose.linear() * dir_sensor, max_range, moving, hit))
          continue;
        const double strength = std::max(1e-4, double(hit.reflectivity) * radarGain(hit.label) *
                                                   std::max(hit.cos_incidence, 0.1));
        const double peak = m.peak_gain + m.reflectivity_db * std::log10(strength) -
                            m.range_db * std::log10(std::max(hit.range, 1.0) / 10.0) +
                            m.speckle_sigma * cheapGaussian(ray_rng);
        // Eq. 7.9's distortion: a target the sensor closes in on appears nearer by beta v.u.
        const double measured = hit.range - m.doppler_beta * v.head<2>().dot(u);
        addReturn(row, measured, peak, m.range_resolution, m.lobe_sigma);
        ++placed;
        if (hit.label == SimLabel::kBuilding && ray_rng.bernoulli(m.ghost_probability))
          addReturn(row, measured + ray_rng.uniform(2.0, 12.0), peak - m.ghost_loss,
                    m.range_resolution, m.lobe_sigma);
      }
    }
    uint8_t* out = scan.power.data() + size_t(a) * m.bins;
    for (int b = 0; b < m.bins; ++b)
      out[b] = uint8_t(std::clamp(std::lround(row[size_t(b)]), 0L, long(m.saturation)));
  }
  if (hits) *hits = placed;
  return scan;
}

bool RadarSimulator::writeMulranDrive(const std::string& out_dir, RadarDriveStats& stats,
                                      const std::function<void(size_t, size_t)>& progress,
                                      std::string* error) const {
  const auto t_start = std::chrono::steady_clock::now();
  const fs::path root(out_dir), data = root / "sensor_data", polar = data / "radar" / "polar";
  std::error_code ec;
  fs::create_directories(polar, ec);
  if (ec) return failWith(error, "cannot create '" + polar.string() + "': " + ec.message());
  const int64_t t0 = sim_.params().start_time_ns;
  auto stampOf = [&](double t) { return t0 + int64_t(std::llround(t * 1e9)); };
  std::map<int64_t, std::vector<std::string>> events;  // data_stamp.csv, in time order

  size_t n = numScans();
  if (model_.max_scans > 0) n = std::min(n, size_t(model_.max_scans));
  const double end_time = n ? sweepStart(n) : 0.0;  // navigation rows up to the last sweep's end
  size_t hits_total = 0;
  for (size_t k = 0; k < n; ++k) {
    size_t hits = 0;
    const radar::RadarPolarScan scan = simulate(k, &hits);
    hits_total += hits;
    const int64_t stamp = stampOf(sweepStart(k));
    std::string why;
    if (!radar::writeMulranPolarPng((polar / (std::to_string(stamp) + ".png")).string(), scan,
                                    &why))
      return failWith(error, why);
    events[stamp].push_back("radar");
    if (progress) progress(k + 1, n);
  }

  // 10 Hz navigation at the LiDAR scan times of the simulator (its GNSS/INS error model).
  auto writeCsv = [&](const fs::path& path, const std::string& text) {
    const std::string tmp = path.string() + ".tmp";
    std::ofstream f(tmp, std::ios::binary);
    f << text;
    f.close();
    if (!f) return false;
    fs::rename(tmp, path, ec);
    return !ec;
  };
  std::string poses, gps, imu;
  char line[512];
  SimRng imu_rng(hashCombine(sim_.params().seed, kImuRowsTag));
  for (size_t k = 0; k < sim_.numScans(); ++k) {
    const double t = sim_.scanTime(k);
    if (t > end_time) break;
    const int64_t stamp = stampOf(t);
    const Eigen::Isometry3d P = radarPose(t);
    const Eigen::Matrix3d R = P.linear();
    const Eigen::Vector3d p = P.translation();
    std::snprintf(line, sizeof(line),
                  "%lld,%.9f,%.9f,%.9f,%.6f,%.9f,%.9f,%.9f,%.6f,%.9f,%.9f,%.9f,%.6f\n",
                  (long long)stamp, R(0, 0), R(0, 1), R(0, 2), p.x(), R(1, 0), R(1, 1), R(1, 2),
                  p.y(), R(2, 0), R(2, 1), R(2, 2), p.z());
    poses += line;
    ++stats.poses;
    const OxtsRecord meas = sim_.measuredOxts(k);
    if (meas.hasGnssFix()) {
      const double var = meas.pos_accuracy * meas.pos_accuracy;
      std::snprintf(line, sizeof(line), "%lld,%.9f,%.9f,%.4f,%g,0,0,0,%g,0,0,0,%g\n",
                    (long long)stamp, meas.lat, meas.lon, meas.alt, var, var, 4 * var);
      gps += line;
      events[stamp].push_back("gps");
      ++stats.gps;
    }
    imu += imuRows(k, t, meas, end_time, stampOf, imu_rng, events, stats);
  }
  std::string stamps;
  for (const auto& [stamp, sensors] : events)
    for (const std::string& s : sensors) stamps += std::to_string(stamp) + "," + s + "\n";
  if (!writeCsv(root / "global_pose.csv", poses) || !writeCsv(data / "gps.csv", gps) ||
      !writeCsv(data / "xsens_imu.csv", imu) || !writeCsv(data / "data_stamp.csv", stamps))
    return failWith(error, "cannot write the CSV files below '" + out_dir + "'");
  stats.scans = n;
  stats.route_length_m = sim_.trajectory().length();
  stats.duration_s = sim_.trajectory().duration();
  stats.mean_hits_per_scan = n ? double(hits_total) / n : 0.0;
  stats.generation_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  stats.scans_per_s = stats.generation_s > 0 ? n / stats.generation_s : 0.0;
  stats.drive_dir = out_dir;
  return true;
}

std::string RadarSimulator::imuRows(size_t k, double t, const OxtsRecord& meas, double end_time,
                                    const std::function<int64_t(double)>& stamp_of, SimRng& rng,
                                    std::map<int64_t, std::vector<std::string>>& events,
                                    RadarDriveStats& stats) const {
  // 100 Hz rows between this epoch and the next: the attitude carries the epoch's INS errors
  // along the true rotation since the epoch; the rates are the true body rates plus white noise
  // and the drive's yaw-rate bias (at 10 Hz a gyro integrated over a sharp turn errs by degrees).
  auto rotation = [this](double s) { return Eigen::Matrix3d(sim_.basePose(s).linear()); };
  const Eigen::Matrix3d measured_at_epoch =
      (Eigen::AngleAxisd(meas.yaw, Eigen::Vector3d::UnitZ()) *
       Eigen::AngleAxisd(meas.pitch, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(meas.roll, Eigen::Vector3d::UnitX()))
          .toRotationMatrix();
  const NavErrorParams& nav = sim_.params().nav;
  const double sg = nav.rtk ? 0.0 : nav.gyro_sigma_deg_s * M_PI / 180.0;
  const double bias = sim_.navErrors().gyro_bias_z;
  const double next_epoch = k + 1 < sim_.numScans() ? sim_.scanTime(k + 1) : end_time;
  std::string rows;
  char line[512];
  for (int j = 0; j < kImuRowsPerEpoch; ++j) {
    const double tj = t + (next_epoch - t) * j / kImuRowsPerEpoch;
    if (tj > end_time) break;
    const Eigen::Matrix3d R = measured_at_epoch * rotation(t).transpose() * rotation(tj);
    const Eigen::Quaterniond q(R);
    const double roll = std::atan2(R(2, 1), R(2, 2)),
                 pitch = std::asin(-std::clamp(R(2, 0), -1.0, 1.0));
    const double yaw = std::atan2(R(1, 0), R(0, 0));
    const Eigen::Vector3d w =
        bodyRate(rotation, tj) +
        Eigen::Vector3d(sg * rng.gaussian(), sg * rng.gaussian(), sg * rng.gaussian() + bias);
    const int64_t stamp = stamp_of(tj);
    std::snprintf(line, sizeof(line),
                  "%lld,%.9f,%.9f,%.9f,%.9f,%.6f,%.6f,%.6f,%.7f,%.7f,%.7f,%.5f,%.5f,%.5f,0,0,0\n",
                  (long long)stamp, q.x(), q.y(), q.z(), q.w(), roll, pitch, yaw, w.x(), w.y(),
                  w.z(), meas.ax, meas.ay, meas.az);
    rows += line;
    events[stamp].push_back("imu");
    ++stats.imu;
  }
  return rows;
}

}  // namespace osm_graph_slam::sim
