#pragma once
// Keyframe clouds held over hours in bounded memory. Each cloud is kept encoded (cloud_codec.h:
// ~8x smaller than PCL's points); beyond `resident_mb` of encodings the least recently used
// ones are written to disk, one file per cloud, and dropped from memory. A spilled cloud is read
// back when asked for. Files are written atomically, so a crash leaves whole files or none.
#include <cstdint>
#include <functional>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>

#include "osm_graph_slam/cloud/cloud_codec.h"
#include "osm_graph_slam/cloud/cloud_store_params.h"
#include "osm_graph_slam/cloud/point_cloud.h"
#include "osm_graph_slam/common/logger.h"

namespace osm_graph_slam {

struct CloudStoreStats {
  size_t clouds = 0;
  size_t resident = 0;  ///< encodings in memory
  size_t on_disk = 0;   ///< clouds with a file (resident or not)
  size_t resident_bytes = 0;
  size_t disk_bytes = 0;
  size_t points = 0;
  size_t pcl_bytes = 0;  ///< what the same clouds take as PCL points
  size_t encoded_bytes = 0;
  size_t write_errors = 0;  ///< spills that failed: the cloud stayed in memory
  size_t read_errors = 0;   ///< loads that failed: the file was missing or corrupt
  std::string last_error;
  double encode_ms = 0.0, decode_ms = 0.0, write_ms = 0.0, read_ms = 0.0;  ///< totals
};

class CloudStore {
 public:
  /// Creates the store's directory lazily, at the first spill. Thread-safe. The first failed
  /// spill and the first failed read are logged (once each) to log_sink.
  explicit CloudStore(CloudStoreParams params = {}, LogSink log_sink = {});
  ~CloudStore();
  CloudStore(const CloudStore&) = delete;
  CloudStore& operator=(const CloudStore&) = delete;

  /// Encodes and keeps cloud under id (replacing an earlier one), then spills beyond the budget.
  void put(uint64_t id, const PointCloud& cloud);
  /// The cloud (decoded; within the codec's resolution of the one put), or null: unknown id, or
  /// its file missing or corrupt (*error says which; counted in stats().read_errors).
  PointCloudConstPtr get(uint64_t id, std::string* error = nullptr) const;
  /// The encoding, read from disk when spilled (empty on error).
  std::string encoded(uint64_t id, std::string* error = nullptr) const;
  bool contains(uint64_t id) const;
  size_t points(uint64_t id) const;  ///< without decoding (0 when unknown)
  void erase(uint64_t id);
  CloudStoreStats stats() const;
  /// The directory spilled files go to (empty before the first spill).
  std::string directory() const;
  /// The file of a spilled cloud (empty when it has none), for tests and tools.
  std::string filePath(uint64_t id) const;

 private:
  struct Entry {
    std::string bytes;  ///< empty when spilled
    size_t size = 0;    ///< encoded bytes
    size_t points = 0;
    bool on_disk = false;
    std::list<uint64_t>::iterator lru;
  };
  void touch(Entry& entry, uint64_t id) const;
  void spillBeyondBudget();
  bool ensureDirectory();
  std::string path(uint64_t id) const;
  std::string readFile(uint64_t id, std::string* error) const;
  void removeEntry(uint64_t id, Entry& entry);

  CloudStoreParams params_;
  Logger logger_;
  std::string directory_;
  bool owns_directory_ = false;
  mutable std::mutex mutex_;
  mutable std::unordered_map<uint64_t, Entry> entries_;
  mutable std::list<uint64_t> lru_;  ///< resident ids, most recently used first
  mutable CloudStoreStats stats_;
};

/// A keyframe's cloud as held by the back-end: a cloud held directly (dumps, tests), an id in a
/// shared CloudStore, or a file read when needed (a map package). Copies are cheap and share it.
class StoredCloud {
 public:
  StoredCloud() = default;
  StoredCloud(PointCloudConstPtr cloud);   // NOLINT: a held cloud converts implicitly
  StoredCloud(const PointCloudPtr& cloud)  // NOLINT: as does a mutable one
      : StoredCloud(PointCloudConstPtr(cloud)) {}
  /// Reads the cloud with `read` at each load() (nothing held in memory); points: its size.
  using Reader = std::function<PointCloudConstPtr(std::string* error)>;
  StoredCloud(Reader read, size_t points);
  /// Puts cloud into store under id (a null cloud gives an empty handle).
  StoredCloud(std::shared_ptr<CloudStore> store, uint64_t id, const PointCloudConstPtr& cloud);

  /// True when a cloud was given (even an empty one), as a shared_ptr is.
  explicit operator bool() const { return cloud_ || store_ || read_; }
  size_t size() const { return points_; }
  bool empty() const { return size() == 0; }
  /// The cloud; null when none was given or its spilled file cannot be read (*error says why).
  PointCloudConstPtr load(std::string* error = nullptr) const;
  /// Removes the cloud from its store (a keyframe refused after it was stored) and empties the
  /// handle. Other copies of the handle then load null.
  void erase();

 private:
  PointCloudConstPtr cloud_;
  std::shared_ptr<const Reader> read_;
  std::shared_ptr<CloudStore> store_;
  uint64_t id_ = 0;
  size_t points_ = 0;
};

}  // namespace osm_graph_slam
