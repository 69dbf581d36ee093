#include "osm_graph_slam/drive_io/dataset_bag.h"

#include <rosbag/bag.h>
#include <tf2_msgs/TFMessage.h>
#include <boost/make_shared.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "osm_graph_slam/drive_io/dataset_messages.h"
#include "osm_graph_slam/io/kitti_raw.h"
#include "osm_graph_slam/io/mulran.h"
#include "osm_graph_slam/osm/enu_converter.h"

namespace osm_graph_slam {
namespace {

/// Opens "<bag>.tmp" and renames it to the final path on commit(); removes it otherwise.
class AtomicBag {
 public:
  explicit AtomicBag(const std::string& path) : path_(path), tmp_(path + ".tmp") {}
  ~AtomicBag() {
    if (bag_.isOpen()) bag_.close();
    if (!committed_) std::remove(tmp_.c_str());
  }
  bool open(std::string& error) {
    try {
      bag_.open(tmp_, rosbag::bagmode::Write);
      bag_.setCompression(rosbag::compression::LZ4);
    } catch (const std::exception& e) {
      error = "cannot create bag '" + tmp_ + "': " + e.what();
      return false;
    }
    return true;
  }
  template <typename Msg>
  void write(const std::string& topic, const ros::Time& t, const Msg& msg) {
    bag_.write(topic, t, msg);
  }
  /// Writes msg on a latched connection ("latching: 1" in the connection header, as rosbag
  /// record stores a latched publisher): rosbag play then latches the topic, so that a
  /// subscriber connecting after the message was played still receives it.
  template <typename Msg>
  void writeLatched(const std::string& topic, const ros::Time& t, const Msg& msg) {
    auto& header = latched_headers_[topic];
    if (!header) {
      header = boost::make_shared<ros::M_string>();
      (*header)["type"] = ros::message_traits::datatype(msg);
      (*header)["md5sum"] = ros::message_traits::md5sum(msg);
      (*header)["message_definition"] = ros::message_traits::definition(msg);
      (*header)["callerid"] = "/kitti2bag";
      (*header)["latching"] = "1";
    }
    bag_.write(topic, t, msg, header);
  }
  bool commit(std::string& error) {
    try {
      bag_.close();
    } catch (const std::exception& e) {
      error = std::string("closing bag failed: ") + e.what();
      return false;
    }
    if (std::rename(tmp_.c_str(), path_.c_str()) != 0) {
      error = "cannot rename '" + tmp_ + "' to '" + path_ + "'";
      return false;
    }
    committed_ = true;
    return true;
  }

 private:
  std::string path_, tmp_;
  rosbag::Bag bag_;
  std::map<std::string, boost::shared_ptr<ros::M_string>> latched_headers_;
  bool committed_ = false;
};

BagConversionResult failed(BagConversionResult r, const std::string& error) {
  r.ok = false;
  r.error = error;
  return r;
}

/// tf_static once, latched (as tf2's static broadcaster publishes it): prefiltering gets the
/// sensor mounting even when it subscribes after the bag started.
void writeStaticTf(AtomicBag& bag, const std::vector<geometry_msgs::TransformStamped>& tfs,
                   const ros::Time& stamp, BagConversionResult& r) {
  tf2_msgs::TFMessage msg;
  msg.transforms = tfs;
  for (auto& t : msg.transforms) t.header.stamp = stamp;
  bag.writeLatched("tf_static", stamp, msg);
  r.tf_static += msg.transforms.size();
}

}  // namespace

BagConversionResult convertKittiRawToBag(const KittiRawBagOptions& o, const ProgressFn& progress) {
  BagConversionResult r;
  KittiRawDrive drive;
  std::string error;
  if (!openKittiRawDrive(o.drive_dir, o.calib_dir, drive, &error)) return failed(r, error);
  // Read every OXTS record first: a malformed one is reported before any bag is written.
  std::vector<OxtsRecord> oxts(drive.oxts_files.size());
  for (size_t i = 0; i < oxts.size(); ++i) {
    if (!readOxtsFile(drive.oxts_files[i], oxts[i], &error)) return failed(r, error);
  }
  // The simulator's exact records (oxts_true/) are the ground truth when present; oxts/ then
  // holds what its GNSS/INS measured.
  std::vector<OxtsRecord> truth(drive.truth_oxts_files.size());
  for (size_t i = 0; i < truth.size(); ++i) {
    if (!readOxtsFile(drive.truth_oxts_files[i], truth[i], &error)) return failed(r, error);
  }
  AtomicBag bag(o.bag_path);
  if (!bag.open(error)) return failed(r, error);

  const ros::Time first = toRosTime(
      std::min(drive.scan_stamps.front(),
               drive.oxts_stamps.empty() ? drive.scan_stamps.front() : drive.oxts_stamps.front()));
  // base_link is the IMU (OXTS) frame, as in the KITTI raw devkit.
  writeStaticTf(bag,
                {makeTransform(drive.T_velo_imu.inverse(), o.base_frame, o.velo_frame, first),
                 makeTransform(Eigen::Isometry3d::Identity(), o.base_frame, o.imu_frame, first)},
                first, r);

  const size_t total = drive.scan_files.size() + oxts.size() + truth.size();
  size_t done = 0;
  if (!oxts.empty()) {
    // The ENU frame of the ground truth is anchored at the first fix (the pipeline's origin); a
    // record without a fix (outage) becomes a NavSatFix with STATUS_NO_FIX.
    size_t anchor = 0;
    while (anchor + 1 < oxts.size() && !oxts[anchor].hasGnssFix()) ++anchor;
    const EnuConverter enu(oxts[anchor].lat, oxts[anchor].lon, oxts[anchor].alt);
    auto writeTruth = [&](const OxtsRecord& x, const ros::Time& t) {
      Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
      pose.translation() = enu.toEnu(x.lat, x.lon, x.alt);
      pose.linear() = quaternionFromRpy(x.roll, x.pitch, x.yaw).toRotationMatrix();
      bag.write(
          o.ground_truth_topic, t,
          makeOdometry(pose, o.enu_frame, o.base_frame, t, {x.vf, x.vl, x.vu}, {x.wf, x.wl, x.wu}));
      ++r.ground_truth;
    };
    for (size_t i = 0; i < oxts.size(); ++i) {
      const OxtsRecord& x = oxts[i];
      const ros::Time t = toRosTime(drive.oxts_stamps[i]);
      bag.write(o.gps_topic, t, makeNavSatFix(x, o.imu_frame, t));
      bag.write(o.imu_topic, t, makeImuFromOxts(x, o.imu_frame, t));
      if (truth.empty()) writeTruth(x, t);
      ++r.gps;
      ++r.imu;
      if (progress) progress(++done, total);
    }
    for (size_t i = 0; i < truth.size(); ++i) {
      writeTruth(truth[i], toRosTime(drive.truth_oxts_stamps[i]));
      if (progress) progress(++done, total);
    }
  }
  std::vector<float> xyzi;
  for (size_t i = 0; i < drive.scan_files.size(); ++i) {
    if (!readFloat32Records(drive.scan_files[i], xyzi, &error)) return failed(r, error);
    const ros::Time t = toRosTime(drive.scan_stamps[i]);
    bag.write(o.cloud_topic, t, makeXyziCloud(xyzi, o.velo_frame, t));
    ++r.clouds;
    if (progress) progress(++done, total);
  }
  if (!bag.commit(error)) return failed(r, error);
  r.ok = true;
  return r;
}

BagConversionResult convertKittiOdometryToBag(const KittiOdometryBagOptions& o,
                                              const ProgressFn& progress) {
  BagConversionResult r;
  KittiOdometrySequence seq;
  std::string error;
  if (!openKittiOdometrySequence(o.sequence_dir, o.poses_path, seq, &error)) {
    return failed(r, error);
  }
  if (o.start_time + (seq.times.empty() ? 0.0 : seq.times.front()) <= 0.0) {
    return failed(r, "start_time + first time must be > 0 (rosbag rejects stamp 0)");
  }
  AtomicBag bag(o.bag_path);
  if (!bag.open(error)) return failed(r, error);
  const auto lidar_poses = seq.lidarPoses();
  const int64_t start_ns = std::llround(o.start_time * 1e9);
  std::vector<float> xyzi;
  for (size_t i = 0; i < seq.scan_files.size(); ++i) {
    if (!readFloat32Records(seq.scan_files[i], xyzi, &error)) return failed(r, error);
    const ros::Time t = toRosTime(start_ns + std::llround(seq.times[i] * 1e9));
    bag.write(o.cloud_topic, t, makeXyziCloud(xyzi, o.velo_frame, t));
    ++r.clouds;
    if (i < lidar_poses.size()) {
      bag.write(o.ground_truth_topic, t,
                makeOdometry(lidar_poses[i], o.world_frame, o.velo_frame, t));
      ++r.ground_truth;
    }
    if (progress) progress(i + 1, seq.scan_files.size());
  }
  if (!bag.commit(error)) return failed(r, error);
  r.ok = true;
  return r;
}

namespace {

/// The stamp of the OXTS record at path when it sits in a KITTI raw oxts/data/ folder beside
/// its timestamps.txt (oxts/data/0000000000.txt -> line 0 of oxts/timestamps.txt).
std::optional<StampNs> oxtsRecordStamp(const std::string& path) {
  namespace fs = std::filesystem;
  const fs::path p(path);
  if (p.parent_path().filename() != "data") return std::nullopt;
  const fs::path stamps_path = p.parent_path().parent_path() / "timestamps.txt";
  const std::string stem = p.stem().string();
  if (stem.empty() || stem.find_first_not_of("0123456789") != std::string::npos ||
      !fs::exists(stamps_path))
    return std::nullopt;
  std::vector<StampNs> stamps;
  if (!readKittiTimestamps(stamps_path.string(), stamps)) return std::nullopt;
  const size_t index = std::stoul(stem);
  if (index >= stamps.size()) return std::nullopt;
  return stamps[index];
}

}  // namespace

BagConversionResult convertScanFolderToBag(const ScanFolderBagOptions& o,
                                           const ProgressFn& progress) {
  namespace fs = std::filesystem;
  BagConversionResult r;
  std::string error;
  if (!fs::is_directory(o.scans_dir))
    return failed(r, "scan folder '" + o.scans_dir + "' does not exist or is not a folder");
  const std::vector<std::string> files = listFiles(o.scans_dir, ".bin");
  if (files.empty()) return failed(r, "no .bin scans in '" + o.scans_dir + "'");
  if (!(o.rate > 0.0) || !std::isfinite(o.rate)) return failed(r, "--rate must be > 0");
  ScanFolderOrigin origin;
  if (!readScanFolderOrigin(o.origin_oxts, o.origin, origin, &error)) return failed(r, error);
  // base_link is the OXTS unit as in KITTI raw: base_link -> velo_link = inv(T_velo_imu).
  Eigen::Isometry3d T_velo_imu = Eigen::Isometry3d::Identity();
  if (!o.calib_path.empty()) {
    if (!readImuToVeloCalib(o.calib_path, T_velo_imu, &error)) return failed(r, error);
  } else {
    r.warnings.push_back("no calibration: base_link is the LiDAR frame (tf_static identity)");
  }
  StampNs start_ns = 0;
  if (o.start_time >= 0.0) {
    start_ns = std::llround(o.start_time * 1e9);
  } else if (const auto stamp =
                 o.origin_oxts.empty() ? std::nullopt : oxtsRecordStamp(o.origin_oxts)) {
    start_ns = *stamp;
  } else {
    start_ns = std::llround(kScanFolderDefaultStart * 1e9);
  }
  if (start_ns <= 0) return failed(r, "the start time must be > 0 (rosbag rejects stamp 0)");
  auto stampOf = [&](size_t i) {
    return toRosTime(start_ns + std::llround(static_cast<double>(i) * 1e9 / o.rate));
  };

  AtomicBag bag(o.bag_path);
  if (!bag.open(error)) return failed(r, error);
  const ros::Time first = stampOf(0);
  r.first_stamp = first.toSec();
  writeStaticTf(bag,
                {makeTransform(T_velo_imu.inverse(), o.base_frame, o.velo_frame, first),
                 makeTransform(Eigen::Isometry3d::Identity(), o.base_frame, o.imu_frame, first)},
                first, r);
  // The one georeference: a fix at the first scan (the map origin), and the attitude there.
  // Both latched: a node that subscribes late (or is restarted) still gets the georeference.
  if (origin.oxts) {
    bag.writeLatched(o.gps_topic, first, makeNavSatFix(*origin.oxts, o.imu_frame, first));
    bag.writeLatched(o.imu_topic, first, makeImuFromOxts(*origin.oxts, o.imu_frame, first));
    ++r.imu;
  } else {
    OxtsRecord fix;
    fix.lat = origin.lat;
    fix.lon = origin.lon;
    fix.alt = origin.alt;
    sensor_msgs::NavSatFix msg = makeNavSatFix(fix, o.imu_frame, first);
    msg.position_covariance = {};
    msg.position_covariance_type = sensor_msgs::NavSatFix::COVARIANCE_TYPE_UNKNOWN;
    bag.writeLatched(o.gps_topic, first, msg);
    if (origin.yaw) {
      // Only a heading is known: roll and pitch are taken as level, rates and accelerations as
      // not available (REP-145).
      sensor_msgs::Imu imu;
      imu.header.frame_id = o.imu_frame;
      imu.header.stamp = first;
      const Eigen::Quaterniond q = quaternionFromRpy(0.0, 0.0, *origin.yaw);
      imu.orientation.x = q.x();
      imu.orientation.y = q.y();
      imu.orientation.z = q.z();
      imu.orientation.w = q.w();
      const double rp = std::pow(2.0 * M_PI / 180.0, 2), yaw = std::pow(1.0 * M_PI / 180.0, 2);
      imu.orientation_covariance = {rp, 0, 0, 0, rp, 0, 0, 0, yaw};
      imu.angular_velocity_covariance[0] = -1.0;
      imu.linear_acceleration_covariance[0] = -1.0;
      bag.writeLatched(o.imu_topic, first, imu);
      ++r.imu;
      r.warnings.push_back(
          "--origin: imu/data at the first scan has the given yaw and roll = "
          "pitch = 0");
    } else {
      r.warnings.push_back(
          "no yaw in --origin: no imu/data; the initial heading must come from global matching");
    }
  }
  ++r.gps;

  std::vector<float> xyzi;
  for (size_t i = 0; i < files.size(); ++i) {
    if (!readFloat32Records(files[i], xyzi, &error)) {
      r.warnings.push_back(error + " (scan " + std::to_string(i) + " skipped)");
      ++r.skipped;
    } else if (xyzi.empty()) {
      r.warnings.push_back("scan '" + files[i] + "' has no points (scan " + std::to_string(i) +
                           " skipped)");
      ++r.skipped;
    } else {
      const ros::Time t = stampOf(i);
      bag.write(o.cloud_topic, t, makeXyziCloud(xyzi, o.velo_frame, t));
      ++r.clouds;
    }
    if (progress) progress(i + 1, files.size());
  }
  if (r.clouds == 0)
    return failed(r, "none of the " + std::to_string(files.size()) + " .bin files in '" +
                         o.scans_dir + "' is a readable scan");
  if (!bag.commit(error)) return failed(r, error);
  r.ok = true;
  return r;
}

namespace {

/// MulRan extrinsics (base_link = vehicle rear axle frame of the MulRan calibration).
Eigen::Isometry3d mulranExtrinsic(double x, double y, double z, double roll_deg, double pitch_deg,
                                  double yaw_deg) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, z);
  T.linear() =
      quaternionFromRpy(roll_deg * M_PI / 180.0, pitch_deg * M_PI / 180.0, yaw_deg * M_PI / 180.0)
          .toRotationMatrix();
  return T;
}

bool readMono8(const std::string& path, sensor_msgs::Image& msg, const std::string& frame,
               const ros::Time& t, std::string& error) {
  cv::Mat img = cv::imread(path, cv::IMREAD_UNCHANGED);
  if (img.empty()) {
    error = "cannot read radar image '" + path + "'";
    return false;
  }
  if (img.channels() == 3) cv::cvtColor(img, img, cv::COLOR_BGR2GRAY);
  if (img.channels() == 4) cv::cvtColor(img, img, cv::COLOR_BGRA2GRAY);
  if (img.depth() == CV_16U) img.convertTo(img, CV_8U, 1.0 / 256.0);
  if (img.type() != CV_8UC1) {
    error = "radar image '" + path + "' is not an 8-bit grey image";
    return false;
  }
  msg = makeMono8Image(img.rows, img.cols, img.data, img.step, frame, t);
  return true;
}

}  // namespace

BagConversionResult convertMulranToBag(const MulranBagOptions& o, const ProgressFn& progress) {
  BagConversionResult r;
  MulranSequence seq;
  std::string error;
  if (!readMulranSequence(o.root, seq, &error)) return failed(r, error);
  AtomicBag bag(o.bag_path);
  if (!bag.open(error)) return failed(r, error);

  int64_t first_ns = INT64_MAX;
  for (const auto& s : seq.stamps) first_ns = std::min(first_ns, s.stamp_ns);
  for (const auto& g : seq.gps) first_ns = std::min(first_ns, g.stamp_ns);
  for (const auto& m : seq.imu) first_ns = std::min(first_ns, m.stamp_ns);
  if (first_ns == INT64_MAX || first_ns <= 0) return failed(r, "MulRan sequence has no stamps");
  const ros::Time first = toRosTime(first_ns);
  writeStaticTf(bag,
                {makeTransform(mulranExtrinsic(1.7042, -0.021, 1.8047, 0.0001, 0.0003, 179.6654),
                               o.base_frame, o.ouster_frame, first),
                 makeTransform(mulranExtrinsic(1.50, -0.04, 1.97, 0.0, 0.0, 0.9), o.base_frame,
                               o.radar_frame, first),
                 makeTransform(Eigen::Isometry3d::Identity(), o.base_frame, o.imu_frame, first),
                 makeTransform(Eigen::Isometry3d::Identity(), o.base_frame, o.gps_frame, first)},
                first, r);

  const size_t total = seq.stamps.size() + seq.gps.size() + seq.imu.size() + seq.poses.size();
  size_t done = 0;
  auto tick = [&] {
    if (progress) progress(++done, total);
  };
  for (const auto& g : seq.gps) {
    sensor_msgs::NavSatFix fix;
    fix.header.frame_id = o.gps_frame;
    fix.header.stamp = toRosTime(g.stamp_ns);
    fix.status.status = sensor_msgs::NavSatStatus::STATUS_FIX;
    fix.status.service = sensor_msgs::NavSatStatus::SERVICE_GPS;
    fix.latitude = g.lat;
    fix.longitude = g.lon;
    fix.altitude = g.alt;
    std::copy(g.covariance.begin(), g.covariance.end(), fix.position_covariance.begin());
    fix.position_covariance_type = sensor_msgs::NavSatFix::COVARIANCE_TYPE_KNOWN;
    bag.write(o.gps_topic, fix.header.stamp, fix);
    ++r.gps;
    tick();
  }
  for (const auto& m : seq.imu) {
    sensor_msgs::Imu imu;
    imu.header.frame_id = o.imu_frame;
    imu.header.stamp = toRosTime(m.stamp_ns);
    imu.orientation.x = m.orientation.x();
    imu.orientation.y = m.orientation.y();
    imu.orientation.z = m.orientation.z();
    imu.orientation.w = m.orientation.w();
    imu.orientation_covariance = {1e-4, 0, 0, 0, 1e-4, 0, 0, 0, 1e-3};
    if (m.has_rates) {
      imu.angular_velocity.x = m.gyro.x();
      imu.angular_velocity.y = m.gyro.y();
      imu.angular_velocity.z = m.gyro.z();
      imu.linear_acceleration.x = m.acc.x();
      imu.linear_acceleration.y = m.acc.y();
      imu.linear_acceleration.z = m.acc.z();
    } else {
      imu.angular_velocity_covariance[0] = -1.0;  // REP-145: not available
      imu.linear_acceleration_covariance[0] = -1.0;
    }
    bag.write(o.imu_topic, imu.header.stamp, imu);
    ++r.imu;
    tick();
  }
  if (!seq.poses.empty()) {
    const Eigen::Isometry3d origin_inv =
        o.absolute_ground_truth ? Eigen::Isometry3d::Identity() : seq.poses.front().pose.inverse();
    for (const auto& p : seq.poses) {
      const ros::Time t = toRosTime(p.stamp_ns);
      bag.write(o.ground_truth_topic, t,
                makeOdometry(origin_inv * p.pose, o.world_frame, o.base_frame, t));
      ++r.ground_truth;
      tick();
    }
  }
  std::vector<float> xyzi;
  for (const auto& s : seq.stamps) {
    const ros::Time t = toRosTime(s.stamp_ns);
    if (s.sensor == "ouster") {
      const std::string path = seq.ousterPath(s.stamp_ns);
      if (o.skip_missing && !std::filesystem::exists(path)) {
        tick();
        continue;
      }
      if (!readFloat32Records(path, xyzi, &error)) return failed(r, error);
      bag.write(o.cloud_topic, t, makeXyziCloud(xyzi, o.ouster_frame, t));
      ++r.clouds;
    } else if (s.sensor == "radar") {
      const std::string path = seq.radarPolarPath(s.stamp_ns);
      if (o.skip_missing && !std::filesystem::exists(path)) {
        tick();
        continue;
      }
      sensor_msgs::Image img;
      if (!readMono8(path, img, o.radar_frame, t, error)) return failed(r, error);
      bag.write(o.radar_topic, t, img);
      ++r.images;
    }
    tick();
  }
  if (!bag.commit(error)) return failed(r, error);
  r.ok = true;
  return r;
}

ProgressFn stderrProgressBar(const std::string& label) {
  auto last_percent = std::make_shared<int>(-1);
  return [label, last_percent](size_t done, size_t total) {
    const int percent = total ? static_cast<int>(100 * done / total) : 100;
    if (percent == *last_percent && done != total) return;
    *last_percent = percent;
    const int width = 40, filled = width * percent / 100;
    std::fprintf(stderr, "\r%s [%s%s] %3d%% %zu/%zu", label.c_str(),
                 std::string(filled, '=').c_str(), std::string(width - filled, ' ').c_str(),
                 percent, done, total);
    if (done >= total) std::fprintf(stderr, "\n");
    std::fflush(stderr);
  };
}

}  // namespace osm_graph_slam
