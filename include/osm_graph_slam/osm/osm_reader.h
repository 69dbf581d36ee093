#pragma once
// Reading OSM XML / PBF through libosmium (implementation keeps libosmium out of this header).
#include <string>
#include <vector>

#include "osm_graph_slam/osm/building.h"

namespace osm_graph_slam {

struct OsmReadStats {
  size_t ways_seen = 0;
  size_t relations_seen = 0;
  size_t buildings = 0;
  size_t roads = 0;
  size_t skipped_missing_nodes = 0;  ///< ways with nodes absent from the extract (clipped)
  size_t skipped_degenerate = 0;     ///< outlines with fewer than 3 distinct vertices
  size_t skipped_open = 0;           ///< building ways whose first and last node differ
  size_t skipped_relations = 0;      ///< building relations missing members or not assemblable
};

/// Limits that keep memory bounded on hostile or huge inputs.
struct OsmReadOptions {
  /// Ways (buildings, roads, relation members) and relations kept in memory at most.
  size_t max_objects = 5'000'000;
  /// Node locations kept in memory at most (only nodes referenced by kept ways are stored).
  size_t max_nodes = 50'000'000;
  bool read_roads = true;
};

struct OsmData {
  std::vector<Building> buildings;  ///< outline_enu etc. empty until EnuConverter fills them
  std::vector<Road> roads;          ///< ways tagged highway=*
  OsmReadStats stats;
  bool ok = false;
  std::string error;  ///< why reading failed (ok == false); partial data is kept
};

/// Reads a .osm (XML) or .osm.pbf file (chosen by extension). Never throws.
OsmData readOsmFile(const std::string& path, const OsmReadOptions& options = {});

/// Parses an OSM XML document held in memory (an Overpass answer). Never throws.
OsmData parseOsmXml(const std::string& xml, const OsmReadOptions& options = {});

}  // namespace osm_graph_slam
