#pragma once
// Helpers shared by the libFuzzer targets: a private scratch directory (tmpfs when available)
// and whole-file writes, for readers that only take a path.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace ogs_fuzz {

/// A directory of this process, created on first use and reused by every execution.
inline const std::string& scratchDir() {
  static const std::string dir = [] {
    const char* base = std::getenv("OGS_FUZZ_TMP");
    std::string pattern =
        std::string(base ? base : (access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp")) +
        "/ogs_fuzz_XXXXXX";
    if (!mkdtemp(pattern.data())) std::abort();
    return pattern;
  }();
  return dir;
}

inline std::string scratchPath(const std::string& name) {
  return scratchDir() + "/" + name;
}

inline void writeFile(const std::string& path, const uint8_t* data, size_t size) {
  FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) std::abort();
  if (size && std::fwrite(data, 1, size, f) != size) std::abort();
  std::fclose(f);
}

inline void writeFile(const std::string& path, const std::string& text) {
  writeFile(path, reinterpret_cast<const uint8_t*>(text.data()), text.size());
}

}  // namespace ogs_fuzz
