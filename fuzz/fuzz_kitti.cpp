// KITTI raw / odometry readers. The first input byte picks the reader, the rest is the file (or
// the text): timestamps.txt, one OXTS record, calib_imu_to_velo.txt, a tracking-layout calib
// file, a poses file, a .bin scan, a --origin text, an odometry sequence's times.txt or calib.txt.
#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "fuzz_util.h"
#include "osm_graph_slam/io/kitti_bin.h"
#include "osm_graph_slam/io/kitti_raw.h"

namespace {

namespace ogs = osm_graph_slam;

/// sequences/00 with one scan, a valid times.txt and calib.txt; the fuzzed file replaces one.
std::string sequenceDir() {
  static const std::string dir = [] {
    const std::string d = ogs_fuzz::scratchPath("sequences/00");
    std::filesystem::create_directories(d + "/velodyne");
    ogs_fuzz::writeFile(d + "/velodyne/000000.bin", std::string(16, '\0'));
    return d;
  }();
  return dir;
}

const char* const kValidTimes = "0.000000e+00\n";
const char* const kValidCalib = "P0: 1 0 0 0 0 1 0 0 0 0 1 0\nTr: 1 0 0 0 0 1 0 0 0 0 1 0\n";

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const uint8_t selector = data[0] % 9;
  const uint8_t* body = data + 1;
  const size_t body_size = size - 1;
  const std::string text(reinterpret_cast<const char*>(body), body_size);
  std::string error;
  Eigen::Isometry3d T;
  switch (selector) {
    case 0: {
      const std::string path = ogs_fuzz::scratchPath("timestamps.txt");
      ogs_fuzz::writeFile(path, body, body_size);
      std::vector<ogs::StampNs> stamps;
      if (ogs::readKittiTimestamps(path, stamps, &error)) {
        for (const ogs::StampNs s : stamps) ogs::formatKittiTimestamp(s);
      }
      break;
    }
    case 1: {
      const std::string path = ogs_fuzz::scratchPath("oxts.txt");
      ogs_fuzz::writeFile(path, body, body_size);
      ogs::OxtsRecord record;
      if (ogs::readOxtsFile(path, record, &error)) record.hasGnssFix();
      ogs::ScanFolderOrigin origin;
      ogs::readScanFolderOrigin(path, "", origin, &error);
      break;
    }
    case 2: {
      const std::string path = ogs_fuzz::scratchPath("calib_imu_to_velo.txt");
      ogs_fuzz::writeFile(path, body, body_size);
      ogs::readKittiRigidCalib(path, T, &error);
      ogs::readImuToVeloCalib(path, T, &error);
      break;
    }
    case 3: {
      const std::string path = ogs_fuzz::scratchPath("calib.txt");
      ogs_fuzz::writeFile(path, body, body_size);
      ogs::readKittiTrackingCalib(path, "Tr_velo_to_cam", T, &error);
      break;
    }
    case 4: {
      const std::string path = ogs_fuzz::scratchPath("poses.txt");
      ogs_fuzz::writeFile(path, body, body_size);
      std::vector<Eigen::Isometry3d> poses;
      ogs::readKittiPoses(path, poses, &error);
      break;
    }
    case 5: {
      const std::string path = ogs_fuzz::scratchPath("scan.bin");
      ogs_fuzz::writeFile(path, body, body_size);
      std::vector<float> values;
      ogs::readFloat32Records(path, values, &error);
      ogs::PointCloud cloud;
      ogs::readKittiBin(path, cloud, &error);
      break;
    }
    case 6: {
      ogs::ScanFolderOrigin origin;
      ogs::readScanFolderOrigin("", text, origin, &error);
      ogs::StampNs stamp;
      if (ogs::parseKittiTimestamp(text, stamp)) ogs::formatKittiTimestamp(stamp);
      break;
    }
    case 7:
    case 8: {
      const std::string dir = sequenceDir();
      ogs_fuzz::writeFile(dir + "/times.txt", selector == 7 ? text : std::string(kValidTimes));
      ogs_fuzz::writeFile(dir + "/calib.txt", selector == 8 ? text : std::string(kValidCalib));
      ogs::KittiOdometrySequence sequence;
      if (ogs::openKittiOdometrySequence(dir, "", sequence, &error)) sequence.lidarPoses();
      break;
    }
  }
  return 0;
}
