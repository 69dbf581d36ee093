#pragma once
// The keyframe message (scan_matching -> graph_backend, loop_detection, ...) and the back-end's
// keyframe input: one conversion each way.
#include <string>

#include "osm_graph_slam/KeyFrame.h"
#include "osm_graph_slam/slam/graph_backend.h"

namespace osm_graph_slam {

/// Fills every field but the header, the cloud and recovery_gap, which the sender sets: it may
/// forward the cloud it received without converting it.
void toKeyFrameMsg(const KeyframeInput& kf, KeyFrame& msg);

/// The message as the back-end's input (no sensor aiding yet). False, with the reason in
/// cloud_error, when the cloud is unusable: the keyframe is still filled, without a cloud.
bool fromKeyFrameMsg(const KeyFrame& msg, KeyframeInput& kf, std::string* cloud_error);

}  // namespace osm_graph_slam
