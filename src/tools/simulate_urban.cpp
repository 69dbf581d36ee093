// simulate_urban: a simulated urban LiDAR drive (KITTI raw layout + ground truth + perturbed OSM
// prior). See doc/simulator.md.
#include <cstdio>
#include <cstdlib>
#include <string>

#include "osm_graph_slam/ros/dataset_bag.h"
#include "osm_graph_slam/sim/simulator.h"

using namespace osm_graph_slam;
using namespace osm_graph_slam::sim;

namespace {

void usage() {
  std::fprintf(stderr,
               "usage: simulate_urban --out DIR [options]\n"
               "  --osm FILE              OSM extract (.osm/.osm.pbf); default: procedural city\n"
               "  --seed N                (default 1)\n"
               "  --length M              route length [m] (default 1500)\n"
               "  --speed V               cruise speed [m/s] (default 8)\n"
               "  --scans N               stop after N scans (default: whole route)\n"
               "  --sensor hdl64e|os1_64  (default hdl64e)\n"
               "  --motion-distortion     per-column sensor poses (default off)\n"
               "  --origin LAT,LON[,ALT]  ENU origin (default: extract centre / Karlsruhe)\n"
               "  --no-clutter            buildings and ground only\n"
               "  --blocks NX,NY          procedural city size in blocks (default 7,6)\n"
               "  --prior-translation-sigma M (1.0)  --prior-rotation-sigma-deg D (2.0)\n"
               "  --prior-removal F (0.05)  --prior-phantom F (0.03)\n"
               "  --dropout P (0.02)  --range-noise M (0.02)\n"
               "  --elevation-bias-deg D (0)  --beam-elevation-sigma-deg D (0)\n"
               "  --beam-range-offset-sigma M (0)   intrinsic calibration errors\n"
               "  --kitti-calibration-error   = 0.22 deg bias, 0.1 deg / 2 cm per beam\n");
}

}  // namespace

int main(int argc, char** argv) {
  SimulationParams p;
  std::string out;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "simulate_urban: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--out")
      out = next();
    else if (a == "--osm")
      p.osm_path = next();
    else if (a == "--seed")
      p.seed = std::strtoull(next().c_str(), nullptr, 10);
    else if (a == "--length")
      p.route.length = std::atof(next().c_str());
    else if (a == "--speed")
      p.route.cruise_speed = std::atof(next().c_str());
    else if (a == "--scans")
      p.max_scans = std::atoi(next().c_str());
    else if (a == "--motion-distortion")
      p.motion_distortion = true;
    else if (a == "--no-clutter")
      p.clutter_enabled = false;
    else if (a == "--sensor") {
      const std::string s = next();
      if (s == "hdl64e")
        p.lidar = LidarModel::hdl64e();
      else if (s == "os1_64")
        p.lidar = LidarModel::os1_64();
      else {
        std::fprintf(stderr, "simulate_urban: unknown sensor '%s'\n", s.c_str());
        return 2;
      }
    } else if (a == "--origin") {
      const std::string s = next();
      if (std::sscanf(s.c_str(), "%lf,%lf,%lf", &p.origin_lat, &p.origin_lon, &p.origin_alt) < 2) {
        std::fprintf(stderr, "simulate_urban: --origin expects LAT,LON[,ALT]\n");
        return 2;
      }
    } else if (a == "--blocks") {
      if (std::sscanf(next().c_str(), "%d,%d", &p.city.blocks_x, &p.city.blocks_y) != 2) return 2;
    } else if (a == "--prior-translation-sigma")
      p.prior.translation_sigma = std::atof(next().c_str());
    else if (a == "--prior-rotation-sigma-deg")
      p.prior.rotation_sigma_deg = std::atof(next().c_str());
    else if (a == "--prior-removal")
      p.prior.removal_fraction = std::atof(next().c_str());
    else if (a == "--prior-phantom")
      p.prior.phantom_fraction = std::atof(next().c_str());
    else if (a == "--dropout")
      p.lidar.dropout_probability = std::atof(next().c_str());
    else if (a == "--range-noise")
      p.lidar.range_noise_sigma = std::atof(next().c_str());
    else if (a == "--elevation-bias-deg")
      p.lidar.elevation_bias_deg = std::atof(next().c_str());
    else if (a == "--beam-elevation-sigma-deg")
      p.lidar.beam_elevation_sigma_deg = std::atof(next().c_str());
    else if (a == "--beam-range-offset-sigma")
      p.lidar.beam_range_offset_sigma = std::atof(next().c_str());
    else if (a == "--kitti-calibration-error") {
      p.lidar.elevation_bias_deg = 0.22;
      p.lidar.beam_elevation_sigma_deg = 0.1;
      p.lidar.beam_range_offset_sigma = 0.02;
    } else {
      usage();
      return 2;
    }
  }
  if (out.empty()) {
    usage();
    return 2;
  }
  UrbanSimulator sim;
  std::string error;
  if (!sim.build(p, &error)) {
    std::fprintf(stderr, "simulate_urban: %s\n", error.c_str());
    return 1;
  }
  std::fprintf(stderr,
               "simulate_urban: %zu buildings, %zu clutter primitives, %zu moving objects; route "
               "%.0f m, %.0f s, %zu scans\n",
               sim.scene().world.buildings.size(), sim.scene().world.primitives.size(),
               sim.scene().world.moving.size(), sim.trajectory().length(),
               sim.trajectory().duration(), sim.numScans());
  SimulationStats stats;
  if (!sim.writeDataset(out, stats, stderrProgressBar("simulate_urban"), &error)) {
    std::fprintf(stderr, "\nsimulate_urban: %s\n", error.c_str());
    return 1;
  }
  std::printf(
      "drive: %s\nscans: %zu\nroute_length_m: %.1f\nrevisits: %d\nmax_yaw_rate_deg_s: %.1f\n"
      "points_per_scan: mean %.0f min %.0f max %.0f\nhit_fractions: building %.3f ground %.3f "
      "clutter %.3f moving %.4f\nprior: %zu perturbed, %zu removed, %zu phantom\n"
      "generation_s: %.1f (ray casting %.1f)\nscans_per_s: %.1f\n",
      stats.drive_dir.c_str(), stats.scans, stats.route_length_m, stats.revisits,
      stats.max_yaw_rate_deg_s, stats.mean_points_per_scan, stats.min_points_per_scan,
      stats.max_points_per_scan, stats.building_fraction, stats.ground_fraction,
      stats.clutter_fraction, stats.moving_fraction, stats.prior_perturbed, stats.prior_removed,
      stats.prior_phantom, stats.generation_s, stats.raycast_s, stats.scans_per_s);
  return 0;
}
