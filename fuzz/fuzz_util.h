#pragma once
// Helpers shared by the libFuzzer targets: a private scratch directory (tmpfs when available)
// and whole-file writes, for readers that only take a path.
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
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

/// A scratch file that cannot be written is a fault of the machine, not of the reader: it is
/// named on stderr before the abort so that the log tells it from a finding.
inline void writeFile(const std::string& path, const uint8_t* data, size_t size) {
  FILE* f = std::fopen(path.c_str(), "wb");
  if (!f || (size && std::fwrite(data, 1, size, f) != size) || std::fclose(f) != 0) {
    std::fprintf(stderr, "fuzz harness: cannot write scratch file %s: %s\n", path.c_str(),
                 std::strerror(errno));
    std::abort();
  }
}

inline void writeFile(const std::string& path, const std::string& text) {
  writeFile(path, reinterpret_cast<const uint8_t*>(text.data()), text.size());
}

}  // namespace ogs_fuzz
