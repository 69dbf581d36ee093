// building_pairs_benchmark: the candidate search behind shared walls and overlap removal
// (nearbyPolygonPairs, a sweep along x) against testing every pair of bounding boxes (the
// reference, measured in the same run), on random city blocks of growing size; also the full
// shared-wall and overlap searches that use it.
//   (the options: building_pairs_benchmark --help)
// --margin defaults to the shared-wall max distance; --repeat (default 5) runs each stage N times
// and prints the median.
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "osm_graph_slam/eval/building_metrics.h"
#include "osm_graph_slam/lines/line_geometry.h"
#include "osm_graph_slam/slam/building_contacts.h"
#include "support/command_line.h"

using namespace osm_graph_slam;

namespace {

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

/// Median wall time of `repeat` runs (the first run pays for cold caches and page faults).
template <typename F>
double medianMs(int repeat, F&& run) {
  std::vector<double> ms;
  for (int r = 0; r < std::max(repeat, 1); ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    run();
    ms.push_back(msSince(t0));
  }
  std::nth_element(ms.begin(), ms.begin() + ms.size() / 2, ms.end());
  return ms[ms.size() / 2];
}

/// n rectangles of 8-25 m at about the building density of the Karlsruhe extract (one per
/// 40 m x 40 m), some touching or overlapping, like a misplaced prior.
std::vector<Building> randomCity(int n) {
  std::mt19937 rng(1);
  const double side = 40.0 * std::sqrt(double(n));
  std::uniform_real_distribution<double> pos(0.0, side), size(8.0, 25.0);
  std::vector<Building> city(n);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d c(pos(rng), pos(rng));
    const double w = size(rng), h = size(rng);
    city[i].id = i;
    city[i].outline_enu = {c, c + Eigen::Vector2d(w, 0.0), c + Eigen::Vector2d(w, h),
                           c + Eigen::Vector2d(0.0, h)};
  }
  return city;
}

/// The reference: every pair of grown boxes.
size_t allPairsCount(const std::vector<const Polygon2*>& polygons, double margin) {
  std::vector<Eigen::AlignedBox2d> boxes(polygons.size());
  for (size_t i = 0; i < polygons.size(); ++i)
    for (const auto& v : *polygons[i]) boxes[i].extend(v);
  const Eigen::Vector2d grow = Eigen::Vector2d::Constant(margin);
  size_t count = 0;
  for (size_t i = 0; i < boxes.size(); ++i) {
    const Eigen::AlignedBox2d grown(boxes[i].min() - grow, boxes[i].max() + grow);
    for (size_t j = i + 1; j < boxes.size(); ++j) count += grown.intersects(boxes[j]) ? 1 : 0;
  }
  return count;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<int> sizes = {170, 1000, 5000, 20000};
  bool json = false;
  int repeat = 5;
  BuildingContactParams contact_params;
  tools::CommandLine cli(
      "building_pairs_benchmark",
      "The candidate search behind shared walls and overlap removal (a sweep along x) against "
      "testing every pair of bounding boxes, on random city blocks of growing size.");
  cli.option("--buildings", "N[,N...]", "the city sizes in buildings",
             [&sizes](const std::string& v) {
               sizes.clear();
               for (const auto& item : tools::splitCommaList(v))
                 sizes.push_back(std::atoi(item.c_str()));
               return std::string();
             })
      .defaultText("170,1000,5000,20000")
      .option("--margin", "M", "the pairs' distance margin (the shared-wall max distance)",
              &contact_params.max_distance)
      .option("--repeat", "N", "runs of each stage; the median counts", &repeat)
      .flag("--json", "print the results as JSON", &json);
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  if (!json)
    std::printf("margin (shared-wall max distance) %.2f m, median of %d runs\n",
                contact_params.max_distance, repeat);
  if (json)
    std::printf("[");
  else
    std::printf("%9s %8s %10s %14s %7s %13s %13s\n", "buildings", "pairs", "sweep ms",
                "all-pairs ms", "ratio", "contacts ms", "overlaps ms");
  for (size_t k = 0; k < sizes.size(); ++k) {
    const std::vector<Building> city = randomCity(std::max(sizes[k], 1));
    std::vector<const Polygon2*> polygons;
    std::vector<Polygon2> outlines;
    for (const auto& b : city) {
      polygons.push_back(&b.outline_enu);
      outlines.push_back(b.outline_enu);
    }
    const double margin = contact_params.max_distance;
    size_t pairs = 0, reference = 0, contacts = 0, overlaps = 0;
    const double sweep_ms =
        medianMs(repeat, [&] { pairs = nearbyPolygonPairs(polygons, margin).size(); });
    const double all_ms = medianMs(repeat, [&] { reference = allPairsCount(polygons, margin); });
    const double contacts_ms =
        medianMs(repeat, [&] { contacts = findBuildingContacts(outlines, contact_params).size(); });
    const double overlaps_ms =
        medianMs(repeat, [&] { overlaps = findOverlappingBuildings(city).size(); });
    if (pairs != reference)
      std::fprintf(stderr, "building_pairs_benchmark: sweep found %zu pairs, all-pairs %zu\n",
                   pairs, reference);
    if (json) {
      std::printf(
          "%s{\"buildings\": %zu, \"margin_m\": %.3f, \"pairs\": %zu, \"reference_pairs\": %zu, "
          "\"sweep_ms\": %.4f, "
          "\"all_pairs_ms\": %.4f, \"ratio\": %.2f, \"contacts\": %zu, \"contacts_ms\": %.4f, "
          "\"overlaps\": %zu, \"overlaps_ms\": %.4f}",
          k ? ", " : "", city.size(), contact_params.max_distance, pairs, reference, sweep_ms,
          all_ms, all_ms / sweep_ms, contacts, contacts_ms, overlaps, overlaps_ms);
    } else {
      std::printf("%9zu %8zu %10.3f %14.3f %6.1fx %13.3f %13.3f\n", city.size(), pairs, sweep_ms,
                  all_ms, all_ms / sweep_ms, contacts_ms, overlaps_ms);
    }
  }
  if (json) std::printf("]\n");
  return 0;
}
