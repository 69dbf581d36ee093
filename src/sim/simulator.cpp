#include "osm_graph_slam/sim/simulator.h"
#include "osm_graph_slam/common/attitude.h"
#include "osm_graph_slam/io/trajectory_io.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "osm_graph_slam/io/kitti_bin.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/osm/osm_reader.h"
#include "osm_graph_slam/sim/sim_random.h"

namespace fs = std::filesystem;

namespace osm_graph_slam::sim {
namespace {

constexpr double kGravity = 9.81;
/// KITTI raw calibration layout: the Velodyne 0.81 m ahead of, 0.32 m right of and 0.80 m above
/// the OXTS unit, axes aligned.
const Eigen::Vector3d kVeloInImu(0.81, -0.32, 0.80);

uint64_t worldSeed(const SimulationParams& p) {
  return p.world_seed != 0 ? p.world_seed : p.seed;
}

bool fail(std::string* error, const std::string& msg) {
  if (error) *error = msg;
  return false;
}

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), f, v);
  return buf;
}

std::string dateFolder(StampNs stamp) {
  const std::string s = formatKittiTimestamp(stamp);  // YYYY-MM-DD ...
  return s.substr(0, 4) + "_" + s.substr(5, 2) + "_" + s.substr(8, 2);
}

/// sim_info.json lines: the manoeuvres asked for and driven, and the motion extremes.
std::string manoeuvresJson(const RouteParams& rp, const Route& route, const Trajectory& traj) {
  const ManoeuvreParams& mp = rp.manoeuvres;
  std::ostringstream o;
  o << "  \"manoeuvres\": {\"requested\": \"" << manoeuvreList(mp) << "\"";
  if (mp.any()) {
    o << ", \"sharp_turn_speed_m_s\": " << fmt("%.2f", mp.sharp_turn_speed)
      << ", \"sharp_turn_radius_m\": " << fmt("%.2f", mp.sharp_turn_radius)
      << ", \"sharp_turn_max_yaw_rate_deg_s\": "
      << fmt("%.1f", mp.sharp_turn_max_yaw_rate * 180.0 / M_PI)
      << ", \"sharp_turn_accel_m_s2\": " << fmt("%.2f", mp.sharp_turn_accel)
      << ", \"u_turn_radius_m\": " << fmt("%.2f", mp.u_turn_radius)
      << ", \"stop_duration_s\": " << fmt("%.1f", mp.stop_duration)
      << ", \"skipped\": " << route.manoeuvres_skipped << ", \"events\": [";
    const auto& events = traj.manoeuvres();
    for (size_t i = 0; i < events.size(); ++i) {
      const ManoeuvreEvent& e = events[i];
      o << (i ? ",\n    " : "\n    ") << "{\"type\": \"" << e.type << "\""
        << (e.fallback ? ", \"fallback\": \"u_turn\"" : "")
        << ", \"t_begin_s\": " << fmt("%.2f", e.t_begin)
        << ", \"t_end_s\": " << fmt("%.2f", e.t_end)
        << ", \"s_begin_m\": " << fmt("%.1f", e.s_begin)
        << ", \"s_end_m\": " << fmt("%.1f", e.s_end) << ", \"length_m\": " << fmt("%.1f", e.length)
        << "}";
    }
    o << "]";
  }
  o << "},\n";
  o << "  \"motion\": {\"max_yaw_rate_deg_s\": " << fmt("%.2f", traj.maxYawRate() * 180.0 / M_PI)
    << ", \"max_accel_m_s2\": " << fmt("%.2f", traj.maxAccel())
    << ", \"max_decel_m_s2\": " << fmt("%.2f", traj.maxDecel())
    << ", \"max_lateral_accel_m_s2\": " << fmt("%.2f", traj.maxLateralAccel()) << "},\n";
  return o.str();
}

/// sim_info.json lines: the scans left out (indices of the 10 Hz sequence and their stamps).
std::string droppedScansJson(const ScanDropParams& d, const std::vector<bool>& dropped,
                             StampNs start_ns, double rate_hz) {
  std::ostringstream o, indices, times, stamps;
  size_t count = 0;
  for (size_t k = 0; k < dropped.size(); ++k) {
    if (!dropped[k]) continue;
    const double t = double(k) / rate_hz;
    indices << (count ? ", " : "") << k;
    times << (count ? ", " : "") << fmt("%.1f", t);
    stamps << (count ? ", " : "") << start_ns + StampNs(std::llround(t * 1e9));
    ++count;
  }
  o << "  \"dropped_scans\": {\"fraction\": " << fmt("%.3f", d.fraction)
    << ", \"burst_length\": " << d.burst_length << ", \"burst_time_s\": "
    << (std::isnan(d.burst_time) ? std::string("\"seeded\"") : fmt("%.2f", d.burst_time))
    << ", \"count\": " << count << ", \"indices\": [" << indices.str() << "], \"times_s\": ["
    << times.str() << "], \"stamps_ns\": [" << stamps.str()
    << "], \"note\": \"indices in the 10 Hz sequence of the route; the written files are "
       "numbered consecutively, the timestamps show the gaps\"},\n";
  return o.str();
}

/// sim_info.json line: the procedural city's downtown district (nothing without one).
std::string downtownJson(const Scene& scene) {
  if (scene.downtown.isEmpty()) return "";
  size_t towers = 0;
  for (const auto& tags : scene.building_tags) {
    const auto it = tags.find("sim:district");
    towers += it != tags.end() && it->second == "downtown";
  }
  const Eigen::Vector2d lo = scene.downtown.min(), hi = scene.downtown.max();
  std::ostringstream o;
  o << "  \"downtown\": {\"bounds_enu_m\": [" << fmt("%.2f", lo.x()) << ", " << fmt("%.2f", lo.y())
    << ", " << fmt("%.2f", hi.x()) << ", " << fmt("%.2f", hi.y()) << "], \"towers\": " << towers
    << "},\n";
  return o.str();
}

/// sim_info.json: the INS errors' parameters and draws (every model but rtk).
std::string insJson(const NavErrorParams& nv, const NavErrorSequence& errors) {
  std::ostringstream o;
  o << ", \"imu_attitude_sigma_deg\": " << fmt("%.3f", nv.imu_attitude_sigma_deg)
    << ", \"imu_heading_bias_deg\": " << fmt("%.3f", nv.imu_heading_bias_deg)
    << ", \"imu_heading_sigma_deg\": " << fmt("%.3f", nv.imu_heading_sigma_deg)
    << ", \"gyro_sigma_deg_s\": " << fmt("%.3f", nv.gyro_sigma_deg_s)
    << ", \"gyro_bias_drawn_deg_s\": " << fmt("%.4f", errors.gyro_bias_z * 180.0 / M_PI)
    << ", \"accel_sigma_m_s2\": " << fmt("%.3f", nv.accel_sigma)
    << ", \"heading_bias_drawn_deg\": " << fmt("%.4f", errors.heading_bias * 180.0 / M_PI);
  return o.str();
}

size_t numSatellites(const NavErrorParams& nv, uint64_t seed) {
  return Constellation::draw(nv.canyon.constellation, seed).size();
}

/// The error of the first epoch with a fix (the map origin), zero if the drive has none.
Eigen::Vector3d firstFixError(const NavErrorSequence& errors) {
  for (const NavEpochError& e : errors.epochs)
    if (!e.outage) return e.gnss;
  return Eigen::Vector3d::Zero();
}

/// sim_info.json: the canyon model's parameters and the receiver's statistics over the drive.
std::string canyonJson(const NavErrorParams& nv, const NavErrorSequence& errors,
                       const CanyonDriveStats& c, size_t satellites) {
  const CanyonGnssParams& p = nv.canyon;
  const Eigen::Vector3d first = firstFixError(errors);
  std::ostringstream o;
  o << ", \"model\": \"canyon\", \"satellites\": " << satellites
    << ", \"elevation_mask_deg\": " << fmt("%.1f", p.constellation.elevation_mask_deg)
    << ", \"sky_rate_deg_per_min\": " << fmt("%.3f", p.constellation.sky_rate_deg_per_min)
    << ", \"range_sigma_m\": " << fmt("%.3f", p.range_sigma)
    << ", \"assumed_range_sigma_m\": " << fmt("%.3f", p.assumed_range_sigma)
    << ", \"reflections\": " << (p.reflections ? "true" : "false")
    << ", \"max_reflector_distance_m\": " << fmt("%.1f", p.max_reflector_distance)
    << ", \"max_pdop\": " << fmt("%.1f", p.max_pdop) << insJson(nv, errors)
    << ", \"first_fix_error_enu_m\": [" << fmt("%.4f", first.x()) << ", " << fmt("%.4f", first.y())
    << ", " << fmt("%.4f", first.z()) << "], \"epochs\": " << c.epochs << ", \"fixes\": " << c.fixes
    << ", \"gnss_error_rms_m\": " << fmt("%.4f", c.horizontal_rms_m)
    << ", \"gnss_error_p95_m\": " << fmt("%.4f", c.horizontal_p95_m)
    << ", \"gnss_error_max_m\": " << fmt("%.4f", c.horizontal_max_m)
    << ", \"gnss_error_mean_m\": " << fmt("%.4f", c.horizontal_mean_m)
    << ", \"reported_accuracy_mean_m\": " << fmt("%.4f", c.reported_horizontal_mean_m)
    << ", \"nlos_fix_share\": " << fmt("%.4f", c.nlos_fix_share) << ", \"outages\": " << c.outages
    << ", \"outage_s\": " << fmt("%.1f", c.outage_s)
    << ", \"satellites_used_mean\": " << fmt("%.2f", c.mean_satellites_used)
    << ", \"satellites_blocked_mean\": " << fmt("%.2f", c.mean_satellites_blocked)
    << ", \"note\": \"horizontal errors over the epochs with a fix; reported_accuracy = HDOP x "
       "assumed_range_sigma (horizontal RMS; oxts pos_accuracy holds it / sqrt 2, per axis)\"";
  return o.str();
}

}  // namespace

UrbanSimulator::UrbanSimulator() = default;
UrbanSimulator::~UrbanSimulator() = default;

bool UrbanSimulator::build(const SimulationParams& params, std::string* error) {
  params_ = params;
  T_imu_velo_ = Eigen::Isometry3d::Identity();
  T_imu_velo_.translation() = kVeloInImu;
  T_imu_velo_.translation().z() = kVeloInImu.z();
  T_velo_imu_ = T_imu_velo_.inverse();
  double lat0 = params.origin_lat, lon0 = params.origin_lon;
  GroundModel ground;
  if (params.flat_ground)
    for (double& amplitude : ground.amplitude) amplitude = 0.0;
  if (!params.osm_path.empty()) {
    const OsmData osm = readOsmFile(params.osm_path);
    if (!osm.ok)
      return fail(error, "cannot read OSM extract '" + params.osm_path + "': " + osm.error);
    if (osm.buildings.empty())
      return fail(error, "OSM extract '" + params.osm_path + "' has no buildings");
    if (std::isnan(lat0) || std::isnan(lon0)) {
      double la0 = 90, la1 = -90, lo0 = 180, lo1 = -180;
      for (const auto& b : osm.buildings) {
        for (const auto& g : b.outline_geo) {
          la0 = std::min(la0, g.lat);
          la1 = std::max(la1, g.lat);
          lo0 = std::min(lo0, g.lon);
          lo1 = std::max(lo1, g.lon);
        }
      }
      lat0 = 0.5 * (la0 + la1);
      lon0 = 0.5 * (lo0 + lo1);
    }
    enu_ = std::make_unique<EnuConverter>(lat0, lon0, params.origin_alt);
    scene_ = sceneFromOsm(osm, *enu_, worldSeed(params), ground);
  } else {
    if (std::isnan(lat0) || std::isnan(lon0)) {
      lat0 = 49.0110;
      lon0 = 8.4170;
    }
    enu_ = std::make_unique<EnuConverter>(lat0, lon0, params.origin_alt);
    CityParams city = params.city;
    city.seed = worldSeed(params);
    scene_ = proceduralCity(city, ground);
  }
  const RoadGraph roads = RoadGraph::fromPolylines(scene_.roads);
  const RoadGraph graph = roads.drivableCore();
  RouteParams rp = params.route;
  rp.seed = params.seed;
  if (!planRoute(graph, rp, route_, error, &roads)) return false;
  trajectory_ = Trajectory::fromRoute(route_, rp);
  {
    // GNSS/INS errors for every scan of the whole route (a shorter --scans drive is a prefix).
    const size_t n = size_t(std::floor(trajectory_.duration() * params.lidar.rate_hz)) + 1;
    std::vector<double> path(n);
    for (size_t k = 0; k < n; ++k) path[k] = trajectory_.at(double(k) / params.lidar.rate_hz).s;
    nav_errors_ = simulateNavErrors(params.nav, params.seed, 1.0 / params.lidar.rate_hz, path);
    canyon_fixes_.clear();
    if (!params.nav.rtk && params.nav.gnss_model == GnssPositionModel::kCanyon &&
        !simulateCanyonGnss(n, error))
      return false;
  }
  if (params.clutter_enabled) {
    ClutterParams cp = params.clutter;
    cp.seed = params.seed;
    addClutter(scene_, cp, &trajectory_);
  }
  scene_.world.finalize();
  return true;
}

bool UrbanSimulator::simulateCanyonGnss(size_t epochs, std::string* error) {
  const std::string problem = CanyonGnss::worldProblem(scene_.world);
  if (!problem.empty()) return fail(error, problem);
  const CanyonGnss receiver(scene_.world, params_.nav.canyon, params_.seed);
  canyon_fixes_.resize(epochs);
  // The antenna at the OXTS point (the fix is reported for it).
  for (size_t k = 0; k < epochs; ++k)
    canyon_fixes_[k] = receiver.epoch(k, scanTime(k), basePose(scanTime(k)).translation());
  applyCanyonFixes(canyon_fixes_, nav_errors_);
  return true;
}

size_t UrbanSimulator::numScans() const {
  const size_t n = size_t(std::floor(trajectory_.duration() * params_.lidar.rate_hz)) + 1;
  return params_.max_scans > 0 ? std::min(n, size_t(params_.max_scans)) : n;
}

std::vector<bool> UrbanSimulator::droppedScans() const {
  const size_t n = numScans();
  std::vector<bool> dropped(n, false);
  const ScanDropParams& d = params_.scan_drop;
  if (d.fraction > 0.0) {
    for (size_t k = 1; k < n; ++k) {
      // One stream per scan: the same scans are missing whatever --scans cuts off.
      SimRng rng(hashCombine(hashCombine(params_.seed, 0x64726f70ULL), k));
      dropped[k] = rng.uniform() < d.fraction;
    }
  }
  if (d.burst_length > 0 && n > 1) {
    const size_t len = std::min(size_t(d.burst_length), n - 1);
    size_t first;
    if (std::isnan(d.burst_time)) {
      SimRng rng(hashCombine(params_.seed, 0x6275727374ULL));
      // The whole burst within 30-70 % of the drive when it fits.
      const size_t lo = std::max<size_t>(1, size_t(0.3 * double(n)));
      const size_t end = size_t(0.7 * double(n));
      const size_t hi = end >= lo + len ? end - len : lo;
      first = lo + size_t(rng.uniformInt(0, int(hi - lo)));
    } else {
      first = size_t(std::max(0.0, std::round(d.burst_time * params_.lidar.rate_hz)));
    }
    first = std::clamp<size_t>(first, 1, n - len);
    for (size_t k = first; k < first + len; ++k) dropped[k] = true;
  }
  return dropped;
}

Eigen::Isometry3d UrbanSimulator::basePose(double t) const {
  const TrajectoryState s = trajectory_.at(t);
  Eigen::Vector2d grad;
  const double z = scene_.world.ground.height(s.position.x(), s.position.y(), grad);
  const Eigen::Vector2d fwd(std::cos(s.yaw), std::sin(s.yaw)), left(-fwd.y(), fwd.x());
  const double pitch = -std::atan(grad.dot(fwd));
  const double roll = std::atan(grad.dot(left));
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotationFromRollPitchYaw(roll, pitch, s.yaw);
  const double imu_height = params_.lidar.mount_height - kVeloInImu.z();
  T.translation() = Eigen::Vector3d(s.position.x(), s.position.y(), z) +
                    T.linear() * Eigen::Vector3d(0, 0, imu_height);
  return T;
}

OxtsRecord UrbanSimulator::oxtsAt(double t) const {
  const TrajectoryState s = trajectory_.at(t);
  const Eigen::Isometry3d T = basePose(t);
  const Eigen::Vector3d geo = enu_->toGeodetic(T.translation());
  OxtsRecord r;
  r.lat = geo.x();
  r.lon = geo.y();
  r.alt = geo.z();
  const Eigen::Matrix3d& R = T.linear();
  r.yaw = yawOf(R);
  const Eigen::Vector2d roll_pitch = rollPitchOf(R);
  r.roll = roll_pitch.x();
  r.pitch = roll_pitch.y();
  const Eigen::Vector3d fwd = R.col(0);
  const Eigen::Vector3d vel = s.speed * fwd;
  r.ve = vel.x();
  r.vn = vel.y();
  const Eigen::Vector3d v_body = R.transpose() * vel;
  r.vf = v_body.x();
  r.vl = v_body.y();
  r.vu = v_body.z();
  const Eigen::Vector2d h(std::cos(s.yaw), std::sin(s.yaw)), left(-h.y(), h.x());
  const Eigen::Vector2d a2 = s.accel * h + s.speed * s.speed * s.curvature * left;
  const Eigen::Vector3d a_body = R.transpose() * Eigen::Vector3d(a2.x(), a2.y(), kGravity);
  r.ax = r.af = a_body.x();
  r.ay = r.al = a_body.y();
  r.az = r.au = a_body.z();
  const Eigen::Vector3d w_body = R.transpose() * Eigen::Vector3d(0, 0, s.yaw_rate);
  r.wx = r.wf = w_body.x();
  r.wy = r.wl = w_body.y();
  r.wz = r.wu = w_body.z();
  r.pos_accuracy = 0.02;
  r.vel_accuracy = 0.02;
  r.navstat = 4;
  r.numsats = 12;
  r.posmode = 4;
  r.velmode = 4;
  r.orimode = 6;
  return r;
}

OxtsRecord UrbanSimulator::measuredOxts(size_t k) const {
  const OxtsRecord truth = oxtsAt(scanTime(k));
  if (params_.nav.rtk || k >= nav_errors_.epochs.size()) return truth;
  // During an outage the record holds the last fix (and says it has none).
  size_t j = k;
  while (j > 0 && nav_errors_.epochs[j].outage) --j;
  const Eigen::Vector3d fix = basePose(scanTime(j)).translation() + nav_errors_.epochs[j].gnss;
  return measuredOxtsRecord(truth, fix, nav_errors_.epochs[k], params_.nav, *enu_);
}

SimulatedScan UrbanSimulator::simulate(size_t k) const {
  return simulateScan(
      scene_.world, params_.lidar, [this](double t) { return sensorPose(t); }, scanTime(k),
      params_.seed, k, params_.motion_distortion, params_.compensated_sweep);
}

bool UrbanSimulator::writeDataset(const std::string& out_dir, SimulationStats& stats,
                                  const std::function<void(size_t, size_t)>& progress,
                                  std::string* error) const {
  const auto t_start = std::chrono::steady_clock::now();
  stats = SimulationStats();
  const std::string date = dateFolder(params_.start_time_ns);
  char drive_name[64];
  std::snprintf(drive_name, sizeof(drive_name), "%s_drive_%04d_sync", date.c_str(),
                params_.drive_number);
  const fs::path date_dir = fs::path(out_dir) / date;
  const fs::path drive = date_dir / drive_name;
  const fs::path gt_dir = fs::path(out_dir) / "ground_truth";
  std::error_code ec;
  for (const auto& d : {drive / "velodyne_points" / "data", drive / "oxts" / "data",
                        drive / "oxts_true" / "data", gt_dir}) {
    fs::create_directories(d, ec);
    if (ec) return fail(error, "cannot create '" + d.string() + "': " + ec.message());
  }
  stats.drive_dir = drive.string();
  if (!writeKittiRigidCalib((date_dir / "calib_imu_to_velo.txt").string(), T_velo_imu_, error)) {
    return false;
  }
  Eigen::Isometry3d T_cam_velo = Eigen::Isometry3d::Identity();
  T_cam_velo.linear() << 0, -1, 0, 0, 0, -1, 1, 0, 0;  // camera: x right, y down, z forward
  T_cam_velo.translation() = Eigen::Vector3d(0.0, -0.08, -0.27);
  if (!writeKittiRigidCalib((date_dir / "calib_velo_to_cam.txt").string(), T_cam_velo, error)) {
    return false;
  }

  const size_t n = numScans();
  const std::vector<bool> dropped = droppedScans();
  std::vector<StampNs> stamps, starts, ends;
  std::vector<Eigen::Isometry3d> velo_poses, imu_poses;
  std::ostringstream times;
  double raycast_s = 0.0, points = 0.0;
  size_t min_pts = SIZE_MAX, max_pts = 0;
  std::array<double, 8> label_counts{};
  for (size_t k = 0; k < n; ++k) {
    if (dropped[k]) {  // no file, no stamp, no OXTS, no ground truth: numbering goes on
      if (progress) progress(k + 1, n);
      continue;
    }
    const size_t file_index = stamps.size();
    const double t = scanTime(k);
    const StampNs stamp = params_.start_time_ns + StampNs(std::llround(t * 1e9));
    const StampNs half = StampNs(std::llround(0.5e9 / params_.lidar.rate_hz));
    stamps.push_back(stamp);
    starts.push_back(stamp - half);
    ends.push_back(stamp + half);
    const auto t0 = std::chrono::steady_clock::now();
    const SimulatedScan scan = simulate(k);
    raycast_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    char name[32];
    std::snprintf(name, sizeof(name), "%010zu", file_index);
    if (!writeKittiBin((drive / "velodyne_points" / "data" / (std::string(name) + ".bin")).string(),
                       scan.cloud, error)) {
      return false;
    }
    if (!writeOxtsFile((drive / "oxts" / "data" / (std::string(name) + ".txt")).string(),
                       measuredOxts(k), error) ||
        !writeOxtsFile((drive / "oxts_true" / "data" / (std::string(name) + ".txt")).string(),
                       oxtsAt(t), error)) {
      return false;
    }
    velo_poses.push_back(sensorPose(t));
    imu_poses.push_back(basePose(t));
    times << fmt("%.6e", t) << '\n';
    points += double(scan.cloud.size());
    min_pts = std::min(min_pts, scan.cloud.size());
    max_pts = std::max(max_pts, scan.cloud.size());
    for (SimLabel l : scan.labels) label_counts[size_t(l)] += 1.0;
    if (progress) progress(k + 1, n);
  }
  const std::string vdir = (drive / "velodyne_points").string();
  const std::string odir = (drive / "oxts").string();
  bool ok =
      writeKittiTimestamps(vdir + "/timestamps.txt", stamps, error) &&
      writeKittiTimestamps(vdir + "/timestamps_start.txt", starts, error) &&
      writeKittiTimestamps(vdir + "/timestamps_end.txt", ends, error) &&
      writeKittiTimestamps(odir + "/timestamps.txt", stamps, error) &&
      writeKittiTimestamps((drive / "oxts_true" / "timestamps.txt").string(), stamps, error) &&
      writeKittiPoses((gt_dir / "poses_velo.txt").string(), velo_poses, error) &&
      writeKittiPoses((gt_dir / "poses_imu.txt").string(), imu_poses, error) &&
      writeFileAtomically((gt_dir / "times.txt").string(), times.str(), error);
  if (!ok) return false;

  PriorMapInfo prior_info;
  const std::vector<PriorBuilding> prior = [&] {
    PriorPerturbationParams pp = params_.prior;
    pp.seed = params_.prior_seed != 0 ? params_.prior_seed : params_.seed;
    return perturbBuildings(scene_, pp, &prior_info);
  }();
  ok = writeBuildingsGeoJson((fs::path(out_dir) / "buildings_true.geojson").string(), scene_, *enu_,
                             error) &&
       writePriorOsm((fs::path(out_dir) / "prior.osm").string(), prior, scene_, *enu_, error) &&
       writePriorOffsetsCsv((fs::path(out_dir) / "prior_offsets.csv").string(), prior, error);
  if (!ok) return false;

  stats.buildings = scene_.world.buildings.size();
  stats.primitives = scene_.world.primitives.size();
  stats.moving_objects = scene_.world.moving.size();
  stats.walls = scene_.world.numWalls();
  const size_t written = stamps.size();
  stats.scans = written;
  stats.dropped_scans = n - written;
  stats.route_length_m = trajectory_.length();
  stats.duration_s = trajectory_.duration();
  stats.revisits = countRevisits(trajectory_);
  stats.max_yaw_rate_deg_s = trajectory_.maxYawRate() * 180.0 / M_PI;
  stats.max_lateral_accel = trajectory_.maxLateralAccel();
  stats.mean_points_per_scan = written ? points / double(written) : 0.0;
  stats.min_points_per_scan = written ? double(min_pts) : 0.0;
  stats.max_points_per_scan = double(max_pts);
  const double total = std::max(points, 1.0);
  stats.building_fraction = label_counts[size_t(SimLabel::kBuilding)] / total;
  stats.ground_fraction = label_counts[size_t(SimLabel::kGround)] / total;
  stats.moving_fraction = label_counts[size_t(SimLabel::kMoving)] / total;
  stats.clutter_fraction =
      1.0 - stats.building_fraction - stats.ground_fraction - stats.moving_fraction;
  for (const auto& b : prior) {
    if (b.status == PriorBuilding::Status::kPerturbed) ++stats.prior_perturbed;
    if (b.status == PriorBuilding::Status::kRemoved) ++stats.prior_removed;
    if (b.status == PriorBuilding::Status::kPhantom) ++stats.prior_phantom;
  }
  double gnss_sq = 0.0;
  size_t gnss_fixes = 0;
  for (size_t k = 0; k < n && k < nav_errors_.epochs.size(); ++k) {
    const NavEpochError& e = nav_errors_.epochs[k];
    if (e.outage) {
      stats.gnss_outage_s += 1.0 / params_.lidar.rate_hz;
      if (k == 0 || !nav_errors_.epochs[k - 1].outage) ++stats.gnss_outages;
      continue;
    }
    const double h = e.gnss.head<2>().norm();
    gnss_sq += h * h;
    stats.gnss_error_max_m = std::max(stats.gnss_error_max_m, h);
    ++gnss_fixes;
  }
  stats.gnss_error_rms_m = gnss_fixes ? std::sqrt(gnss_sq / double(gnss_fixes)) : 0.0;
  if (!canyon_fixes_.empty()) {
    const std::vector<CanyonEpoch> driven(
        canyon_fixes_.begin(), canyon_fixes_.begin() + std::min(n, canyon_fixes_.size()));
    stats.canyon = summarizeCanyonDrive(driven, 1.0 / params_.lidar.rate_hz);
  }
  stats.raycast_s = raycast_s;
  stats.generation_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  stats.scans_per_s = stats.generation_s > 0 ? double(n) / stats.generation_s : 0.0;

  // sim_info.json: parameters and statistics (no timings: same seed, same bytes).
  std::ostringstream info;
  info << "{\n  \"seed\": " << params_.seed << ",\n";
  if (params_.world_seed != 0) info << "  \"world_seed\": " << params_.world_seed << ",\n";
  if (params_.prior_seed != 0) info << "  \"prior_seed\": " << params_.prior_seed << ",\n";
  info << "  \"world\": \""
       << (params_.osm_path.empty() ? std::string("procedural") : params_.osm_path) << "\",\n"
       << downtownJson(scene_) << "  \"enu_origin\": {\"lat\": " << fmt("%.9f", enu_->originLat())
       << ", \"lon\": " << fmt("%.9f", enu_->originLon())
       << ", \"alt\": " << fmt("%.3f", enu_->originAlt()) << "},\n"
       << "  \"sensor\": \"" << params_.lidar.name << "\",\n"
       << "  \"motion_distortion\": " << (params_.motion_distortion ? "true" : "false") << ",\n"
       << "  \"compensated_sweep\": " << (params_.compensated_sweep ? "true" : "false") << ",\n"
       << "  \"calibration_error\": {\"elevation_bias_deg\": "
       << fmt("%.3f", params_.lidar.elevation_bias_deg)
       << ", \"beam_elevation_sigma_deg\": " << fmt("%.3f", params_.lidar.beam_elevation_sigma_deg)
       << ", \"beam_range_offset_sigma_m\": " << fmt("%.3f", params_.lidar.beam_range_offset_sigma)
       << "},\n"
       << "  \"drive_dir\": \"" << fs::relative(drive, out_dir).string() << "\",\n"
       << "  \"scans\": " << written << ",\n"
       << "  \"route_length_m\": " << fmt("%.2f", stats.route_length_m) << ",\n"
       << "  \"duration_s\": " << fmt("%.2f", stats.duration_s) << ",\n"
       << "  \"revisits\": " << stats.revisits << ",\n"
       << manoeuvresJson(params_.route, route_, trajectory_)
       << droppedScansJson(params_.scan_drop, dropped, params_.start_time_ns, params_.lidar.rate_hz)
       << "  \"buildings\": " << stats.buildings << ",\n"
       << "  \"clutter_primitives\": " << stats.primitives << ",\n"
       << "  \"moving_objects\": " << stats.moving_objects << ",\n"
       << "  \"mean_points_per_scan\": " << fmt("%.1f", stats.mean_points_per_scan) << ",\n"
       << "  \"building_hit_fraction\": " << fmt("%.4f", stats.building_fraction) << ",\n"
       << "  \"ground_hit_fraction\": " << fmt("%.4f", stats.ground_fraction) << ",\n"
       << "  \"prior\": {\"model\": \"" << priorModelName(params_.prior.model) << "\""
       << ", \"translation_sigma_m\": " << fmt("%.3f", params_.prior.translation_sigma)
       << ", \"rotation_sigma_deg\": " << fmt("%.3f", params_.prior.rotation_sigma_deg)
       << ", \"removal_fraction\": " << fmt("%.3f", params_.prior.removal_fraction)
       << ", \"phantom_fraction\": " << fmt("%.3f", params_.prior.phantom_fraction)
       << ", \"perturbed\": " << stats.prior_perturbed << ", \"removed\": " << stats.prior_removed
       << ", \"phantom\": " << stats.prior_phantom;
  const PriorPerturbationParams& pr = params_.prior;
  if (pr.model == PriorModel::kBlocks || pr.model == PriorModel::kMixed) {
    info << ", \"block_size_m\": " << fmt("%.3f", pr.block_size)
         << ", \"block_touch_distance_m\": " << fmt("%.3f", pr.block_touch_distance)
         << ", \"block_translation_sigma_m\": " << fmt("%.3f", pr.block_translation_sigma)
         << ", \"block_rotation_sigma_deg\": " << fmt("%.3f", pr.block_rotation_sigma_deg)
         << ", \"block_residual_sigma_m\": " << fmt("%.3f", pr.block_residual_sigma)
         << ", \"block_residual_rotation_sigma_deg\": "
         << fmt("%.3f", pr.block_residual_rotation_sigma_deg)
         << ", \"block_groups\": " << prior_info.groups;
  }
  if (pr.model == PriorModel::kGlobal || pr.model == PriorModel::kMixed) {
    info << ", \"global_offset_min_m\": " << fmt("%.3f", pr.global_offset_min)
         << ", \"global_offset_max_m\": " << fmt("%.3f", pr.global_offset_max)
         << ", \"global_rotation_sigma_deg\": " << fmt("%.3f", pr.global_rotation_sigma_deg)
         << ", \"global_offset_m\": [" << fmt("%.4f", prior_info.global_offset.x()) << ", "
         << fmt("%.4f", prior_info.global_offset.y())
         << "], \"global_rotation_deg\": " << fmt("%.4f", prior_info.global_rotation * 180 / M_PI);
  }
  if (pr.model == PriorModel::kMixed) {
    info << ", \"mixed_translation_sigma_m\": " << fmt("%.3f", pr.mixed_translation_sigma)
         << ", \"mixed_rotation_sigma_deg\": " << fmt("%.3f", pr.mixed_rotation_sigma_deg);
  }
  info << "},\n";
  const NavErrorParams& nv = params_.nav;
  info << "  \"gnss_ins\": {\"rtk\": " << (nv.rtk ? "true" : "false");
  if (!nv.rtk && nv.gnss_model == GnssPositionModel::kCanyon) {
    info << canyonJson(nv, nav_errors_, stats.canyon, numSatellites(nv, params_.seed));
  } else if (!nv.rtk) {
    const Eigen::Vector3d first =
        nav_errors_.epochs.empty() ? Eigen::Vector3d::Zero() : nav_errors_.epochs.front().gnss;
    info << ", \"gnss_sigma_m\": " << fmt("%.3f", nv.gnss_sigma)
         << ", \"gnss_sigma_vertical_m\": " << fmt("%.3f", nv.gnss_sigma_vertical)
         << ", \"gnss_bias_sigma_m\": " << fmt("%.3f", nv.gnss_bias_sigma)
         << ", \"gnss_bias_sigma_vertical_m\": " << fmt("%.3f", nv.gnss_bias_sigma_vertical)
         << ", \"gnss_bias_tau_s\": " << fmt("%.1f", nv.gnss_bias_tau_s)
         << ", \"gnss_outages_per_km\": " << fmt("%.3f", nv.gnss_outages_per_km)
         << ", \"gnss_outage_duration_s\": " << fmt("%.1f", nv.gnss_outage_duration_s)
         << ", \"gnss_outage_min_start_s\": " << fmt("%.1f", nv.gnss_outage_min_start_s)
         << ", \"pos_accuracy_m\": " << fmt("%.3f", gnssReportedAccuracy(nv))
         << insJson(nv, nav_errors_) << ", \"first_fix_error_enu_m\": [" << fmt("%.4f", first.x())
         << ", " << fmt("%.4f", first.y()) << ", " << fmt("%.4f", first.z())
         << "], \"gnss_error_rms_m\": " << fmt("%.4f", stats.gnss_error_rms_m)
         << ", \"gnss_error_max_m\": " << fmt("%.4f", stats.gnss_error_max_m)
         << ", \"outages\": " << stats.gnss_outages
         << ", \"outage_s\": " << fmt("%.1f", stats.gnss_outage_s);
  }
  info << "},\n"
       << "  \"ground_truth\": \"ground_truth/poses_velo.txt: velo_link in the ENU frame above, "
          "KITTI 3x4 rows; poses_imu.txt: base_link (OXTS); the drive's oxts_true/: exact OXTS "
          "records (oxts/: what the GNSS/INS measured)\"\n}\n";
  return writeFileAtomically((fs::path(out_dir) / "sim_info.json").string(), info.str(), error);
}

}  // namespace osm_graph_slam::sim
