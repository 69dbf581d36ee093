// simulate_urban: a simulated urban LiDAR drive (KITTI raw layout + ground truth + perturbed OSM
// prior). See doc/simulator.md.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "osm_graph_slam/ros/dataset_bag.h"
#include "osm_graph_slam/sim/forest_world.h"
#include "osm_graph_slam/sim/radar_sim.h"
#include "osm_graph_slam/sim/simulator.h"

using namespace osm_graph_slam;
using namespace osm_graph_slam::sim;

namespace {

void usage() {
  std::fprintf(
      stderr,
      "usage: simulate_urban --out DIR [options]\n"
      "  --osm FILE              OSM extract (.osm/.osm.pbf); default: procedural city\n"
      "  --seed N                (default 1)\n"
      "  --world-seed N          the world's layout and heights (default: the seed);\n"
      "                          another --seed drives other roads of the same world\n"
      "  --length M              route length [m] (default 1500)\n"
      "  --speed V               cruise speed [m/s] (default 8)\n"
      "  --scans N               stop after N scans (default: whole route)\n"
      "  --sensor hdl64e|os1_64|navtech  (default hdl64e; navtech radar: doc/radar.md)\n"
      "  --radar-doppler-beta S (0.049)  --radar-no-skew   (navtech only)\n"
      "  --motion-distortion     per-column sensor poses, each point in its column's frame\n"
      "                          as a driver without deskewing gives it (default off)\n"
      "  --compensated-sweep     with --motion-distortion: points moved to the stamp's\n"
      "                          frame by the true motion (a perfect deskew)\n"
      "  --origin LAT,LON[,ALT]  ENU origin (default: extract centre / Karlsruhe)\n"
      "  --no-clutter            buildings and ground only\n"
      "  --flat-ground           level ground (default: gentle slopes of a few percent)\n"
      "  --world city|forest|park  procedural world (default city; forest/park: trails,\n"
      "                          trees, undergrowth; doc/landmarks.md)\n"
      "  --forest-density sparse|intermediate|dense  (default intermediate)\n"
      "  --blocks NX,NY          procedural city size in blocks (default 7,6)\n"
      "  --prior-translation-sigma M (1.0)  --prior-rotation-sigma-deg D (2.0)\n"
      "  --prior-removal F (0.05)  --prior-phantom F (0.03)\n"
      "  --dropout P (0.02)  --range-noise M (0.02)\n"
      "  --elevation-bias-deg D (0)  --beam-elevation-sigma-deg D (0)\n"
      "  --beam-range-offset-sigma M (0)   intrinsic calibration errors\n"
      "  --kitti-calibration-error   = 0.22 deg bias, 0.1 deg / 2 cm per beam\n"
      "  --manoeuvres LIST       none (default), all, or a comma list of\n"
      "                          sharp_turn,u_turn,stop,dead_end,long_straight\n"
      "  --drop-scans F          each scan missing with probability F (default 0)\n"
      "  --dropout-burst N[@T]   N consecutive scans missing, from T s (default:\n"
      "                          a seeded time in the middle of the drive)\n");
  const SimulationParams d;  // the defaults
  const NavErrorParams& n = d.nav;
  const PriorPerturbationParams& r = d.prior;
  std::fprintf(
      stderr,
      "GNSS/INS errors (default consumer-grade; oxts_true/ always holds the exact records):\n"
      "  --gnss-model noisy|rtk|canyon  (default noisy: the errors below; canyon: fixes from\n"
      "                          the satellites the buildings let through, NLOS reflections)\n"
      "  --rtk                   = --gnss-model rtk: exact GNSS/INS (as KITTI's OXTS)\n"
      "  --downtown              procedural city: a downtown of 20-80 m towers on narrow\n"
      "                          streets in its central blocks (other buildings unchanged)\n"
      "  --gnss-sigma M (%g)  --gnss-sigma-vertical M (%g)   white noise per axis\n"
      "  --gnss-bias-sigma M (%g)  --gnss-bias-sigma-vertical M (%g)  --gnss-bias-tau S (%g)\n"
      "                          first-order Gauss-Markov bias per axis\n"
      "  --gnss-outages-per-km F (%g)  --gnss-outage-duration S (%g)   no fix (pos_accuracy %g)\n"
      "  --imu-heading-bias-deg D (%g, sign from the seed)  --imu-heading-sigma-deg D (%g)\n"
      "  --imu-attitude-sigma-deg D (%g)  --gyro-sigma-deg-s D (%g)  --accel-sigma M (%g)\n"
      "  --gyro-bias-deg-s D (%g, sign from the seed)   constant yaw-rate gyro bias\n"
      "prior-map error model:\n"
      "  --prior-model independent|blocks|global|mixed (%s)\n"
      "  --prior-block-size M (%g)  --prior-block-sigma M (%g)  --prior-block-rotation-sigma-deg D "
      "(%g)\n"
      "  --prior-block-residual-sigma M (%g)  --prior-block-residual-rotation-sigma-deg D (%g)\n"
      "  --prior-global-offset MIN,MAX (%g,%g)  --prior-global-rotation-sigma-deg D (%g)\n"
      "  --prior-mixed-sigma M (%g)  --prior-mixed-rotation-sigma-deg D (%g)\n",
      n.gnss_sigma, n.gnss_sigma_vertical, n.gnss_bias_sigma, n.gnss_bias_sigma_vertical,
      n.gnss_bias_tau_s, n.gnss_outages_per_km, n.gnss_outage_duration_s, kOxtsNoFixAccuracy,
      n.imu_heading_bias_deg, n.imu_heading_sigma_deg, n.imu_attitude_sigma_deg, n.gyro_sigma_deg_s,
      n.accel_sigma, n.gyro_bias_deg_s, priorModelName(r.model), r.block_size,
      r.block_translation_sigma, r.block_rotation_sigma_deg, r.block_residual_sigma,
      r.block_residual_rotation_sigma_deg, r.global_offset_min, r.global_offset_max,
      r.global_rotation_sigma_deg, r.mixed_translation_sigma, r.mixed_rotation_sigma_deg);
}

}  // namespace

int main(int argc, char** argv) {
  SimulationParams p;
  std::string out;
  bool navtech = false;  // radar drive instead of the LiDAR one
  NavtechModel navtech_model;
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
    else if (a == "--world-seed")
      p.world_seed = std::strtoull(next().c_str(), nullptr, 10);
    else if (a == "--length")
      p.route.length = std::atof(next().c_str());
    else if (a == "--speed")
      p.route.cruise_speed = std::atof(next().c_str());
    else if (a == "--scans")
      p.max_scans = std::atoi(next().c_str());
    else if (a == "--motion-distortion")
      p.motion_distortion = true;
    else if (a == "--compensated-sweep")
      p.compensated_sweep = true;
    else if (a == "--no-clutter")
      p.clutter_enabled = false;
    else if (a == "--flat-ground")
      p.flat_ground = true;
    else if (a == "--world") {  // forest/park: sim/forest_world.h (issue 24)
      p.city.world = next();
      if (p.city.world != "city" && p.city.world != "forest" && p.city.world != "park") {
        std::fprintf(stderr, "simulate_urban: --world expects city, forest or park\n");
        return 2;
      }
      p.clutter_enabled = p.city.world == "city";  // forests bring their own undergrowth
    } else if (a == "--forest-density") {
      p.city.forest_density = next();
      ForestParams check;
      if (p.city.forest_density == "park" || !forestPreset(p.city.forest_density, check)) {
        std::fprintf(stderr,
                     "simulate_urban: --forest-density expects sparse, intermediate or "
                     "dense\n");
        return 2;
      }
    } else if (a == "--sensor") {
      const std::string s = next();
      if (s == "hdl64e")
        p.lidar = LidarModel::hdl64e();
      else if (s == "os1_64")
        p.lidar = LidarModel::os1_64();
      else if (s == "navtech")
        navtech = true;
      else {
        std::fprintf(stderr, "simulate_urban: unknown sensor '%s'\n", s.c_str());
        return 2;
      }
    } else if (a == "--radar-doppler-beta")
      navtech_model.doppler_beta = std::atof(next().c_str());
    else if (a == "--radar-no-skew")
      navtech_model.motion_skew = false;
    else if (a == "--origin") {
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
    else if (a == "--rtk")  // = --gnss-model rtk
      p.nav.rtk = true;
    else if (a == "--gnss-model") {
      if (!parseGnssModel(next(), p.nav)) {
        std::fprintf(stderr, "simulate_urban: --gnss-model expects noisy, rtk or canyon\n");
        return 2;
      }
    } else if (a == "--downtown")
      p.city.downtown.enabled = true;
    else if (a == "--gnss-sigma")
      p.nav.gnss_sigma = std::atof(next().c_str());
    else if (a == "--gnss-sigma-vertical")
      p.nav.gnss_sigma_vertical = std::atof(next().c_str());
    else if (a == "--gnss-bias-sigma")
      p.nav.gnss_bias_sigma = std::atof(next().c_str());
    else if (a == "--gnss-bias-sigma-vertical")
      p.nav.gnss_bias_sigma_vertical = std::atof(next().c_str());
    else if (a == "--gnss-bias-tau")
      p.nav.gnss_bias_tau_s = std::atof(next().c_str());
    else if (a == "--gnss-outages-per-km")
      p.nav.gnss_outages_per_km = std::atof(next().c_str());
    else if (a == "--gnss-outage-duration")
      p.nav.gnss_outage_duration_s = std::atof(next().c_str());
    else if (a == "--imu-heading-bias-deg")
      p.nav.imu_heading_bias_deg = std::atof(next().c_str());
    else if (a == "--imu-heading-sigma-deg")
      p.nav.imu_heading_sigma_deg = std::atof(next().c_str());
    else if (a == "--imu-attitude-sigma-deg")
      p.nav.imu_attitude_sigma_deg = std::atof(next().c_str());
    else if (a == "--gyro-sigma-deg-s")
      p.nav.gyro_sigma_deg_s = std::atof(next().c_str());
    else if (a == "--gyro-bias-deg-s")
      p.nav.gyro_bias_deg_s = std::atof(next().c_str());
    else if (a == "--accel-sigma")
      p.nav.accel_sigma = std::atof(next().c_str());
    else if (a == "--prior-model") {
      const std::string m = next();
      if (!parsePriorModel(m, p.prior.model)) {
        std::fprintf(stderr,
                     "simulate_urban: unknown --prior-model '%s' (independent, blocks, global, "
                     "mixed)\n",
                     m.c_str());
        return 2;
      }
    } else if (a == "--prior-block-size")
      p.prior.block_size = std::atof(next().c_str());
    else if (a == "--prior-block-sigma")
      p.prior.block_translation_sigma = std::atof(next().c_str());
    else if (a == "--prior-block-rotation-sigma-deg")
      p.prior.block_rotation_sigma_deg = std::atof(next().c_str());
    else if (a == "--prior-block-residual-sigma")
      p.prior.block_residual_sigma = std::atof(next().c_str());
    else if (a == "--prior-block-residual-rotation-sigma-deg")
      p.prior.block_residual_rotation_sigma_deg = std::atof(next().c_str());
    else if (a == "--prior-global-offset") {
      if (std::sscanf(next().c_str(), "%lf,%lf", &p.prior.global_offset_min,
                      &p.prior.global_offset_max) != 2 ||
          p.prior.global_offset_min > p.prior.global_offset_max) {
        std::fprintf(stderr,
                     "simulate_urban: --prior-global-offset expects MIN,MAX (MIN <= MAX)\n");
        return 2;
      }
    } else if (a == "--prior-global-rotation-sigma-deg")
      p.prior.global_rotation_sigma_deg = std::atof(next().c_str());
    else if (a == "--prior-mixed-sigma")
      p.prior.mixed_translation_sigma = std::atof(next().c_str());
    else if (a == "--prior-mixed-rotation-sigma-deg")
      p.prior.mixed_rotation_sigma_deg = std::atof(next().c_str());
    else if (a == "--dropout")
      p.lidar.dropout_probability = std::atof(next().c_str());
    else if (a == "--manoeuvres") {
      std::string why;
      if (!parseManoeuvreList(next(), p.route.manoeuvres, &why)) {
        std::fprintf(stderr, "simulate_urban: --manoeuvres: %s\n", why.c_str());
        return 2;
      }
    } else if (a == "--drop-scans") {
      p.scan_drop.fraction = std::atof(next().c_str());
      if (!(p.scan_drop.fraction >= 0.0 && p.scan_drop.fraction < 1.0)) {
        std::fprintf(stderr, "simulate_urban: --drop-scans expects a fraction in [0, 1)\n");
        return 2;
      }
    } else if (a == "--dropout-burst") {
      const std::string v = next();
      char at = 0;
      const int fields = std::sscanf(v.c_str(), "%d%c%lf", &p.scan_drop.burst_length, &at,
                                     &p.scan_drop.burst_time);
      if (!((fields == 1 || (fields == 3 && at == '@')) && p.scan_drop.burst_length >= 0)) {
        std::fprintf(stderr, "simulate_urban: --dropout-burst expects N or N@T (seconds)\n");
        return 2;
      }
    } else if (a == "--range-noise")
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
  if (navtech) {  // --scans counts radar sweeps; the navigation records cover them all
    navtech_model.max_scans = p.max_scans;
    p.max_scans = 0;
  }
  UrbanSimulator sim;
  std::string error;
  if (!sim.build(p, &error)) {
    std::fprintf(stderr, "simulate_urban: %s\n", error.c_str());
    return 1;
  }
  if (navtech) {
    const RadarSimulator radar(sim, navtech_model, p.seed);
    RadarDriveStats rs;
    if (!radar.writeMulranDrive(out, rs, stderrProgressBar("simulate_urban"), &error)) {
      std::fprintf(stderr, "\nsimulate_urban: %s\n", error.c_str());
      return 1;
    }
    std::printf(
        "drive: %s\nradar_scans: %zu\ngps: %zu\nimu: %zu\nroute_length_m: %.1f\n"
        "duration_s: %.1f\nmean_returns_per_scan: %.0f\ngeneration_s: %.1f\n"
        "scans_per_s: %.1f\n",
        rs.drive_dir.c_str(), rs.scans, rs.gps, rs.imu, rs.route_length_m, rs.duration_s,
        rs.mean_hits_per_scan, rs.generation_s, rs.scans_per_s);
    return 0;
  }
  const std::vector<bool> dropped = sim.droppedScans();
  std::fprintf(stderr,
               "simulate_urban: %zu buildings, %zu clutter primitives, %zu moving objects; route "
               "%.0f m, %.0f s, %zu scans (%zu dropped); manoeuvres %s (%zu driven), max yaw "
               "rate %.1f deg/s, max accel %.2f m/s^2\n",
               sim.scene().world.buildings.size(), sim.scene().world.primitives.size(),
               sim.scene().world.moving.size(), sim.trajectory().length(),
               sim.trajectory().duration(), sim.numScans(),
               size_t(std::count(dropped.begin(), dropped.end(), true)),
               manoeuvreList(p.route.manoeuvres).c_str(), sim.trajectory().manoeuvres().size(),
               sim.trajectory().maxYawRate() * 180.0 / M_PI, sim.trajectory().maxAccel());
  SimulationStats stats;
  if (!sim.writeDataset(out, stats, stderrProgressBar("simulate_urban"), &error)) {
    std::fprintf(stderr, "\nsimulate_urban: %s\n", error.c_str());
    return 1;
  }
  std::printf(
      "drive: %s\nscans: %zu\nroute_length_m: %.1f\nrevisits: %d\nmax_yaw_rate_deg_s: %.1f\n"
      "points_per_scan: mean %.0f min %.0f max %.0f\nhit_fractions: building %.3f ground %.3f "
      "clutter %.3f moving %.4f\nprior: %zu perturbed, %zu removed, %zu phantom\n"
      "gnss: %s, horizontal error rms %.2f m max %.2f m, %d outages (%.0f s)\n"
      "generation_s: %.1f (ray casting %.1f)\nscans_per_s: %.1f\n",
      stats.drive_dir.c_str(), stats.scans, stats.route_length_m, stats.revisits,
      stats.max_yaw_rate_deg_s, stats.mean_points_per_scan, stats.min_points_per_scan,
      stats.max_points_per_scan, stats.building_fraction, stats.ground_fraction,
      stats.clutter_fraction, stats.moving_fraction, stats.prior_perturbed, stats.prior_removed,
      stats.prior_phantom, p.nav.rtk ? "rtk" : "consumer-grade", stats.gnss_error_rms_m,
      stats.gnss_error_max_m, stats.gnss_outages, stats.gnss_outage_s, stats.generation_s,
      stats.raycast_s, stats.scans_per_s);
  if (!p.nav.rtk && p.nav.gnss_model == GnssPositionModel::kCanyon) {
    const CanyonDriveStats& c = stats.canyon;
    std::printf(
        "gnss_canyon: horizontal error rms %.2f m p95 %.2f m max %.2f m, nlos fixes %.1f %%, "
        "outage %.1f s, reported accuracy mean %.2f m vs true error mean %.2f m\n",
        c.horizontal_rms_m, c.horizontal_p95_m, c.horizontal_max_m, 100.0 * c.nlos_fix_share,
        c.outage_s, c.reported_horizontal_mean_m, c.horizontal_mean_m);
  }
  return 0;
}
