#pragma once
// The options that name a drive for openDriveSource() (drive_io/drive_source.h), shared by the
// offline runners (offline_slam, offline_localization, offline_osm_localization): declared here
// once so that their spelling and help agree. Read them back with CommandLine::values().
#include "osm_graph_slam/drive_io/bag_drive_reader.h"
#include "support/command_line.h"

namespace osm_graph_slam::tools {

inline void addDriveSourceOptions(CommandLine& cli) {
  const BagDriveTopics topics;
  cli.option("--kitti-raw", "DRIVE_DIR", "a KITTI raw drive folder (real or simulate_urban's)")
      .option("--calib-dir", "DIR",
              "--kitti-raw: the folder of the calib_*.txt files (default: the drive folder, then "
              "its parent)")
      .option("--bag", "FILE.bag", "a bag as kitti2bag writes it")
      .option("--scans", "DIR",
              "a folder of KITTI .bin scans with one georeference (--origin-oxts or --origin)")
      .option("--origin-oxts", "FILE", "--scans: the OXTS record of the first scan")
      .option("--origin", "LAT,LON,ALT[,YAW_DEG]", "--scans: the georeference of the first scan")
      .option("--rate", "HZ", "--scans: the scan rate")
      .defaultText("10")
      .option("--calib", "FILE",
              "--scans: the LiDAR mounting (calib_imu_to_velo.txt or a tracking-layout file with "
              "Tr_imu_to_velo); without it base_link is the LiDAR frame")
      .option("--cloud-topic", "T", "--bag: the point cloud topic")
      .defaultText(topics.cloud)
      .option("--gps-topic", "T", "--bag: the GNSS fix topic")
      .defaultText(topics.gps)
      .option("--imu-topic", "T", "--bag: the IMU topic")
      .defaultText(topics.imu)
      .option("--ground-truth-topic", "T", "--bag: the ground-truth odometry topic")
      .defaultText(topics.ground_truth)
      .option("--base-frame", "F", "--bag: the vehicle frame")
      .defaultText(topics.base_frame);
}

}  // namespace osm_graph_slam::tools
