// evaluate_slam: accuracy of a SLAM run against ground truth (trajectory and buildings).
//
// The options: evaluate_slam --help.
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
#include "support/command_line.h"

using namespace osm_graph_slam;
using osm_graph_slam::tools::CommandLine;

namespace {

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
  bool json = false;
  double min_coverage = 0.0;
  SlamEvaluationInput in;
  CommandLine cli("evaluate_slam",
                  "Accuracy of a SLAM run against ground truth: the trajectory (ATE, RPE), the "
                  "coverage of the drive, loops and buildings.");
  cli.option("--estimate", "FILE", "the estimated trajectory (KITTI or TUM)")
      .required()
      .option("--ground-truth", "FILE", "the ground truth (KITTI or TUM)")
      .required()
      .option("--baseline", "FILE", "a second trajectory to compare (e.g. odometry)")
      .option("--baseline-label", "NAME", "the baseline's name in the report", &in.baseline_label)
      .option("--buildings-true", "FILE", "the true buildings (.geojson, .osm or .osm.pbf)")
      .option("--buildings-prior", "FILE", "the prior buildings")
      .option("--buildings-corrected", "FILE", "the corrected buildings")
      .option("--origin", "LAT,LON",
              "the ENU origin of the building sets (default: the first true outline's first "
              "point)")
      .option("--alignment", "none|first|umeyama", "how the estimate is aligned to the truth")
      .defaultText("none")
      .flag("--planar", "errors in the plane only", &in.options.planar)
      .option("--max-dt", "S", "the largest stamp difference of associated poses",
              &in.options.max_time_difference)
      .flag("--json", "print the evaluation as JSON", &json)
      .option("--plot-dir", "DIR", "write plot_data.json there and plot it")
      .option("--run-report", "timing.json",
              "offline_slam's timing.json: the coverage counts the span of the scans it read")
      .option("--loops", "loops.txt", "offline_slam's accepted loops: judged, with their recall")
      .option("--min-coverage", "F", "exit 3 when the coverage (0..1) is below F", &min_coverage)
      .option("--allowed-gap", "S", "a gap in the estimate up to S s still counts as covered",
              &in.coverage.allowed_gap);
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  std::map<std::string, std::string> args = cli.values();

  if (!loadTrajectory(args["estimate"], in.estimate) ||
      !loadTrajectory(args["ground-truth"], in.ground_truth))
    return 1;
  if (args.count("baseline")) {
    in.baseline.emplace();
    if (!loadTrajectory(args["baseline"], *in.baseline)) return 1;
  }
  const std::string alignment = args.count("alignment") ? args["alignment"] : "none";
  if (alignment == "first") {
    in.options.alignment = TrajectoryAlignment::kFirstPose;
  } else if (alignment == "umeyama") {
    in.options.alignment = TrajectoryAlignment::kUmeyamaSE3;
  } else if (alignment != "none") {
    return cli.fail("unknown alignment '" + alignment + "'");
  }

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
      return cli.fail("--origin takes LAT,LON");
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
