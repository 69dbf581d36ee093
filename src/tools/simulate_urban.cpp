// simulate_urban: a simulated urban LiDAR drive (KITTI raw layout + ground truth + perturbed OSM
// prior). See doc/simulator.md.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "osm_graph_slam/drive_io/dataset_bag.h"
#include "osm_graph_slam/sim/forest_world.h"
#include "osm_graph_slam/sim/radar_sim.h"
#include "osm_graph_slam/sim/simulator.h"
#include "support/command_line.h"

using namespace osm_graph_slam;
using namespace osm_graph_slam::sim;

namespace {

std::string formatPair(double a, double b) {
  char text[64];
  std::snprintf(text, sizeof(text), "%g,%g", a, b);
  return text;
}

struct Options {
  SimulationParams p;
  std::string out;
  bool navtech = false;  ///< radar drive instead of the LiDAR one
  NavtechModel navtech_model;
};

void declareDriveOptions(tools::CommandLine& cli, Options& o) {
  SimulationParams& p = o.p;
  cli.option("--out", "DIR", "where the drive is written", &o.out)
      .required()
      .option("--osm", "FILE", "OSM extract (.osm/.osm.pbf); default: procedural city", &p.osm_path)
      .option("--seed", "N", "the drive's seed", &p.seed)
      .option("--world-seed", "N",
              "the world's layout and heights (0: the seed); another --seed drives other roads "
              "of the same world",
              &p.world_seed)
      .option("--prior-seed", "N",
              "the prior map's seed (0: the seed); drives of one world share one prior map with it",
              &p.prior_seed)
      .option("--start-day", "K", "the drive starts K days after the default start time",
              [&p](const std::string& v) {
                char* end = nullptr;
                const long days = std::strtol(v.c_str(), &end, 10);
                if (end == v.c_str() || *end != '\0' || days < 0 || days > 36500)
                  return std::string("expects a whole number of days, 0 to 36500");
                p.start_time_ns += static_cast<StampNs>(days) * 86400LL * 1000000000LL;
                return std::string();
              })
      .option("--length", "M", "route length", &p.route.length)
      .option("--route-start", "X,Y",
              "the route starts at the junction nearest to this ENU point [m] (a fleet's "
              "depot); default: a junction drawn from the seed",
              [&p](const std::string& v) {
                double x = 0.0, y = 0.0;
                char tail = 0;
                if (std::sscanf(v.c_str(), "%lf,%lf%c", &x, &y, &tail) != 2)
                  return std::string("expects X,Y in metres");
                p.route.start_near = Eigen::Vector2d(x, y);
                return std::string();
              })
      .option("--speed", "V", "cruise speed, m/s", &p.route.cruise_speed)
      .option("--scans", "N", "stop after N scans (0: whole route)", &p.max_scans)
      .option("--sensor", "hdl64e|os1_64|navtech", "the sensor (navtech radar: doc/radar.md)",
              [&o](const std::string& s) {
                if (s == "hdl64e")
                  o.p.lidar = LidarModel::hdl64e();
                else if (s == "os1_64")
                  o.p.lidar = LidarModel::os1_64();
                else if (s == "navtech")
                  o.navtech = true;
                else
                  return "unknown sensor '" + s + "'";
                return std::string();
              })
      .defaultText("hdl64e")
      .option("--radar-doppler-beta", "S", "navtech only: the Doppler beta",
              &o.navtech_model.doppler_beta)
      .flag("--radar-no-skew", "navtech only: the whole turn at the sweep's start pose",
            &o.navtech_model.motion_skew, false)
      .flag("--motion-distortion",
            "per-column sensor poses, each point in its column's frame as a driver without "
            "deskewing gives it",
            &p.motion_distortion)
      .flag("--compensated-sweep",
            "with --motion-distortion: points moved to the stamp's frame by the true motion (a "
            "perfect deskew)",
            &p.compensated_sweep)
      .option("--origin", "LAT,LON[,ALT]", "ENU origin (default: extract centre / Karlsruhe)",
              [&p](const std::string& s) {
                if (std::sscanf(s.c_str(), "%lf,%lf,%lf", &p.origin_lat, &p.origin_lon,
                                &p.origin_alt) < 2)
                  return std::string("expects LAT,LON[,ALT]");
                return std::string();
              })
      .flag("--no-clutter", "buildings and ground only", &p.clutter_enabled, false)
      .flag("--flat-ground", "level ground (default: gentle slopes of a few percent)",
            &p.flat_ground);
}

void declareWorldOptions(tools::CommandLine& cli, Options& o) {
  SimulationParams& p = o.p;
  cli.option("--world", "city|forest|park",
             "procedural world (forest/park: trails, trees, undergrowth; doc/landmarks.md)",
             [&p](const std::string& w) {
               if (w != "city" && w != "forest" && w != "park")
                 return std::string("expects city, forest or park");
               p.city.world = w;
               p.clutter_enabled = w == "city";  // forests bring their own undergrowth
               return std::string();
             })
      .defaultText(p.city.world)
      .option("--forest-density", "sparse|intermediate|dense", "the forest's density",
              [&p](const std::string& d) {
                ForestParams check;
                if (d == "park" || !forestPreset(d, check))
                  return std::string("expects sparse, intermediate or dense");
                p.city.forest_density = d;
                return std::string();
              })
      .defaultText(p.city.forest_density)
      .option("--blocks", "NX,NY", "procedural city size in blocks",
              [&p](const std::string& v) {
                if (std::sscanf(v.c_str(), "%d,%d", &p.city.blocks_x, &p.city.blocks_y) != 2)
                  return std::string("expects NX,NY");
                return std::string();
              })
      .defaultText(std::to_string(p.city.blocks_x) + "," + std::to_string(p.city.blocks_y))
      .option("--manoeuvres", "LIST",
              "none, all, or a comma list of sharp_turn,u_turn,stop,dead_end,long_straight",
              [&p](const std::string& v) {
                std::string why;
                if (!parseManoeuvreList(v, p.route.manoeuvres, &why)) return why;
                return std::string();
              })
      .defaultText("none")
      .option("--drop-scans", "F", "each scan missing with probability F",
              [&p](const std::string& v) {
                double f = 0.0;
                if (!tools::parseDouble(v, &f) || !(f >= 0.0 && f < 1.0))
                  return std::string("expects a fraction in [0, 1)");
                p.scan_drop.fraction = f;
                return std::string();
              })
      .defaultText("0")
      .option("--dropout-burst", "N[@T]",
              "N consecutive scans missing, from T s (default: a seeded time in the middle of "
              "the drive)",
              [&p](const std::string& v) {
                char at = 0;
                const int fields = std::sscanf(v.c_str(), "%d%c%lf", &p.scan_drop.burst_length, &at,
                                               &p.scan_drop.burst_time);
                if (!((fields == 1 || (fields == 3 && at == '@')) && p.scan_drop.burst_length >= 0))
                  return std::string("expects N or N@T (seconds)");
                return std::string();
              });
}

void declareSensorErrorOptions(tools::CommandLine& cli, Options& o) {
  LidarModel& l = o.p.lidar;
  cli.option("--dropout", "P", "a return's dropout probability", &l.dropout_probability)
      .option("--range-noise", "M", "range noise sigma", &l.range_noise_sigma)
      .option("--elevation-bias-deg", "D", "intrinsic calibration error: elevation bias",
              &l.elevation_bias_deg)
      .option("--beam-elevation-sigma-deg", "D", "intrinsic calibration error per beam",
              &l.beam_elevation_sigma_deg)
      .option("--beam-range-offset-sigma", "M", "intrinsic calibration error per beam",
              &l.beam_range_offset_sigma)
      .flag("--kitti-calibration-error", "= 0.22 deg bias, 0.1 deg / 2 cm per beam", [&l] {
        l.elevation_bias_deg = 0.22;
        l.beam_elevation_sigma_deg = 0.1;
        l.beam_range_offset_sigma = 0.02;
      });
  NavErrorParams& n = o.p.nav;
  cli.option("--gnss-model", "noisy|rtk|canyon",
             "GNSS fixes: noisy (the errors below), rtk (exact, as KITTI's OXTS) or canyon (from "
             "the satellites the buildings let through, with NLOS reflections)",
             [&n](const std::string& v) {
               return parseGnssModel(v, n) ? std::string() : "expects noisy, rtk or canyon";
             })
      .defaultText("noisy")
      .flag("--rtk", "= --gnss-model rtk: exact GNSS/INS, no errors at all", &n.rtk)
      .flag("--downtown",
            "procedural city: a downtown of 20-80 m towers on narrow streets in its central "
            "blocks (other buildings unchanged)",
            &o.p.city.downtown.enabled)
      .option("--gnss-sigma", "M", "GNSS white noise per horizontal axis", &n.gnss_sigma)
      .option("--gnss-sigma-vertical", "M", "GNSS white noise, vertical", &n.gnss_sigma_vertical)
      .option("--gnss-bias-sigma", "M", "GNSS first-order Gauss-Markov bias per axis",
              &n.gnss_bias_sigma)
      .option("--gnss-bias-sigma-vertical", "M", "GNSS bias, vertical", &n.gnss_bias_sigma_vertical)
      .option("--gnss-bias-tau", "S", "GNSS bias time constant", &n.gnss_bias_tau_s)
      .option("--gnss-outages-per-km", "F", "GNSS outages (no fix) per km", &n.gnss_outages_per_km)
      .option("--gnss-outage-duration", "S", "GNSS outage duration", &n.gnss_outage_duration_s)
      .option("--imu-heading-bias-deg", "D", "INS heading bias (sign from the seed)",
              &n.imu_heading_bias_deg)
      .option("--imu-heading-sigma-deg", "D", "INS heading noise", &n.imu_heading_sigma_deg)
      .option("--imu-attitude-sigma-deg", "D", "INS roll/pitch noise", &n.imu_attitude_sigma_deg)
      .option("--gyro-sigma-deg-s", "D", "gyro noise", &n.gyro_sigma_deg_s)
      .option("--gyro-bias-deg-s", "D", "constant yaw-rate gyro bias (sign from the seed)",
              &n.gyro_bias_deg_s)
      .option("--accel-sigma", "M", "accelerometer noise, m/s^2", &n.accel_sigma);
}

void declarePriorOptions(tools::CommandLine& cli, Options& o) {
  PriorPerturbationParams& r = o.p.prior;
  cli.option("--prior-translation-sigma", "M", "prior: per-building translation error",
             &r.translation_sigma)
      .option("--prior-rotation-sigma-deg", "D", "prior: per-building rotation error",
              &r.rotation_sigma_deg)
      .option("--prior-removal", "F", "prior: fraction of buildings removed", &r.removal_fraction)
      .option("--prior-phantom", "F", "prior: fraction of phantom buildings added",
              &r.phantom_fraction)
      .option("--prior-model", "independent|blocks|global|mixed", "prior: the error model",
              [&r](const std::string& m) {
                if (!parsePriorModel(m, r.model))
                  return "unknown model '" + m + "' (independent, blocks, global, mixed)";
                return std::string();
              })
      .defaultText(priorModelName(r.model))
      .option("--prior-block-size", "M", "prior blocks: size", &r.block_size)
      .option("--prior-block-sigma", "M", "prior blocks: translation error per block",
              &r.block_translation_sigma)
      .option("--prior-block-rotation-sigma-deg", "D", "prior blocks: rotation error per block",
              &r.block_rotation_sigma_deg)
      .option("--prior-block-residual-sigma", "M", "prior blocks: per-building residual",
              &r.block_residual_sigma)
      .option("--prior-block-residual-rotation-sigma-deg", "D",
              "prior blocks: per-building rotation residual", &r.block_residual_rotation_sigma_deg)
      .option("--prior-global-offset", "MIN,MAX", "prior global: the offset's range",
              [&r](const std::string& v) {
                if (std::sscanf(v.c_str(), "%lf,%lf", &r.global_offset_min, &r.global_offset_max) !=
                        2 ||
                    r.global_offset_min > r.global_offset_max)
                  return std::string("expects MIN,MAX (MIN <= MAX)");
                return std::string();
              })
      .defaultText(formatPair(r.global_offset_min, r.global_offset_max))
      .option("--prior-global-rotation-sigma-deg", "D", "prior global: rotation error",
              &r.global_rotation_sigma_deg)
      .option("--prior-mixed-sigma", "M", "prior mixed: translation error",
              &r.mixed_translation_sigma)
      .option("--prior-mixed-rotation-sigma-deg", "D", "prior mixed: rotation error",
              &r.mixed_rotation_sigma_deg);
}

/// The navtech radar drive (MulRan layout).
int writeRadarDrive(const UrbanSimulator& sim, const NavtechModel& navtech_model,
                    const SimulationParams& p, const std::string& out) {
  std::string error;
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

/// The LiDAR drive (KITTI raw layout, ground truth, perturbed prior).
int writeLidarDrive(UrbanSimulator& sim, const SimulationParams& p, const std::string& out) {
  std::string error;
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

}  // namespace

int main(int argc, char** argv) {
  Options o;
  tools::CommandLine cli("simulate_urban",
                         "A simulated urban LiDAR (or navtech radar) drive: KITTI raw layout + "
                         "ground truth + perturbed OSM prior. See doc/simulator.md.");
  declareDriveOptions(cli, o);
  declareWorldOptions(cli, o);
  declareSensorErrorOptions(cli, o);
  declarePriorOptions(cli, o);
  cli.note(
      "GNSS/INS errors are consumer-grade by default; oxts_true/ always holds the exact "
      "records.");
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  SimulationParams& p = o.p;
  if (o.navtech) {  // --scans counts radar sweeps; the navigation records cover them all
    o.navtech_model.max_scans = p.max_scans;
    p.max_scans = 0;
  }
  UrbanSimulator sim;
  std::string error;
  if (!sim.build(p, &error)) {
    std::fprintf(stderr, "simulate_urban: %s\n", error.c_str());
    return 1;
  }
  return o.navtech ? writeRadarDrive(sim, o.navtech_model, p, o.out)
                   : writeLidarDrive(sim, p, o.out);
}
