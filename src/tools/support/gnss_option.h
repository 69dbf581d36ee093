#pragma once
// --gnss all|origin of the runners that build a graph (offline_slam, replay_backend): the same
// drive run as if GNSS had failed after its first fix, the baseline "odometry + loops" of the
// drive matrix and the setting of the real KITTI drive (doc/matrix.md, GNSS modes).
#include "osm_graph_slam/slam/backend_params.h"
#include "support/command_line.h"

namespace osm_graph_slam::tools {

struct GnssUse {
  bool origin_only = false;
  /// origin: the first fix places the map (the origin, and the first keyframe's anchor) and no
  /// fix after it reaches the graph: gnss_prior_std 0, whose meaning that is (backend_params.h).
  void apply(GnssParams& gnss) const {
    if (origin_only) gnss.gnss_prior_std = 0.0;
  }
};

inline void addGnssUseOption(CommandLine& cli, GnssUse& use) {
  cli.option("--gnss", "all|origin",
             "origin: the first fix is the map origin and anchors the first keyframe, no fix "
             "after it is used (a GNSS-denied run; overrides gnss_prior_std with 0)",
             [&use](const std::string& v) {
               if (v != "all" && v != "origin") return std::string("expects all or origin");
               use.origin_only = v == "origin";
               return std::string();
             })
      .defaultText("all");
}

}  // namespace osm_graph_slam::tools
