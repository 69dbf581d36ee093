#pragma once
// Reading and writing the g2o text format (the format of the public pose-graph datasets).
//
// Supported tags: VERTEX_SE2, EDGE_SE2, VERTEX_SE3:QUAT, EDGE_SE3:QUAT, VERTEX_XY, EDGE_SE2_XY,
// EDGE_PRIOR_SE2, FIX. Information matrices are stored as their upper triangle, row by row.
// Vertices referenced by edges but never declared (edge-only files such as M3500) are
// initialised by composing the odometry chain (edges between consecutive ids), then by a
// breadth-first walk over the remaining edges.
#include <iosfwd>
#include <string>

#include "osm_graph_slam/graph/pose_graph.h"

namespace osm_graph_slam {

struct G2oReadResult {
  bool ok = false;
  int line = 0;         ///< 1-based line of the first error (0: not tied to a line)
  std::string message;  ///< "line N: ..." on error
  int num_vertices = 0;
  int num_edges = 0;
  int num_fixed = 0;
  int num_initialised = 0;  ///< vertices not declared in the file, initialised from edges
};

/// Reads a graph. On error the output graph is left untouched (nothing is half-read).
G2oReadResult readG2o(const std::string& path, PoseGraph* graph);
G2oReadResult readG2o(std::istream& in, PoseGraph* graph);

struct G2oWriteResult {
  bool ok = false;
  std::string message;
  int num_vertices = 0;
  int num_edges = 0;
  int num_skipped_edges = 0;  ///< edge types the g2o format above cannot express (SE3 priors...)
};

/// Writes every vertex, FIX lines for fixed vertices and every expressible edge, with 17
/// significant digits (exact round trip). The file is written to a temp file, then renamed.
G2oWriteResult writeG2o(const PoseGraph& graph, const std::string& path);
G2oWriteResult writeG2o(const PoseGraph& graph, std::ostream& out);

}  // namespace osm_graph_slam
