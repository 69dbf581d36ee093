// evaluate_slam: accuracy of a SLAM run against ground truth (trajectory and buildings).
//
//   evaluate_slam --estimate slam.txt --ground-truth gt.txt [--baseline odom.txt]
//                 [--baseline-label odometry] [--buildings-true true.geojson]
//                 [--buildings-prior prior.osm] [--buildings-corrected corrected.geojson]
//                 [--origin LAT,LON] [--alignment none|first|umeyama] [--planar]
//                 [--max-dt 0.02] [--json] [--plot-dir DIR]
//                 [--run-report timing.json] [--loops loops.txt] [--min-coverage F]
//                 [--allowed-gap S]
//
// Coverage: the share of the drive (ground truth, widened by the span of the scans the run read
// when --run-report gives offline_slam's timing.json) that has estimated poses; --min-coverage
// makes a truncated run exit 3. --loops judges offline_slam's accepted loops and their recall.
//
// Trajectories: KITTI (12 or 13 columns) or TUM files. Buildings: .geojson or .osm/.osm.pbf.
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <map>
#include <string>

#include <fstream>
#include <nlohmann/json.hpp>

#include "osm_graph_slam/eval/plot_data.h"
#include "osm_graph_slam/eval/slam_evaluation.h"
#include "osm_graph_slam/io/building_geojson.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/osm/osm_reader.h"

using namespace osm_graph_slam;

namespace {

int usage(const std::string& why) {
  std::cerr << "evaluate_slam: " << why << "\n"
            << "usage: evaluate_slam --estimate FILE --ground-truth FILE [--baseline FILE]\n"
               "       [--baseline-label NAME] [--buildings-true FILE] [--buildings-prior FILE]\n"
               "       [--buildings-corrected FILE] [--origin LAT,LON]\n"
               "       [--alignment none|first|umeyama] [--planar] [--max-dt S] [--json]\n"
               "       [--plot-dir DIR] [--run-report timing.json] [--loops loops.txt]\n"
               "       [--min-coverage F] [--allowed-gap S]\n";
  return 2;
}

bool loadTrajectory(const std::string& path, Trajectory& out) {
  const TrajectoryReadResult r = readTrajectory(path);
  if (!r.ok) {
    std::cerr << "evaluate_slam: " << r.error << "\n";
    return false;
  }
  out = r.trajectory;
  return true;
}

bool loadBuildings(const std::string& path, std::vector<Building>& out) {
  const bool geojson = path.size() > 8 && path.substr(path.size() - 8) == ".geojson";
  if (geojson) {
    BuildingFileResult r = readBuildingsGeoJson(path);
    if (!r.ok) {
      std::cerr << "evaluate_slam: " << r.error << "\n";
      return false;
    }
    out = std::move(r.buildings);
    return true;
  }
  OsmData data = readOsmFile(path);
  if (!data.ok) {
    std::cerr << "evaluate_slam: " << path << ": " << data.error << "\n";
    return false;
  }
  out = std::move(data.buildings);
  return true;
}

/// Tracking counters and the scans' time span from offline_slam's timing.json.
bool loadRunReport(const std::string& path, SlamEvaluationInput& in) {
  std::ifstream f(path);
  const nlohmann::json doc = nlohmann::json::parse(f, nullptr, false);
  if (!f || doc.is_discarded() || !doc.is_object()) {
    std::cerr << "evaluate_slam: --run-report '" << path << "' is not a readable JSON report\n";
    return false;
  }
  const auto it = doc.find("tracking");
  if (it == doc.end() || !it->is_object()) {
    std::cerr << "evaluate_slam: --run-report '" << path
              << "' has no \"tracking\" section (written by an older offline_slam?)\n";
    return false;
  }
  const nlohmann::json& t = *it;
  in.untracked_scans = t.value("failed_matches", size_t(0)) + t.value("rejected_scans", size_t(0));
  in.lost_events = t.value("lost_events", size_t(0));
  if (t.value("scans", size_t(0)) > 0)
    in.coverage.input_span = {t.value("first_stamp", 0.0), t.value("last_stamp", 0.0)};
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  std::map<std::string, std::string> args;
  bool json = false;
  SlamEvaluationInput in;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--json") {
      json = true;
    } else if (a == "--planar") {
      in.options.planar = true;
    } else if (a.rfind("--", 0) == 0 && i + 1 < argc) {
      args[a.substr(2)] = argv[++i];
    } else {
      return usage("unexpected argument '" + a + "'");
    }
  }
  if (!args.count("estimate") || !args.count("ground-truth"))
    return usage("--estimate and --ground-truth are required");

  if (!loadTrajectory(args["estimate"], in.estimate) ||
      !loadTrajectory(args["ground-truth"], in.ground_truth))
    return 1;
  if (args.count("baseline")) {
    in.baseline.emplace();
    if (!loadTrajectory(args["baseline"], *in.baseline)) return 1;
  }
  if (args.count("baseline-label")) in.baseline_label = args["baseline-label"];
  if (args.count("max-dt")) in.options.max_time_difference = std::atof(args["max-dt"].c_str());
  const std::string alignment = args.count("alignment") ? args["alignment"] : "none";
  if (alignment == "first") {
    in.options.alignment = TrajectoryAlignment::kFirstPose;
  } else if (alignment == "umeyama") {
    in.options.alignment = TrajectoryAlignment::kUmeyamaSE3;
  } else if (alignment != "none") {
    return usage("unknown alignment '" + alignment + "'");
  }

  if (args.count("allowed-gap")) in.coverage.allowed_gap = std::atof(args["allowed-gap"].c_str());
  if (args.count("run-report") && !loadRunReport(args["run-report"], in)) return 1;
  if (args.count("loops")) {
    LoopClosureReadResult loops = readLoopClosures(args["loops"]);
    if (!loops.ok) {
      std::cerr << "evaluate_slam: " << loops.error << "\n";
      return 1;
    }
    in.loops = std::move(loops.loops);
    in.loop_options.max_time_difference = in.options.max_time_difference;
  }
  double min_coverage = 0.0;
  if (args.count("min-coverage")) min_coverage = std::atof(args["min-coverage"].c_str());

  const std::pair<const char*, std::vector<Building>*> sets[] = {
      {"buildings-true", &in.buildings_true},
      {"buildings-prior", &in.buildings_prior},
      {"buildings-corrected", &in.buildings_corrected}};
  for (const auto& [key, target] : sets)
    if (args.count(key) && !loadBuildings(args[key], *target)) return 1;

  if (!in.buildings_true.empty()) {
    // All sets share one ENU frame; distances do not depend on which origin it is.
    GeoPoint origin = in.buildings_true.front().outline_geo.front();
    if (args.count("origin") &&
        std::sscanf(args["origin"].c_str(), "%lf,%lf", &origin.lat, &origin.lon) != 2)
      return usage("--origin takes LAT,LON");
    const EnuConverter enu(origin.lat, origin.lon);
    for (const auto& [key, target] : sets)
      for (auto& b : *target) enu.project(b);
  }

  const SlamEvaluation evaluation = evaluateSlam(in);
  if (evaluation.slam.associated == 0) {
    std::cerr << "evaluate_slam: no estimate pose has a ground-truth pose within "
              << in.options.max_time_difference << " s (check the stamps)\n";
    return 1;
  }
  std::cout << (json ? evaluationToJson(evaluation) + "\n" : evaluationToTable(evaluation));

  if (args.count("plot-dir")) {
    const std::string dir = args["plot-dir"];
    std::filesystem::create_directories(dir);
    std::string error;
    if (!writeFileAtomically(dir + "/plot_data.json", plotDataJson(in, evaluation), &error)) {
      std::cerr << "evaluate_slam: " << error << "\n";
      return 1;
    }
    const std::string script = std::string(OGS_SOURCE_DIR) + "/scripts/plot_evaluation.py";
    const std::string cmd = "/usr/bin/python3 '" + script + "' '" + dir + "' >&2";
    if (std::system(cmd.c_str()) != 0) {
      std::cerr << "evaluate_slam: plotting failed (" << cmd << "); plot data is in " << dir
                << "/plot_data.json\n";
      return 1;
    }
  }
  if (evaluation.coverage.fraction < min_coverage) {
    std::cerr << "evaluate_slam: coverage " << 100.0 * evaluation.coverage.fraction
              << " % is below --min-coverage " << 100.0 * min_coverage << " %\n";
    return 3;
  }
  return 0;
}
