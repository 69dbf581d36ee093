#pragma once
// One 64-bit key for a 2D grid cell (hash maps of occupied cells). The shift is done on the
// unsigned bit pattern: shifting a negative signed index is undefined behaviour in C++17
// (UBSan, scripts/test.sh --sanitize); the bits are those of the old (x << 32) ^ (y & mask).
#include <cstdint>

namespace osm_graph_slam {

inline int64_t packCellKey(int64_t x, int64_t y) {
  return static_cast<int64_t>((uint64_t(uint32_t(x)) << 32) | uint64_t(uint32_t(y)));
}

}  // namespace osm_graph_slam
