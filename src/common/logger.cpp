#include "osm_graph_slam/common/logger.h"

#include <iostream>

namespace osm_graph_slam {

Logger::Logger(LogSink sink) : sink_(std::move(sink)) {}

void Logger::log(LogLevel level, const std::string& msg) const {
  if (sink_) {
    sink_(level, msg);
    return;
  }
  if (level == LogLevel::kWarn) std::cerr << "[WARN] " << msg << '\n';
  if (level == LogLevel::kError) std::cerr << "[ERROR] " << msg << '\n';
}

void Logger::warnOnce(const std::string& key, const std::string& msg) const {
  {
    std::lock_guard<std::mutex> lock(once_mutex_);
    if (!once_keys_.insert(key).second) return;
  }
  warn(msg);
}

void Logger::resetOnce(const std::string& key) const {
  std::lock_guard<std::mutex> lock(once_mutex_);
  once_keys_.erase(key);
}

Logger silentLogger() {
  return Logger([](LogLevel, const std::string&) {});
}

}  // namespace osm_graph_slam
