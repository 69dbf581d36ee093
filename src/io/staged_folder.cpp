#include "osm_graph_slam/io/staged_folder.h"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <filesystem>

namespace osm_graph_slam {
namespace {

namespace fs = std::filesystem;

constexpr char kStagingPrefix[] = ".partial-";

bool fail(std::string* error, const std::string& why) {
  if (error) *error = why;
  return false;
}

/// The writer's pid in a staging folder's name, or 0 when the name is not one of ours.
pid_t stagingOwner(const std::string& name) {
  const std::string prefix = kStagingPrefix;
  if (name.compare(0, prefix.size(), prefix) != 0) return 0;
  const std::string rest = name.substr(prefix.size());
  const size_t dash = rest.find('-');
  try {
    return static_cast<pid_t>(std::stol(rest.substr(0, dash)));
  } catch (...) {
    return 0;
  }
}

/// A save killed mid-way leaves its staging folder; removed once its process is gone.
void removeAbandonedStaging(const fs::path& target) {
  std::error_code ec;
  for (fs::directory_iterator it(target, ec), end; !ec && it != end; it.increment(ec)) {
    const pid_t owner = stagingOwner(it->path().filename().string());
    if (owner > 0 && owner != ::getpid() && ::kill(owner, 0) != 0 && errno == ESRCH) {
      std::error_code ignored;
      fs::remove_all(it->path(), ignored);
    }
  }
}

}  // namespace

StagedFolder::~StagedFolder() {
  if (staging_.empty()) return;
  std::error_code ignored;
  fs::remove_all(staging_, ignored);
}

bool StagedFolder::open(const std::string& target, std::string* error) {
  if (target.empty()) return fail(error, "no destination folder given");
  std::error_code ec;
  fs::create_directories(target, ec);
  if (ec || !fs::is_directory(target))
    return fail(error, "cannot create folder '" + target +
                           "': " + (ec ? ec.message() : "a file of that name exists"));
  removeAbandonedStaging(target);
  static std::atomic<unsigned> counter{0};
  const fs::path staging = fs::path(target) / (kStagingPrefix + std::to_string(::getpid()) + "-" +
                                               std::to_string(counter++));
  fs::remove_all(staging, ec);
  if (!fs::create_directory(staging, ec) || ec)
    return fail(error, "folder '" + target + "' is not writable: cannot create '" +
                           staging.string() + "': " + ec.message());
  target_ = target;
  staging_ = staging.string();
  return true;
}

std::string StagedFolder::stagedPath(const std::string& name) const {
  return (fs::path(staging_) / name).string();
}

std::string StagedFolder::finalPath(const std::string& name) const {
  return (fs::path(target_) / name).string();
}

bool StagedFolder::commit(std::string* error) {
  if (staging_.empty()) return fail(error, "nothing staged");
  std::error_code ec;
  std::vector<fs::path> entries;
  for (fs::directory_iterator it(staging_, ec), end; !ec && it != end; it.increment(ec))
    entries.push_back(it->path());
  if (ec) return fail(error, "cannot list '" + staging_ + "': " + ec.message());
  syncFolder(staging_);
  for (const auto& entry : entries)
    if (!replacePath(entry.string(), finalPath(entry.filename().string()), error)) return false;
  syncFolder(target_);
  fs::remove_all(staging_, ec);
  staging_.clear();
  return true;
}

bool replacePath(const std::string& from, const std::string& to, std::string* error) {
  std::error_code ec;
  if (!fs::is_directory(to, ec)) {
    fs::rename(from, to, ec);  // a file is replaced atomically
    return ec ? fail(error, "cannot rename '" + from + "' to '" + to + "': " + ec.message()) : true;
  }
  const fs::path old = to + ".old-" + std::to_string(::getpid());
  fs::remove_all(old, ec);
  fs::rename(to, old, ec);
  if (ec) return fail(error, "cannot move '" + to + "' aside: " + ec.message());
  fs::rename(from, to, ec);
  if (ec) {
    const std::string why = ec.message();
    fs::rename(old, to, ec);
    return fail(error, "cannot rename '" + from + "' to '" + to + "': " + why);
  }
  fs::remove_all(old, ec);
  return true;
}

void syncFolder(const std::string& folder) {
  const int fd = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

}  // namespace osm_graph_slam
