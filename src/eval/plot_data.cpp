#include "osm_graph_slam/eval/plot_data.h"

#include <nlohmann/json.hpp>

namespace osm_graph_slam {
namespace {

using nlohmann::json;

json xy(const std::vector<Eigen::Vector3d>& points) {
  json out = json::array();
  for (const auto& p : points) out.push_back({p.x(), p.y()});
  return out;
}

json trajectoryPlot(const TrajectoryErrors& e) {
  return {{"estimate_xy", xy(e.estimate_positions)},
          {"ground_truth_xy", xy(e.ground_truth_positions)},
          {"ate", e.ate_per_pose},
          {"distance", e.distance_along_path}};
}

json outlines(const std::vector<Building>& buildings) {
  json out = json::array();
  for (const auto& b : buildings) {
    json ring = json::array();
    for (const auto& v : b.outline_enu) ring.push_back({v.x(), v.y()});
    out.push_back({{"id", b.id}, {"outline", ring}});
  }
  return out;
}

}  // namespace

std::string plotDataJson(const SlamEvaluationInput& input, const SlamEvaluation& evaluation) {
  json doc = {{"slam", trajectoryPlot(evaluation.slam)},
              {"baseline_label", evaluation.baseline_label},
              {"buildings_true", outlines(input.buildings_true)},
              {"buildings_prior", outlines(input.buildings_prior)},
              {"buildings_corrected", outlines(input.buildings_corrected)}};
  if (evaluation.baseline) doc["baseline"] = trajectoryPlot(*evaluation.baseline);
  return doc.dump();
}

}  // namespace osm_graph_slam
