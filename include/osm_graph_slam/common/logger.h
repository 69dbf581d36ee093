#pragma once
// A tiny injectable logger for the ROS-free core. Nodelets pass a sink that forwards to
// NODELET_*; tools and tests use the default sink (stderr).
#include <functional>
#include <mutex>
#include <set>
#include <string>

namespace osm_graph_slam {

enum class LogLevel { kDebug, kInfo, kWarn, kError };

using LogSink = std::function<void(LogLevel, const std::string&)>;

class Logger {
 public:
  /// An empty sink writes warnings and errors to stderr.
  explicit Logger(LogSink sink = {});

  void debug(const std::string& msg) const { log(LogLevel::kDebug, msg); }
  void info(const std::string& msg) const { log(LogLevel::kInfo, msg); }
  void warn(const std::string& msg) const { log(LogLevel::kWarn, msg); }
  void error(const std::string& msg) const { log(LogLevel::kError, msg); }
  void log(LogLevel level, const std::string& msg) const;

  /// Logs only the first message for a given key ("log once with the reason").
  void warnOnce(const std::string& key, const std::string& msg) const;
  /// Forget a key so that a recurring fault is reported again after it cleared.
  void resetOnce(const std::string& key) const;

 private:
  LogSink sink_;
  mutable std::mutex once_mutex_;
  mutable std::set<std::string> once_keys_;
};

/// A logger that drops everything (benchmarks).
Logger silentLogger();

}  // namespace osm_graph_slam
