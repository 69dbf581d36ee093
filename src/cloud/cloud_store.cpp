#include "osm_graph_slam/cloud/cloud_store.h"

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "osm_graph_slam/common/atomic_file.h"
#include "osm_graph_slam/common/timing.h"

namespace osm_graph_slam {
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

CloudStore::CloudStore(CloudStoreParams params, LogSink log_sink)
    : params_(std::move(params)), logger_(std::move(log_sink)) {}

CloudStore::~CloudStore() {
  if (!owns_directory_) return;
  std::error_code ec;
  fs::remove_all(directory_, ec);  // best effort: a leftover directory holds only whole files
}

void CloudStore::put(uint64_t id, const PointCloud& cloud) {
  const auto t0 = Clock::now();
  std::string bytes = encodeCloud(cloud, params_.codec);
  const double encode_ms = msSince(t0);

  std::lock_guard<std::mutex> lock(mutex_);
  stats_.encode_ms += encode_ms;
  auto it = entries_.find(id);
  if (it != entries_.end()) removeEntry(id, it->second);
  Entry& e = entries_[id];
  e.size = bytes.size();
  e.points = cloud.size();
  e.bytes = std::move(bytes);
  lru_.push_front(id);
  e.lru = lru_.begin();
  ++stats_.clouds, ++stats_.resident;
  stats_.resident_bytes += e.size;
  stats_.encoded_bytes += e.size;
  stats_.points += e.points;
  stats_.pcl_bytes += e.points * sizeof(PointT);
  spillBeyondBudget();
}

void CloudStore::removeEntry(uint64_t id, Entry& e) {
  if (!e.bytes.empty()) {  // resident (an encoding is never empty: it has a header)
    lru_.erase(e.lru);
    --stats_.resident;
    stats_.resident_bytes -= e.bytes.size();
  }
  if (e.on_disk) {
    std::error_code ec;
    fs::remove(path(id), ec);
    --stats_.on_disk;
    stats_.disk_bytes -= e.size;
  }
  --stats_.clouds;
  stats_.encoded_bytes -= e.size;
  stats_.points -= e.points;
  stats_.pcl_bytes -= e.points * sizeof(PointT);
  entries_.erase(id);
}

void CloudStore::erase(uint64_t id) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = entries_.find(id);
  if (it != entries_.end()) removeEntry(id, it->second);
}

void CloudStore::spillBeyondBudget() {
  const double budget = params_.resident_mb * 1024.0 * 1024.0;
  // The newest cloud always stays: it is the one the caller is about to use.
  while (stats_.resident_bytes > budget && lru_.size() > 1) {
    const uint64_t id = lru_.back();
    Entry& e = entries_.at(id);
    if (!e.on_disk) {
      const auto t0 = Clock::now();
      std::string why;
      if (!ensureDirectory() || !writeFileAtomically(path(id), e.bytes, &why)) {
        // Kept in memory: memory grows past the budget, nothing is lost.
        ++stats_.write_errors;
        stats_.last_error = why.empty() ? stats_.last_error : why;
        logger_.warnOnce("cloud_store_write",
                         "keyframe cloud store: cannot spill cloud " + std::to_string(id) +
                             " to disk (" + stats_.last_error +
                             "); clouds stay in memory past the budget (reported once)");
        return;
      }
      stats_.write_ms += msSince(t0);
      e.on_disk = true;
      ++stats_.on_disk;
      stats_.disk_bytes += e.size;
    }
    lru_.pop_back();
    stats_.resident_bytes -= e.bytes.size();
    --stats_.resident;
    std::string().swap(e.bytes);
  }
}

bool CloudStore::ensureDirectory() {
  if (!directory_.empty()) return true;
  static std::atomic<int> counter{0};
  std::error_code ec;
  const fs::path parent =
      params_.directory.empty() ? fs::temp_directory_path(ec) : fs::path(params_.directory);
  const fs::path dir = parent / ("cloud_store_" + std::to_string(::getpid()) + "_" +
                                 std::to_string(counter.fetch_add(1)));
  // A folder of this name is a crashed process's of the same pid: nothing reads it any more.
  if (!ec && fs::exists(dir, ec)) fs::remove_all(dir, ec);
  if (ec || !fs::create_directories(dir, ec) || ec) {
    stats_.last_error = "cannot create '" + dir.string() + "': " + ec.message();
    return false;
  }
  directory_ = dir.string();
  owns_directory_ = true;
  return true;
}

std::string CloudStore::path(uint64_t id) const {
  return (fs::path(directory_) / (std::to_string(id) + ".ogsc")).string();
}

std::string CloudStore::readFile(uint64_t id, std::string* error) const {
  const auto t0 = Clock::now();
  std::ifstream in(path(id), std::ios::binary);
  std::ostringstream bytes;
  if (in) bytes << in.rdbuf();
  stats_.read_ms += msSince(t0);
  if (!in) {
    if (error) *error = "cannot read '" + path(id) + "'";
    return {};
  }
  return bytes.str();
}

void CloudStore::touch(Entry& e, uint64_t id) const {
  lru_.erase(e.lru);
  lru_.push_front(id);
  e.lru = lru_.begin();
}

std::string CloudStore::encoded(uint64_t id, std::string* error) const {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = entries_.find(id);
  if (it == entries_.end()) {
    if (error) *error = "no cloud " + std::to_string(id) + " in the store";
    return {};
  }
  Entry& e = it->second;
  if (!e.bytes.empty()) {
    touch(e, id);
    return e.bytes;
  }
  // Spilled: read back without making it resident again, so that an export over every
  // keyframe does not push the working set around the vehicle out of memory.
  return readFile(id, error);
}

PointCloudConstPtr CloudStore::get(uint64_t id, std::string* error) const {
  std::string why;
  const std::string bytes = encoded(id, &why);
  PointCloudPtr cloud;
  if (!bytes.empty()) {
    const auto t0 = Clock::now();
    cloud = decodeCloud(bytes, &why);
    std::lock_guard<std::mutex> lock(mutex_);
    stats_.decode_ms += msSince(t0);
  }
  if (!cloud) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (entries_.count(id)) {
      ++stats_.read_errors;
      stats_.last_error = "cloud " + std::to_string(id) + ": " + why;
      logger_.warnOnce("cloud_store_read", "keyframe cloud store: " + stats_.last_error +
                                               "; left out where it is needed (reported once)");
    }
    if (error) *error = "cloud " + std::to_string(id) + ": " + why;
  }
  return cloud;
}

bool CloudStore::contains(uint64_t id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return entries_.count(id) > 0;
}

size_t CloudStore::points(uint64_t id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = entries_.find(id);
  return it == entries_.end() ? 0 : it->second.points;
}

CloudStoreStats CloudStore::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

std::string CloudStore::directory() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return directory_;
}

std::string CloudStore::filePath(uint64_t id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = entries_.find(id);
  return it != entries_.end() && it->second.on_disk ? path(id) : std::string();
}

StoredCloud::StoredCloud(PointCloudConstPtr cloud)
    : cloud_(std::move(cloud)), points_(cloud_ ? cloud_->size() : 0) {}

StoredCloud::StoredCloud(std::shared_ptr<CloudStore> store, uint64_t id,
                         const PointCloudConstPtr& cloud) {
  if (!cloud || !store) {
    *this = StoredCloud(cloud);
    return;
  }
  store->put(id, *cloud);
  store_ = std::move(store);
  id_ = id;
  points_ = cloud->size();
}

void StoredCloud::erase() {
  if (store_) store_->erase(id_);
  *this = StoredCloud();
}

StoredCloud::StoredCloud(Reader read, size_t points)
    : read_(std::make_shared<const Reader>(std::move(read))), points_(points) {}

PointCloudConstPtr StoredCloud::load(std::string* error) const {
  if (read_) return (*read_)(error);
  if (cloud_ || !store_) return cloud_;
  return store_->get(id_, error);
}

}  // namespace osm_graph_slam
