#pragma once
// Reading a dump_graph directory back and replaying it into a GraphBackend: the back-end's
// inputs (keyframes, segments, floors, loops, buildings, origin) without the front-end, so that
// back-end parameters can be compared on the same drive in seconds (tools/replay_backend).
#include <optional>
#include <string>
#include <vector>

#include "osm_graph_slam/slam/graph_backend.h"

namespace osm_graph_slam {

struct GraphDump {
  std::vector<KeyframeInput> keyframes;  ///< clouds are not loaded
  std::map<uint64_t, std::vector<LineSegment2>> segments;
  std::vector<LoopClosureInput> loops;
  std::vector<Building> buildings;        ///< ENU filled when the origin is known
  std::optional<Eigen::Vector3d> origin;  ///< lat, lon, alt
  std::optional<double> initial_heading;  ///< [rad] ENU yaw of the first keyframe
};

/// Reads what dumpGraph wrote. Returns false with the file (and line) at fault.
bool readGraphDump(const std::string& directory, GraphDump& dump, std::string* error);

/// Loads keyframes/<id>.pcd of every keyframe into its cloud (dumpGraph's layout). Returns how
/// many keyframes have none; the first reason is in *error.
size_t loadDumpClouds(const std::string& directory, GraphDump& dump, std::string* error);

/// Feeds the dump in keyframe order, calling update() every `optimize_every` keyframes as the
/// offline pipeline does (loops arrive with their newer keyframe; buildings are available from
/// the start). Returns the last update's report with the match counts and times (total_ms,
/// stage_ms) summed over all updates.
/// final_full_batch false: the last update is a routine one too (optimization_window), for a
/// caller that solves the whole graph its own way (GraphBackend::optimizeInTiles).
BackendUpdateReport replayGraphDump(const GraphDump& dump, GraphBackend& backend,
                                    int optimize_every, bool final_full_batch = true);

}  // namespace osm_graph_slam
