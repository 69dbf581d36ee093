// evaluate_map: a run measured without ground truth (a real drive): wall points of all keyframes
// at the optimised poses against the OSM prior's and the corrected building outlines (per
// building), the largest shift of a building no keyframe saw, the map's sharpness (mean plane
// variance) and, against a baseline run (e.g. without OSM), its sharpness and the trajectory
// difference. A run is an offline_slam output folder written with --dump RUN/dump.
//
//   (the options: evaluate_map --help)
#include <pcl/io/pcd_io.h>

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "osm_graph_slam/eval/map_agreement.h"
#include "osm_graph_slam/graph/g2o_io.h"
#include "osm_graph_slam/graph/pose_graph.h"
#include "osm_graph_slam/io/building_geojson.h"
#include "osm_graph_slam/io/trajectory_io.h"
#include "osm_graph_slam/lines/line_geometry.h"
#include "osm_graph_slam/osm/building_set.h"
#include "osm_graph_slam/osm/enu_converter.h"
#include "osm_graph_slam/slam/graph_backend.h"
#include "osm_graph_slam/slam/graph_dump.h"
#include "support/command_line.h"

using namespace osm_graph_slam;
using osm_graph_slam::tools::CommandLine;
namespace fs = std::filesystem;

namespace {

struct Run {
  GraphDump dump;
  Trajectory trajectory;  ///< optimised keyframe poses (map)
  std::vector<PosedCloud> keyframes;
  std::vector<Building> corrected;
};

bool loadRun(const std::string& dir, Run& run, std::string* error) {
  const fs::path dump = fs::path(dir) / "dump";
  if (!fs::exists(dump)) {
    *error = dir + " has no dump/ folder: run offline_slam with --dump " + (dump.string());
    return false;
  }
  if (!readGraphDump(dump.string(), run.dump, error)) return false;
  const TrajectoryReadResult t = readTrajectory((fs::path(dir) / "trajectory_tum.txt").string());
  if (!t.ok) {
    *error = t.error;
    return false;
  }
  run.trajectory = t.trajectory;
  std::map<long long, Eigen::Isometry3d> pose_by_ms;  // keyframes named by stamp
  for (const auto& p : run.trajectory) pose_by_ms[std::llround(p.stamp * 1000.0)] = p.pose;
  for (const auto& kf : run.dump.keyframes) {
    const auto it = pose_by_ms.find(std::llround(kf.stamp * 1000.0));
    char name[32];
    std::snprintf(name, sizeof(name), "%06lu.pcd", static_cast<unsigned long>(kf.id));
    PointCloudPtr cloud = std::make_shared<PointCloud>();
    if (it == pose_by_ms.end() ||
        pcl::io::loadPCDFile((dump / "keyframes" / name).string(), *cloud) != 0)
      continue;  // a keyframe without a cloud or pose adds no point
    run.keyframes.emplace_back(it->second, cloud);
  }
  const fs::path corrected = fs::path(dir) / "buildings_corrected.geojson";
  if (fs::exists(corrected) && run.dump.origin) {
    BuildingFileResult b = readBuildingsGeoJson(corrected.string());
    if (!b.ok) {
      *error = b.error;
      return false;
    }
    const EnuConverter enu(run.dump.origin->x(), run.dump.origin->y(), run.dump.origin->z());
    for (auto& building : b.buildings) enu.project(building);
    run.corrected = std::move(b.buildings);
  }
  return true;
}

/// The OSM datum vertex of the run's graph.g2o (the extract's common offset the back-end
/// estimated), if the run had one.
std::optional<Eigen::Vector3d> readDatum(const std::string& dir) {
  PoseGraph graph;
  if (!readG2o((fs::path(dir) / "graph.g2o").string(), &graph).ok) return std::nullopt;
  const std::optional<Pose2> datum = graph.vertexSE2(GraphBackend::kOsmDatumVertex);
  if (!datum) return std::nullopt;
  return Eigen::Vector3d(datum->x, datum->y, datum->theta);
}

/// The pairs of corrected buildings that overlap (as the back-end counts them), with the area
/// and the same pair's overlap in the prior.
nlohmann::json overlapsJson(const std::vector<Building>& prior,
                            const std::vector<Building>& corrected) {
  std::map<std::pair<int64_t, int>, const Building*> prior_by_id;
  for (const auto& b : prior) prior_by_id[{b.id, b.part}] = &b;
  nlohmann::json out = nlohmann::json::array();
  for (const auto& [i, j] : findOverlappingBuildings(corrected)) {
    const Building &a = corrected[i], &b = corrected[j];
    const auto pa = prior_by_id.find({a.id, a.part}), pb = prior_by_id.find({b.id, b.part});
    const double prior_area =
        pa != prior_by_id.end() && pb != prior_by_id.end()
            ? polygonOverlapArea(pa->second->outline_enu, pb->second->outline_enu)
            : 0.0;
    out.push_back({{"a", a.id},
                   {"b", b.id},
                   {"area_m2", polygonOverlapArea(a.outline_enu, b.outline_enu)},
                   {"prior_area_m2", prior_area}});
  }
  return out;
}

/// The run's wall points against the prior and the corrected outlines, per building.
nlohmann::json wallAgreementJson(const Run& run, const std::string& run_dir,
                                 WallAgreementOptions options) {
  options.datum = readDatum(run_dir);
  const WallAgreement w =
      evaluateWallAgreement(run.keyframes, run.dump.buildings, run.corrected, options);
  nlohmann::json rows = nlohmann::json::array();
  for (const auto& b : w.observed)
    rows.push_back({{"id", b.id},
                    {"part", b.part},
                    {"points", b.points},
                    {"prior_median_m", b.prior_median},
                    {"prior_p90_m", b.prior_p90},
                    {"corrected_median_m", b.corrected_median},
                    {"corrected_p90_m", b.corrected_p90},
                    {"shift_m", b.shift}});
  nlohmann::json roofs = nlohmann::json::array();
  for (const auto& r : w.roof_only)
    roofs.push_back({{"id", r.id},
                     {"part", r.part},
                     {"points_inside_prior", r.inside_prior},
                     {"points_inside_corrected", r.inside_corrected},
                     {"shift_m", r.shift}});
  return {{"observed_buildings", w.observed.size()},
          {"points", w.points},
          {"prior_median_m", w.prior_median},
          {"corrected_median_m", w.corrected_median},
          {"prior_p90_m", w.prior_p90},
          {"corrected_p90_m", w.corrected_p90},
          {"unobserved_buildings", w.unobserved},
          {"max_unobserved_shift_m", w.max_unobserved_shift},
          {"max_unobserved_shift_id", w.max_unobserved_shift_id},
          {"max_unobserved_shift_after_datum_m", w.max_unobserved_shift_after_datum},
          {"osm_datum", options.datum ? nlohmann::json{{"x_m", options.datum->x()},
                                                       {"y_m", options.datum->y()},
                                                       {"yaw_rad", options.datum->z()}}
                                      : nlohmann::json()},
          {"overlapping_pairs", overlapsJson(run.dump.buildings, run.corrected)},
          {"buildings", rows},
          {"roof_only", roofs}};
}

/// The run against a baseline run: sharpness and trajectory difference.
nlohmann::json baselineJson(const Run& run, const Run& baseline, const MapSharpness& sharp) {
  const MapSharpness b = evaluateMapSharpness(baseline.keyframes);
  std::map<long long, Eigen::Vector3d> base_by_ms;
  for (const auto& p : baseline.trajectory)
    base_by_ms[std::llround(p.stamp * 1000.0)] = p.pose.translation();
  double max_d = 0, sum_d = 0;
  size_t n = 0;
  for (const auto& p : run.trajectory) {
    const auto it = base_by_ms.find(std::llround(p.stamp * 1000.0));
    if (it == base_by_ms.end()) continue;
    const double d = (p.pose.translation() - it->second).norm();
    max_d = std::max(max_d, d), sum_d += d, ++n;
  }
  return {
      {"mean_plane_variance", b.mean_plane_variance},
      {"sharpness_change",
       b.mean_plane_variance > 0 ? sharp.mean_plane_variance / b.mean_plane_variance - 1.0 : 0.0},
      {"common_keyframes", n},
      {"trajectory_difference_max_m", max_d},
      {"trajectory_difference_mean_m", n ? sum_d / n : 0.0}};
}

/// The report as text.
void printReport(const nlohmann::json& doc, const Run& run, const MapSharpness& sharp) {
  std::printf("keyframes %zu; map sharpness (mean plane variance) %.5f m^2 over %zu points\n",
              run.keyframes.size(), sharp.mean_plane_variance, sharp.points);
  if (doc.count("walls")) {
    const auto& w = doc["walls"];
    std::printf(
        "\nbuilding        points  prior median/p90 [m]  corrected median/p90 [m]  shift [m]\n");
    for (const auto& b : w["buildings"])
      std::printf("%-14lld %7zu  %8.3f / %6.3f      %8.3f / %6.3f          %6.3f\n",
                  b["id"].get<long long>(), b["points"].get<size_t>(),
                  b["prior_median_m"].get<double>(), b["prior_p90_m"].get<double>(),
                  b["corrected_median_m"].get<double>(), b["corrected_p90_m"].get<double>(),
                  b["shift_m"].get<double>());
    std::printf(
        "observed %zu buildings (%zu wall points): median of medians prior %.3f m -> corrected "
        "%.3f m"
        " (p90 %.3f -> %.3f m)\nunobserved %zu buildings, largest shift %.3f m (id %lld)\n",
        w["observed_buildings"].get<size_t>(), w["points"].get<size_t>(),
        w["prior_median_m"].get<double>(), w["corrected_median_m"].get<double>(),
        w["prior_p90_m"].get<double>(), w["corrected_p90_m"].get<double>(),
        w["unobserved_buildings"].get<size_t>(), w["max_unobserved_shift_m"].get<double>(),
        w["max_unobserved_shift_id"].get<long long>());
    std::printf("overlapping pairs of corrected buildings: %zu\n", w["overlapping_pairs"].size());
    for (const auto& o : w["overlapping_pairs"])
      std::printf("  %lld and %lld: %.3f m^2 (prior %.3f m^2)\n", o["a"].get<long long>(),
                  o["b"].get<long long>(), o["area_m2"].get<double>(),
                  o["prior_area_m2"].get<double>());
    for (const auto& r : w["roof_only"])
      std::printf(
          "roof only (building=roof/carport: no walls, not measured) %lld: wall-band points under "
          "it prior %zu -> corrected %zu, shift %.3f m\n",
          r["id"].get<long long>(), r["points_inside_prior"].get<size_t>(),
          r["points_inside_corrected"].get<size_t>(), r["shift_m"].get<double>());
    if (!w["osm_datum"].is_null())
      std::printf(
          "OSM datum (the extract's common offset) %.3f, %.3f m, %.3f deg; the largest "
          "unobserved shift after it %.3f m\n",
          w["osm_datum"]["x_m"].get<double>(), w["osm_datum"]["y_m"].get<double>(),
          w["osm_datum"]["yaw_rad"].get<double>() * 180.0 / M_PI,
          w["max_unobserved_shift_after_datum_m"].get<double>());
  }
  if (doc.count("baseline")) {
    const auto& b = doc["baseline"];
    std::printf(
        "baseline: sharpness %.5f m^2 (this run %+.1f %%), trajectory difference max %.3f m, mean "
        "%.3f m over %zu keyframes\n",
        b["mean_plane_variance"].get<double>(), 100.0 * b["sharpness_change"].get<double>(),
        b["trajectory_difference_max_m"].get<double>(),
        b["trajectory_difference_mean_m"].get<double>(), b["common_keyframes"].get<size_t>());
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::string run_dir, baseline_dir;
  bool json = false;
  WallAgreementOptions options;
  CommandLine cli("evaluate_map",
                  "A run measured without ground truth (a real drive): wall points at the "
                  "optimised poses against the prior's and the corrected building outlines, the "
                  "map's sharpness and, against a baseline run, the trajectory difference.");
  cli.option("--run", "DIR", "an offline_slam --output folder written with --dump DIR/dump",
             &run_dir)
      .required()
      .option("--baseline", "DIR", "a baseline run's folder (e.g. without OSM)", &baseline_dir)
      .option("--min-z", "Z", "the lowest wall point, base_link z in m", &options.min_z)
      .option("--max-z", "Z", "the highest wall point, base_link z in m", &options.max_z)
      .flag("--json", "print the report as JSON", &json);
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  Run run, baseline;
  std::string error;
  if (!loadRun(run_dir, run, &error) ||
      (!baseline_dir.empty() && !loadRun(baseline_dir, baseline, &error))) {
    std::cerr << "evaluate_map: " << error << "\n";
    return 1;
  }
  nlohmann::json doc = {{"keyframes", run.keyframes.size()}};
  const MapSharpness sharp = evaluateMapSharpness(run.keyframes);
  doc["sharpness"] = {{"points", sharp.points}, {"mean_plane_variance", sharp.mean_plane_variance}};
  if (!run.corrected.empty()) doc["walls"] = wallAgreementJson(run, run_dir, options);
  if (!baseline_dir.empty()) doc["baseline"] = baselineJson(run, baseline, sharp);
  if (json)
    std::cout << doc.dump(2) << "\n";
  else
    printReport(doc, run, sharp);
  return 0;
}
