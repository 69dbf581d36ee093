#pragma once
// Where tests find the real data of ../shared/data (never committed to this repository).
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

namespace osm_graph_slam::test {

/// $OGS_SHARED_DATA_DIR if set, else ../shared/data beside the checkout (resolved at configure).
inline std::string sharedDataDir() {
  if (const char* env = std::getenv("OGS_SHARED_DATA_DIR")) return env;
  return OGS_SHARED_DATA_DIR;
}

inline std::string sharedDataPath(const std::string& relative) {
  return sharedDataDir() + "/" + relative;
}

inline std::string sourceDir() {
  return OGS_SOURCE_DIR;
}

/// Unpacks scans first..first+count-1 of kitti_raw_0005/velodyne.tar.xz into dir (only those
/// members: tar still reads the whole 287 MB archive, ~7 s). Their paths, or empty with the reason.
inline std::vector<std::string> unpackKitti0005Scans(const std::filesystem::path& dir, int first,
                                                     int count, std::string* why) {
  const std::string archive = sharedDataPath("kitti_raw_0005/velodyne.tar.xz");
  std::filesystem::create_directories(dir);
  std::vector<std::string> files;
  std::string members;
  for (int i = first; i < first + count; ++i) {
    char name[64];
    std::snprintf(name, sizeof(name), "velodyne/%010d.bin", i);
    members += std::string(" '") + name + "'";
    files.push_back((dir / name).string());
  }
  const std::string log = (dir / "tar.log").string();
  const std::string command = "tar xJf '" + archive + "' -C '" + dir.string() + "' --occurrence=1" +
                              members + " > '" + log + "' 2>&1";
  if (std::system(command.c_str()) != 0) {
    *why = "cannot unpack " + archive + " (see " + log + ")";
    return {};
  }
  for (const auto& f : files)
    if (!std::filesystem::exists(f)) {
      *why = f + " missing after unpacking " + archive;
      return {};
    }
  return files;
}

}  // namespace osm_graph_slam::test

/// Skips the current test with a clear message when a file of ../shared/data is absent.
#define OGS_REQUIRE_SHARED_FILE(path)                                                    \
  do {                                                                                   \
    if (!std::filesystem::exists(path)) {                                                \
      GTEST_SKIP() << "shared data file " << (path)                                      \
                   << " is absent (tests read real data from ../shared/data); skipping"; \
    }                                                                                    \
  } while (0)
