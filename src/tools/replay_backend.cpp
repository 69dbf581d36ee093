// Re-runs the graph back-end on a dump_graph directory (offline_slam --dump, or the nodelet's
// dump_graph service) with other parameters, without the front-end (the options: replay_backend
// --help). Writes trajectory_tum.txt, trajectory_kitti.txt, buildings_corrected.geojson and
// odometry_tum.txt, and prints what the last update did.
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <set>
#include <stdexcept>
#include <vector>

#include "osm_graph_slam/common/logger.h"
#include "osm_graph_slam/common/param_reader.h"
#include "osm_graph_slam/eval/building_metrics.h"
#include "osm_graph_slam/io/building_geojson.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/io/yaml_param_reader.h"
#include "osm_graph_slam/lines/line_geometry.h"
#include "osm_graph_slam/slam/graph_dump.h"
#include "osm_graph_slam/slam/params_io.h"
#include "osm_graph_slam/slam/pipeline_params_io.h"
#include "support/command_line.h"
#include "support/gnss_option.h"
#include "support/pipeline_config.h"

using namespace osm_graph_slam;
using osm_graph_slam::tools::addGnssUseOption;
using osm_graph_slam::tools::CommandLine;
using osm_graph_slam::tools::GnssUse;

namespace {

/// --set key=value pairs as a ParamReader over the back-end's parameters.
class OverrideReader : public ParamReader {
 public:
  explicit OverrideReader(std::map<std::string, std::string> values) : values_(std::move(values)) {}

  /// --set keys no parameter asked for (misspelt, or a nested key without its 'group/').
  std::vector<std::string> unusedKeys() const {
    std::vector<std::string> out;
    for (const auto& [key, value] : values_)
      if (!used_.count(key)) out.push_back(key);
    return out;
  }
  /// --set values that are not of the parameter's type ("0.z0" for a number, "yes" for a bool).
  const std::vector<std::string>& badValues() const { return bad_; }

  bool getDouble(const std::string& key, double* v) const override {
    return parse(key, v, [](const std::string& s, size_t* pos) { return std::stod(s, pos); });
  }
  bool getInt(const std::string& key, int* v) const override {
    return parse(key, v, [](const std::string& s, size_t* pos) { return std::stoi(s, pos); });
  }
  bool getBool(const std::string& key, bool* v) const override {
    return parse(key, v, [](const std::string& s, size_t* pos) {
      if (s != "true" && s != "false" && s != "1" && s != "0") throw std::invalid_argument(s);
      *pos = s.size();
      return s == "true" || s == "1";
    });
  }
  bool getString(const std::string& key, std::string* v) const override {
    const std::string* s = find(key);
    if (s) *v = *s;
    return s != nullptr;
  }

 private:
  /// The whole value must parse; anything else is reported and the default kept.
  template <typename T, typename Parse>
  bool parse(const std::string& key, T* v, Parse p) const {
    const std::string* s = find(key);
    if (!s) return false;
    try {
      size_t pos = 0;
      const T parsed = p(*s, &pos);
      if (pos == s->size()) {
        *v = parsed;
        return true;
      }
    } catch (const std::exception&) {
    }
    bad_.push_back(key + "=" + *s);
    return false;
  }

  const std::string* find(const std::string& key) const {
    used_.insert(key);
    auto it = values_.find(key);
    return it == values_.end() ? nullptr : &it->second;
  }
  std::map<std::string, std::string> values_;
  mutable std::set<std::string> used_;
  mutable std::vector<std::string> bad_;
};

}  // namespace

int main(int argc, char** argv) {
  std::map<std::string, std::string> sets;
  bool use_osm = true;
  GnssUse gnss_use;
  CommandLine cli("replay_backend",
                  "Re-runs the graph back-end on a dump_graph directory (offline_slam --dump, or "
                  "the nodelet's dump_graph service) with other parameters, without the "
                  "front-end.");
  cli.option("--dump", "DIR", "the dump to replay")
      .required()
      .option("--output", "DIR",
              "where trajectory_tum.txt, trajectory_kitti.txt, odometry_tum.txt and "
              "buildings_corrected.geojson go")
      .required()
      .option("--config", "OVERRIDES.yaml", "parameter overrides")
      .defaultText("config/kitti.yaml")
      .option("--set", "key=value",
              "override one graph_backend parameter (as in config/graph_backend.yaml, nested "
              "keys with '/': line_matcher/max_translation=2.0); repeatable",
              [&sets](const std::string& kv) {
                const auto eq = kv.find('=');
                if (eq == std::string::npos) return "expects key=value, got '" + kv + "'";
                sets[kv.substr(0, eq)] = kv.substr(eq + 1);
                return std::string();
              })
      .flag("--no-osm", "replay without the OSM prior", &use_osm, false)
      .option("--edges", "FILE",
              "write every robot<->building edge left in the graph (for analysis)");
  addGnssUseOption(cli, gnss_use);
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  std::map<std::string, std::string> args = cli.values();

  SlamPipelineParams params;
  std::string error;
  const OverrideReader overrides(sets);
  if (!tools::loadToolConfig(args, params, &error) ||
      !readParams(overrides, params.backend, &error)) {
    std::cerr << "replay_backend: " << error << "\n";
    return 1;
  }
  if (!overrides.badValues().empty())
    return cli.fail("--set " + overrides.badValues().front() +
                    ": not a value of that parameter's type");
  // A misspelt --set would otherwise replay the defaults under the wrong name.
  if (const auto unused = overrides.unusedKeys(); !unused.empty())
    return cli.fail("--set " + unused.front() + ": no such graph_backend parameter");
  params.backend.use_osm = params.backend.use_osm && use_osm;
  gnss_use.apply(params.backend.gnss);
  GraphDump dump;
  if (!readGraphDump(args["dump"], dump, &error)) {
    std::cerr << "replay_backend: " << error << "\n";
    return 1;
  }
  if (dump.initial_heading) {
    params.backend.initial_yaw_known = true;
    params.backend.initial_yaw = *dump.initial_heading;
  }
  // An analysis tool: the back-end's info lines (heading, datum, re-anchors) are wanted here.
  const auto logger = std::make_shared<Logger>([](LogLevel level, const std::string& msg) {
    if (level != LogLevel::kDebug) std::cerr << "[backend] " << msg << "\n";
  });
  GraphBackend backend(params.backend, logger);
  const auto t0 = std::chrono::steady_clock::now();
  const BackendUpdateReport last = replayGraphDump(dump, backend, params.optimize_every_keyframes);
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();

  const std::string out = args["output"];
  std::filesystem::create_directories(out);
  bool ok = writeTumTrajectory(out + "/trajectory_tum.txt", backend.trajectory()) &&
            writeKittiPoses(out + "/trajectory_kitti.txt", backend.trajectory(), false) &&
            writeTumTrajectory(out + "/odometry_tum.txt", backend.odomTrajectory());
  const auto buildings = backend.correctedBuildings();
  for (const auto& [i, j] :
       findOverlappingBuildings(buildings, params.backend.buildings.overlap_min_area))
    std::cout << "overlap: buildings " << buildings[i].id << " and " << buildings[j].id << ", "
              << polygonOverlapArea(buildings[i].outline_enu, buildings[j].outline_enu) << " m^2\n";
  if (!buildings.empty())
    ok = ok && writeBuildingsGeoJson(out + "/buildings_corrected.geojson", buildings, &error);
  size_t edges = 0, observed = 0;
  for (const auto& b : backend.buildings()) {
    edges += b.observations;
    observed += b.observations > 0;
  }
  std::cout << "replayed " << dump.keyframes.size() << " keyframes, " << dump.loops.size()
            << " loops, " << dump.buildings.size() << " buildings in " << ms << " ms; " << edges
            << " robot-building edges on " << observed << " buildings (local matches "
            << last.local_attempts << ", rejected " << last.local_rejected << ", no visible wall "
            << last.local_unseen << "); last update: " << last.overlap_edges << " overlap edges, "
            << last.overlaps_remaining << " overlaps left, chi2 " << last.phase1.final_chi2 << " / "
            << last.joint.final_chi2 << "\n";
  const BackendUpdateReport::StageMs& st = last.stage_ms;
  std::cout << "back-end updates " << last.total_ms << " ms: OSM matching " << st.osm
            << " ms, phase 1 " << st.phase1 << " ms, phase 2 " << st.phase2 << " ms, joint "
            << st.joint << " ms, overlaps " << st.overlaps << " ms\n";
  if (args.count("edges")) {
    // Analysis (doc/backend.md): every robot<->building edge with the priors' reference poses.
    std::ofstream f(args["edges"]);
    std::map<uint64_t, double> stamps;
    for (const auto& kf : backend.keyframes()) stamps[kf.id] = kf.stamp;
    f << std::setprecision(12);
    f << "# keyframe stamp building z_x z_y z_theta info_xx info_yy info_tt prior_x prior_y "
         "prior_theta\n";
    std::map<int64_t, Pose2> priors;
    for (const auto& b : backend.buildings()) priors[b.prior.id] = b.prior.reference_pose;
    for (const auto& e : backend.buildingObservations()) {
      const Pose2& p = priors[e.building];
      f << e.keyframe << " " << stamps[e.keyframe] << " " << e.building << " " << e.measurement.x
        << " " << e.measurement.y << " " << e.measurement.theta << " " << e.information(0, 0) << " "
        << e.information(1, 1) << " " << e.information(2, 2) << " " << p.x << " " << p.y << " "
        << p.theta << "\n";
    }
  }
  if (const auto datum = backend.osmDatum())
    std::cout << "OSM datum: " << datum->x << " " << datum->y << " m, "
              << datum->theta * 180.0 / M_PI << " deg\n";
  for (double scale : backend.odometryScales()) std::cout << "odometry scale: " << scale << "\n";
  if (!ok) {
    std::cerr << "replay_backend: writing " << out << " failed " << error << "\n";
    return 1;
  }
  return 0;
}
