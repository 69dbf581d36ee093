#pragma once
// Forwards the core's log lines (Logger) to rosconsole under a nodelet's name, as NODELET_* do.
#include <ros/console.h>

#include <string>

#include "osm_graph_slam/common/logger.h"

namespace osm_graph_slam {

inline LogSink nodeletLogSink(const std::string& name) {
  return [name](LogLevel level, const std::string& msg) {
    switch (level) {
      case LogLevel::kDebug:
        ROS_DEBUG_STREAM_NAMED(name, msg);
        break;
      case LogLevel::kInfo:
        ROS_INFO_STREAM_NAMED(name, msg);
        break;
      case LogLevel::kWarn:
        ROS_WARN_STREAM_NAMED(name, msg);
        break;
      case LogLevel::kError:
        ROS_ERROR_STREAM_NAMED(name, msg);
        break;
    }
  };
}

}  // namespace osm_graph_slam
