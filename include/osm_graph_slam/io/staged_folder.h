#pragma once
// A set of files that replaces its predecessor all at once or not at all. Every file of one save
// is written into a hidden folder inside the destination (same file system, so renames are
// atomic) and moved into place only when all of them were written. A save that fails (disk
// full, file size limit, I/O error) or is interrupted (SIGINT, crash) leaves the previous files
// exactly as they were; the next save removes the partial folder of a process that is gone.
#include <string>
#include <vector>

namespace osm_graph_slam {

class StagedFolder {
 public:
  StagedFolder() = default;
  StagedFolder(const StagedFolder&) = delete;
  StagedFolder& operator=(const StagedFolder&) = delete;
  ~StagedFolder();  ///< removes the staging folder of a save that was not committed

  /// Creates `target` if needed and the staging folder inside it. False with the reason.
  bool open(const std::string& target, std::string* error);
  /// Where to write `name` (a relative path; sub-folders are created by the caller).
  std::string stagedPath(const std::string& name) const;
  /// Where `name` is once committed.
  std::string finalPath(const std::string& name) const;
  /// Moves every top-level entry of the staging folder into the target, replacing entries of the
  /// same name (folders are swapped: the old one moved aside first, removed after the rename).
  bool commit(std::string* error);

  const std::string& staging() const { return staging_; }

 private:
  std::string target_;
  std::string staging_;
};

/// Replaces `to` by `from` (both on one file system). A folder at `to` is moved aside before and
/// removed only after the rename, so at every moment one complete version exists.
bool replacePath(const std::string& from, const std::string& to, std::string* error);

/// Flushes a folder's entries (renames, new files) to the disk; best effort.
void syncFolder(const std::string& folder);

}  // namespace osm_graph_slam
