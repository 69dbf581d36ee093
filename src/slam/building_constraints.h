#pragma once
// Building<->building constraints of the back-end: the consistency gate on robot<->building
// edges, shared walls between touching buildings, and overlap resolution (OSM thesis Alg. 3.2).
// Internal to src/slam/.
#include <map>
#include <optional>
#include <utility>
#include <vector>

#include "backend_state.h"
#include "osm_graph_slam/slam/building_contacts.h"

namespace osm_graph_slam {

class BuildingConstraints {
 public:
  /// optimizer: every optimisation of the overlap resolution.
  BuildingConstraints(OsmMode mode, const BuildingConstraintParams& params,
                      const OsmPriorParams& prior, const LineMatcherParams& matcher,
                      const OptimizerOptions& optimizer)
      : mode_(mode), params_(params), prior_(prior), optimizer_(optimizer), matcher_(matcher) {}

  /// Removes robot<->building edges whose χ² against the building as its other observations
  /// place it (after phase 2) exceeds building_edge_gate_chi2. Returns how many.
  size_t gateBuildingEdges(BackendState& s, BackendUpdateReport& report) const;

  /// Ties buildings that share a wall in the prior, once one of them is in the graph.
  void addSharedWallEdges(BackendState& s, BackendUpdateReport& report);

  /// Removes the overlap edges of the last resolution (they are re-derived every time).
  void removeOverlapEdges(BackendState& s);
  /// Hard building<->building edges until no outlines intersect (level 2, robots fixed).
  void resolveOverlaps(BackendState& s, BackendUpdateReport& report);

 private:
  struct SharedWall {
    BuildingContact contact;  ///< ENU prior geometry
    bool tied = false;        ///< its two wall-end-on-wall edges are in the graph
  };
  void findNewContacts(const BackendState& s);
  /// One overlap-removal edge moving the less observed of the two; false if none separates them.
  bool addSeparationEdge(BackendState& s, BuildingState* a, BuildingState* b);
  /// The overlaps the hard edges left (a building wedged between neighbours that both moved
  /// towards it: their edges push it back and forth): the less observed building of each pair
  /// is moved by the shortest translation that clears it of every outline. Returns the pairs
  /// still overlapping.
  std::vector<std::pair<size_t, size_t>> projectOutOfOverlaps(
      BackendState& s, const std::vector<BuildingState*>& order, std::vector<Building>& outlines,
      std::vector<std::pair<size_t, size_t>> overlaps) const;
  /// The shortest translation (rings of 1 cm, 10 degree steps, at most
  /// overlap_projection_max_translation) after which outline `mover` overlaps no other by more
  /// than half of overlap_min_area, plus overlap_clearance; nullopt if there is none.
  std::optional<Eigen::Vector2d> clearingTranslation(size_t mover,
                                                     const std::vector<Building>& outlines) const;

  const OsmMode mode_;
  const BuildingConstraintParams& params_;
  const OsmPriorParams& prior_;
  const OptimizerOptions& optimizer_;
  LineMatcher matcher_;
  std::map<std::pair<int64_t, int64_t>, SharedWall> shared_walls_;
  size_t shared_walls_searched_ = 0;  ///< number of buildings at the last search
  std::vector<int> overlap_edges_;
};

}  // namespace osm_graph_slam
