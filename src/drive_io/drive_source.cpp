#include "osm_graph_slam/drive_io/drive_source.h"

#include <chrono>
#include <filesystem>
#include <iostream>

#include "osm_graph_slam/common/attitude.h"
#include "osm_graph_slam/common/imu_reading_buffer.h"
#include "osm_graph_slam/drive_io/bag_drive_reader.h"
#include "osm_graph_slam/io/kitti_bin.h"
#include "osm_graph_slam/io/kitti_raw.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/slam/sensor_inputs.h"

namespace osm_graph_slam {
namespace {

std::string argOr(const std::map<std::string, std::string>& args, const std::string& key,
                  const std::string& fallback) {
  const auto it = args.find(key);
  return it == args.end() ? fallback : it->second;
}

Eigen::Isometry3d oxtsPose(const OxtsRecord& r, const EnuConverter& enu) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = rotationFromRollPitchYaw(r.roll, r.pitch, r.yaw);
  pose.translation() = enu.toEnu(r.lat, r.lon, r.alt);
  return pose;
}

/// KITTI raw folder: velodyne_points/*.bin with the OXTS record of the same index.
class KittiRawSource : public DriveSource {
 public:
  bool open(const std::string& dir, const std::string& calib_dir, std::string* error) {
    if (!openKittiRawDrive(dir, calib_dir, drive_, error)) return false;
    OxtsRecord first, fix;
    if (drive_.oxts_files.empty() || !readOxtsFile(drive_.oxts_files.front(), first, error)) {
      if (error) *error = "no usable first GPS fix: " + *error;
      return false;
    }
    // The map origin is the first record with a GNSS fix (a simulated outage has none).
    fix = first;
    for (size_t i = 1; !fix.hasGnssFix() && i < drive_.oxts_files.size(); ++i) {
      if (!readOxtsFile(drive_.oxts_files[i], fix, error)) return false;
    }
    if (!fix.hasGnssFix()) {
      if (error) *error = "no OXTS record of '" + dir + "' has a GNSS fix";
      return false;
    }
    lat = fix.lat;
    lon = fix.lon;
    alt = fix.alt;
    initial_yaw = first.yaw;
    enu_.emplace(fix.lat, fix.lon, fix.alt);
    // base_link is the OXTS/IMU frame (as kitti2bag's tf_static): p_base = inv(T_velo_imu) p_velo.
    sensor_to_base = drive_.T_velo_imu.inverse();
    return true;
  }
  size_t size() const override { return drive_.scan_files.size(); }
  bool next(DriveScan& scan) override {
    if (index_ >= size()) return false;
    const size_t i = index_++;
    scan = DriveScan();
    scan.stamp = static_cast<double>(drive_.scan_stamps[i]) * 1e-9;
    auto cloud = std::make_shared<PointCloud>();
    if (readKittiBin(drive_.scan_files[i], *cloud, &scan.error)) scan.cloud = cloud;
    OxtsRecord r;
    if (i < drive_.oxts_files.size() && readOxtsFile(drive_.oxts_files[i], r)) {
      scan.truth = oxtsPose(r, *enu_);  // KITTI's OXTS is RTK GNSS + INS
      if (r.hasGnssFix()) {
        const Eigen::Vector3d enu = enu_->toEnu(r.lat, r.lon, r.alt);
        scan.gnss = enu.head<2>();
        scan.gnss_altitude = enu.z();
        if (r.pos_accuracy > 0.0) scan.gnss_std = r.pos_accuracy;
      }
      scan.roll_pitch = Eigen::Vector2d(r.roll, r.pitch);
      scan.orientation = Eigen::Quaterniond(oxtsPose(r, *enu_).linear());
      scan.angular_velocity = Eigen::Vector3d(r.wx, r.wy, r.wz);
      scan.linear_acceleration = Eigen::Vector3d(r.ax, r.ay, r.az);
    }
    // simulate_urban's exact records: the truth in the frame of the (measured) first fix.
    if (!drive_.truth_oxts_files.empty()) {
      scan.truth.reset();
      if (i < drive_.truth_oxts_files.size() && readOxtsFile(drive_.truth_oxts_files[i], r))
        scan.truth = oxtsPose(r, *enu_);
    }
    return true;
  }

 private:
  KittiRawDrive drive_;
  std::optional<EnuConverter> enu_;
  size_t index_ = 0;
};

/// A bag as kitti2bag writes it; the IMU and GNSS matched to each cloud's stamp by SensorInputs
/// (as the graph_backend nodelet does), the ground truth nearest to it.
class BagSource : public DriveSource {
 public:
  explicit BagSource(const SensorInputsParams& params) : inputs_(unbounded(params)) {}

  bool open(const std::string& path, const BagDriveTopics& topics, std::string* error) {
    if (!reader_.open(path, topics, error)) return false;
    const std::optional<BagFix> fix = reader_.firstFix();
    if (!fix) {
      if (error) *error = "bag '" + path + "' has no valid fix on '" + topics.gps + "'";
      return false;
    }
    lat = fix->lat;
    lon = fix->lon;
    alt = fix->alt;
    enu_.emplace(lat, lon, alt);
    for (const BagFix& f : reader_.fixes())
      inputs_.addFix({static_cast<double>(f.stamp_ns) * 1e-9, f.lat, f.lon, f.alt, f.std_xy});
    for (const auto& [stamp_ns, q] : reader_.orientations())
      inputs_.addOrientation(static_cast<double>(stamp_ns) * 1e-9, q);
    for (const BagImuReading& r : reader_.imuRates(false))
      gyro_.add(static_cast<double>(r.stamp_ns) * 1e-9, r.value);
    for (const BagImuReading& r : reader_.imuRates(true))
      accel_.add(static_cast<double>(r.stamp_ns) * 1e-9, r.value);
    // The sensor mounting from tf_static: base_link -> the first cloud's frame.
    pending_ = reader_.nextCloud();
    if (pending_) {
      const InitialHeading heading =
          inputs_.initialHeading(static_cast<double>(pending_->stamp_ns) * 1e-9);
      initial_yaw = heading.yaw;
      if (!heading.warning.empty()) std::cerr << "note: " << heading.warning << "\n";
    }
    const std::string frame = pending_ ? pending_->frame_id : std::string();
    const auto base_T_sensor = reader_.baseToFrame(frame);
    if (!base_T_sensor) {
      if (error)
        *error = "no static transform " + topics.base_frame + " -> '" + frame + "' on '" +
                 topics.tf_static + "' in '" + path + "'";
      return false;
    }
    sensor_to_base = *base_T_sensor;
    return true;
  }
  size_t size() const override { return reader_.numClouds(); }
  bool next(DriveScan& scan) override {
    std::optional<BagCloud> c = pending_ ? std::move(pending_) : reader_.nextCloud();
    pending_.reset();
    if (!c) return false;
    scan = DriveScan();
    scan.stamp = static_cast<double>(c->stamp_ns) * 1e-9;
    scan.cloud = c->cloud;
    scan.error = c->error;
    if (const auto a = inputs_.attitudeAt(scan.stamp)) {
      scan.roll_pitch = Eigen::Vector2d(a->roll, a->pitch);
      scan.orientation = a->orientation;
    }
    // The IMU between the previous scan and this one (as the localization nodelet takes it).
    const double from = previous_stamp_.value_or(scan.stamp - 0.1);
    scan.angular_velocity = gyro_.meanBetween(from, scan.stamp, kImuMaxGap);
    scan.linear_acceleration = accel_.meanBetween(from, scan.stamp, kImuMaxGap);
    previous_stamp_ = scan.stamp;
    scan.truth = reader_.groundTruthAt(c->stamp_ns);
    // The pipeline anchors its first keyframe here, whichever cloud that is.
    if (const auto f = inputs_.fixAt(scan.stamp)) {
      const Eigen::Vector3d enu = enu_->toEnu(f->lat, f->lon, f->alt);
      scan.gnss = enu.head<2>();
      scan.gnss_altitude = enu.z();
      if (f->std_xy > 0.0) scan.gnss_std = f->std_xy;
    }
    return true;
  }

 private:
  static SensorInputsParams unbounded(SensorInputsParams params) {
    params.max_samples = 0;  // the whole bag is in memory already
    return params;
  }

  /// [s] no IMU reading this close to a scan: none for it (the nodelet's imu_max_gap).
  static constexpr double kImuMaxGap = 0.2;

  BagDriveReader reader_;
  SensorInputs inputs_;
  std::optional<EnuConverter> enu_;
  std::optional<BagCloud> pending_;
  ImuReadingBuffer gyro_, accel_;  ///< the whole bag, base_link
  std::optional<double> previous_stamp_;
};

/// A folder of KITTI .bin scans with one georeference for the first scan and no IMU: stamps at
/// a fixed rate, the GNSS fix only at the first scan (the map origin), the heading if known.
class ScanFolderSource : public DriveSource {
 public:
  bool open(const std::map<std::string, std::string>& args, const std::string& program,
            std::string* error) {
    const std::string dir = args.at("scans");
    files_ = listFiles(dir, ".bin");
    if (files_.empty()) return fail(error, "no .bin scans in '" + dir + "'");
    if (args.count("rate")) rate_ = std::atof(args.at("rate").c_str());
    if (!(rate_ > 0.0)) return fail(error, "--rate must be > 0");
    ScanFolderOrigin origin;
    if (!readScanFolderOrigin(argOr(args, "origin-oxts", ""), argOr(args, "origin", ""), origin,
                              error))
      return false;
    lat = origin.lat, lon = origin.lon, alt = origin.alt;
    initial_yaw = origin.yaw;
    if (origin.oxts) first_roll_pitch_ = Eigen::Vector2d(origin.oxts->roll, origin.oxts->pitch);
    if (origin.oxts && origin.oxts->pos_accuracy > 0.0) origin_std_ = origin.oxts->pos_accuracy;
    if (args.count("calib")) {
      // p_velo = T_velo_imu p_imu; base_link is the IMU frame: p_base = inv(T_velo_imu) p_velo.
      Eigen::Isometry3d T_velo_imu;
      if (!readImuToVeloCalib(args.at("calib"), T_velo_imu, error)) return false;
      sensor_to_base = T_velo_imu.inverse();
    } else {
      std::cerr << program << ": note: no --calib: base_link is the LiDAR frame\n";
    }
    return true;
  }
  size_t size() const override { return files_.size(); }
  bool next(DriveScan& scan) override {
    if (index_ >= files_.size()) return false;
    const size_t i = index_++;
    scan = DriveScan();
    scan.stamp = kFirstStamp + double(i) / rate_;
    auto cloud = std::make_shared<PointCloud>();
    if (readKittiBin(files_[i], *cloud, &scan.error)) scan.cloud = cloud;
    if (i == 0) {
      scan.gnss = Eigen::Vector2d::Zero();  // the georeference is the origin
      scan.gnss_std = origin_std_;
      scan.roll_pitch = first_roll_pitch_;
    }
    return true;
  }

 private:
  static bool fail(std::string* error, const std::string& why) {
    if (error) *error = why;
    return false;
  }
  static constexpr double kFirstStamp = 1.0;  ///< [s] (bags refuse stamp 0)
  std::vector<std::string> files_;
  double rate_ = 10.0;
  size_t index_ = 0;
  std::optional<Eigen::Vector2d> first_roll_pitch_;
  std::optional<double> origin_std_;  ///< the origin record's pos_accuracy
};

}  // namespace

ScanPrefetcher::ScanPrefetcher(DriveSource& source, size_t max_scans, size_t depth, Prepare prepare)
    : source_(source),
      max_scans_(max_scans),
      depth_(depth),
      prepare_(std::move(prepare)),
      thread_([this] { run(); }) {}

ScanPrefetcher::~ScanPrefetcher() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  changed_.notify_all();
  thread_.join();
}

bool ScanPrefetcher::next(DriveScan& scan) {
  std::unique_lock<std::mutex> lock(mutex_);
  changed_.wait(lock, [this] { return !queue_.empty() || done_; });
  if (queue_.empty()) return false;
  scan = std::move(queue_.front());
  queue_.pop_front();
  changed_.notify_all();
  return true;
}

void ScanPrefetcher::run() {
  for (size_t i = 0; i < max_scans_; ++i) {
    DriveScan scan;
    if (!source_.next(scan)) break;
    if (prepare_ && scan.cloud) {
      const auto t0 = std::chrono::steady_clock::now();
      prepare_(scan);
      scan.prepare_ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    }
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [this] { return queue_.size() < depth_ || stop_; });
    if (stop_) break;
    queue_.push_back(std::move(scan));
    changed_.notify_all();
  }
  std::lock_guard<std::mutex> lock(mutex_);
  done_ = true;
  changed_.notify_all();
}

void printProgress(size_t done, size_t total) {
  if (total == 0 || (done % 10 != 0 && done != total)) return;
  const int width = 40;
  const int filled = static_cast<int>(width * done / total);
  std::cerr << "\r[" << std::string(filled, '#') << std::string(width - filled, ' ') << "] " << done
            << "/" << total << (done == total ? "\n" : "") << std::flush;
}

std::unique_ptr<DriveSource> openDriveSource(const std::map<std::string, std::string>& args,
                                             const std::string& program, std::string* error,
                                             const SensorInputsParams& inputs) {
  if (args.count("kitti-raw") + args.count("bag") + args.count("scans") != 1) {
    if (error) *error = "exactly one of --kitti-raw, --bag and --scans is required";
    return nullptr;
  }
  if (args.count("kitti-raw")) {
    auto kitti = std::make_unique<KittiRawSource>();
    if (!kitti->open(args.at("kitti-raw"), argOr(args, "calib-dir", ""), error)) return nullptr;
    return kitti;
  }
  if (args.count("scans")) {
    auto folder = std::make_unique<ScanFolderSource>();
    if (!folder->open(args, program, error)) return nullptr;
    return folder;
  }
  BagDriveTopics topics;
  topics.cloud = argOr(args, "cloud-topic", topics.cloud);
  topics.gps = argOr(args, "gps-topic", topics.gps);
  topics.imu = argOr(args, "imu-topic", topics.imu);
  topics.ground_truth = argOr(args, "ground-truth-topic", topics.ground_truth);
  topics.base_frame = argOr(args, "base-frame", topics.base_frame);
  auto bag = std::make_unique<BagSource>(inputs);
  if (!bag->open(args.at("bag"), topics, error)) return nullptr;
  return bag;
}

}  // namespace osm_graph_slam
