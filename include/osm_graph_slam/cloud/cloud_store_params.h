#pragma once
// Parameters of the keyframe cloud store (cloud/cloud_store.h) and its codec, apart from them so
// that backend_params.h can hold them without pulling PCL into every back-end user.
#include <string>

#include "osm_graph_slam/common/param_declaration.h"

namespace osm_graph_slam {

struct CloudCodecParams {
  /// [m] quantisation step. A cloud wider than 65,534 steps gets the step that fits it (stated in
  /// the encoding), so an encoding never fails. <= 0: lossless (float32 planes).
  double resolution = 0.01;
  /// zlib level 0-9 of the shuffled planes (0: stored as they are, 8 bytes a point). Level 1:
  /// 6.1 bytes a point on the real KITTI drive (doc/long_drives.md).
  int deflate_level = 1;
};

struct CloudStoreParams {
  CloudCodecParams codec;
  /// [MB] encoded clouds kept in memory; the least recently used beyond it live only on disk.
  /// 256 MB holds ~1,350 keyframes of the real KITTI drive losslessly (15k points, 189 kB each),
  /// ~2,900 at 1 cm (89 kB).
  double resident_mb = 256.0;
  /// Parent of the store's own directory (DIR/cloud_store_<pid>_<n>), removed with the store.
  /// Empty: the system's temporary directory.
  std::string directory;

  template <class V>
  void visit(V& v) {
    v("cloud_store_resident_mb", resident_mb,
      "[MB] encoded keyframe clouds kept in memory; older ones are spilled to disk");
    v("cloud_store_directory", directory,
      "where spilled keyframe clouds go (a folder of its own inside; \"\": the temp directory)");
    v("cloud_store_resolution", codec.resolution,
      "[m] quantisation of stored keyframe clouds (0: lossless)");
    v("cloud_store_deflate_level", codec.deflate_level,
      "zlib level of stored keyframe clouds (0: none, 8 B a point; 1: 6.1 B on KITTI)");
  }
};

}  // namespace osm_graph_slam
