#pragma once
// An incremental KD-tree over fixed-dimension float vectors (nanoflann's dynamic index: a
// logarithmic forest of static trees, so an insertion costs amortised O(log n) rebuild work).
// Used for the Scan Context ring keys and for keyframe positions. nanoflann stays in the .cpp.
#include <cstddef>
#include <memory>
#include <utility>
#include <vector>

namespace osm_graph_slam {

class DynamicKdIndex {
 public:
  explicit DynamicKdIndex(int dimension);
  ~DynamicKdIndex();
  DynamicKdIndex(const DynamicKdIndex&) = delete;
  DynamicKdIndex& operator=(const DynamicKdIndex&) = delete;

  int dimension() const { return dimension_; }
  size_t size() const;
  /// Appends a vector (its index is the previous size()); wrong dimensions are rejected.
  bool add(const float* values);

  /// (index, squared distance) of the k nearest vectors whose index is < index_limit, closest
  /// first.
  std::vector<std::pair<size_t, float>> knn(const float* query, size_t k, size_t index_limit) const;
  /// (index, squared distance) of every vector within radius whose index is < index_limit.
  std::vector<std::pair<size_t, float>> radius(const float* query, float radius,
                                               size_t index_limit) const;

 private:
  struct Impl;
  int dimension_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace osm_graph_slam
