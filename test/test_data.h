#pragma once
// Where tests find the real data of ../shared/data (never committed to this repository).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>

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

}  // namespace osm_graph_slam::test

/// Skips the current test with a clear message when a file of ../shared/data is absent.
#define OGS_REQUIRE_SHARED_FILE(path)                                                    \
  do {                                                                                   \
    if (!std::filesystem::exists(path)) {                                                \
      GTEST_SKIP() << "shared data file " << (path)                                      \
                   << " is absent (tests read real data from ../shared/data); skipping"; \
    }                                                                                    \
  } while (0)
