#pragma once
// Files that are either whole or absent: a crash or a full disk never leaves a half-written file
// under the final name.
#include <string>

namespace osm_graph_slam {

/// Writes content to path atomically (path.tmp, fsync, then rename). Shared by every file writer.
bool writeFileAtomically(const std::string& path, const std::string& content,
                         std::string* error = nullptr);

}  // namespace osm_graph_slam
