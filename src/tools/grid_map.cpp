// grid_map: the occupancy grid (cloud/occupancy_grid.h) of a dump (offline_slam --dump, the
// nodelet's dump_graph) at the poses of a TUM trajectory matched by stamp, written as map_server's
// map.pgm + map.yaml. With the run's own trajectory_tum.txt it gives save_map's grid again; with
// ground_truth_tum.txt it shows the grid's own errors apart from the SLAM's pose errors
// (scripts/evaluate_grid.py compares either with the true footprints).
#include <pcl/io/pcd_io.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <iomanip>
#include <iostream>
#include <iterator>
#include <map>
#include <sstream>
#include <vector>

#include "osm_graph_slam/cloud/occupancy_grid.h"
#include "osm_graph_slam/io/map_server_files.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/slam/graph_dump.h"
#include "osm_graph_slam/slam/pipeline_params_io.h"
#include "support/command_line.h"
#include "support/pipeline_config.h"

using namespace osm_graph_slam;
using osm_graph_slam::tools::CommandLine;

namespace {

/// [s] a keyframe's pose is the trajectory's pose at its stamp, within this (the runs write the
/// keyframes' stamps; interpolating would invent poses the trajectory does not hold).
constexpr double kStampTolerance = 1e-3;

/// The pose stamped nearest to t, if within kStampTolerance (poses in time order).
bool poseAt(const Trajectory& poses, double t, Eigen::Isometry3d* pose) {
  const auto after = std::lower_bound(poses.begin(), poses.end(), t,
                                      [](const StampedPose& p, double s) { return p.stamp < s; });
  for (auto it : {after, after == poses.begin() ? after : std::prev(after)}) {
    if (it != poses.end() && std::abs(it->stamp - t) <= kStampTolerance) {
      *pose = it->pose;
      return true;
    }
  }
  return false;
}

std::string cloudPath(const std::string& dump, uint64_t id) {
  char name[64];
  std::snprintf(name, sizeof(name), "/keyframes/%06lu.pcd", static_cast<unsigned long>(id));
  return dump + name;
}

double msSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
      .count();
}

double threadCpuMs() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return t.tv_sec * 1e3 + t.tv_nsec * 1e-6;
}

/// "median m ms, 95 % p ms, max x ms" of a sorted list.
std::string spread(const std::vector<double>& sorted_ms) {
  if (sorted_ms.empty()) return "none";
  std::ostringstream os;
  os << std::fixed << std::setprecision(2) << "median " << sorted_ms[sorted_ms.size() / 2]
     << " ms, 95 % " << sorted_ms[sorted_ms.size() * 95 / 100] << " ms, max " << sorted_ms.back()
     << " ms";
  return os.str();
}

struct Built {
  size_t inserted = 0, without_pose = 0, without_cloud = 0;
  std::vector<double> insert_ms;
  std::vector<double> extract_ms;     ///< of insert_ms: reading the cloud (ground, obstacles, rays)
  std::vector<double> insert_cpu_ms;  ///< the thread's CPU time: without a loaded machine's waits
};

Built buildGrid(OccupancyGrid& grid, const GraphDump& dump, const std::string& dump_dir,
                const Trajectory& poses) {
  Built built;
  for (const KeyframeInput& kf : dump.keyframes) {
    Eigen::Isometry3d pose;
    if (!poseAt(poses, kf.stamp, &pose)) {
      ++built.without_pose;
      continue;
    }
    PointCloud cloud;
    if (pcl::io::loadPCDFile(cloudPath(dump_dir, kf.id), cloud) != 0 || cloud.empty()) {
      ++built.without_cloud;
      continue;
    }
    const double cpu_start = threadCpuMs();
    const auto start = std::chrono::steady_clock::now();
    PlanarScan scan = extractPlanarScan(cloud, Eigen::Vector3f::Zero(), kf.floor, grid.params());
    built.extract_ms.push_back(msSince(start));
    grid.insertScan(kf.id, pose, std::move(scan));
    built.insert_ms.push_back(msSince(start));
    built.insert_cpu_ms.push_back(threadCpuMs() - cpu_start);
    ++built.inserted;
  }
  return built;
}

}  // namespace

int main(int argc, char** argv) {
  CommandLine cli("grid_map",
                  "The occupancy grid of a dump_graph directory at the poses of a TUM trajectory "
                  "(matched by keyframe stamp), as map_server's map.pgm + map.yaml.");
  cli.option("--dump", "DIR", "the dump (offline_slam --dump, dump_graph) with keyframe clouds")
      .required()
      .option("--trajectory", "TUM",
              "the poses: the run's trajectory_tum.txt, or ground_truth_tum.txt")
      .required()
      .option("--output", "DIR", "where map.pgm and map.yaml go (the folder must exist)")
      .required()
      .option("--config", "OVERRIDES.yaml",
              "parameter overrides (the grid_* keys of graph_backend)")
      .defaultText("config/kitti.yaml");
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  std::map<std::string, std::string> args = cli.values();

  SlamPipelineParams params;
  std::string error;
  if (!tools::loadToolConfig(args, params, &error)) {
    std::cerr << "grid_map: " << error << "\n";
    return 1;
  }
  const std::string grid_error = occupancyGridParamsError(params.backend.grid);
  if (!grid_error.empty()) {
    std::cerr << "grid_map: " << grid_error << "\n";
    return 1;
  }
  GraphDump dump;
  if (!readGraphDump(args["dump"], dump, &error)) {
    std::cerr << "grid_map: " << error << "\n";
    return 1;
  }
  const TrajectoryReadResult poses = readTrajectory(args["trajectory"]);
  if (!poses.ok) {
    std::cerr << "grid_map: " << poses.error << "\n";
    return 1;
  }

  OccupancyGrid grid(params.backend.grid);
  Built built = buildGrid(grid, dump, args["dump"], poses.trajectory);
  // What an optimisation that moves every keyframe costs (each moved one: out, then in again).
  const auto rerender_start = std::chrono::steady_clock::now();
  grid.rerender();
  const double rerender_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - rerender_start)
          .count();
  const auto image_start = std::chrono::steady_clock::now();
  const OccupancyGridImage image = grid.image();  // what the nodelet publishes per optimisation
  const double image_ms = msSince(image_start);
  const std::string out = args["output"];
  if (image.cells.empty() || !writeFileAtomically(out + "/map.pgm", mapServerPgm(image), &error) ||
      !writeFileAtomically(out + "/map.yaml", mapServerYaml(image, "map.pgm"), &error)) {
    std::cerr << "grid_map: " << (image.cells.empty() ? "no grid cell" : error) << "\n";
    return 1;
  }
  std::sort(built.insert_ms.begin(), built.insert_ms.end());
  std::sort(built.extract_ms.begin(), built.extract_ms.end());
  std::sort(built.insert_cpu_ms.begin(), built.insert_cpu_ms.end());
  std::cout << std::fixed << std::setprecision(2) << "grid_map: " << built.inserted
            << " keyframes (" << built.without_pose << " without a pose, " << built.without_cloud
            << " without a cloud), " << image.width << " x " << image.height << " cells of "
            << image.resolution << " m\n  insert per keyframe: " << spread(built.insert_ms)
            << "\n  the same in CPU time: " << spread(built.insert_cpu_ms)
            << "\n  of which reading the cloud: " << spread(built.extract_ms)
            << "\n  re-rendering all keyframes: " << rerender_ms << " ms; the image: " << image_ms
            << " ms\n";
  return 0;
}
