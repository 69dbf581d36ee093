#include "osm_graph_slam/common/dynamic_kd_index.h"

#include <algorithm>
#include <limits>
#include <nanoflann.hpp>

namespace osm_graph_slam {
namespace {

/// Flat row-major storage seen by nanoflann.
struct FlatDataset {
  int dim = 0;
  std::vector<float> data;
  size_t kdtree_get_point_count() const { return dim > 0 ? data.size() / dim : 0; }
  float kdtree_get_pt(size_t idx, size_t d) const { return data[idx * dim + d]; }
  template <class BBox>
  bool kdtree_get_bbox(BBox&) const {
    return false;
  }
};

using Tree =
    nanoflann::KDTreeSingleIndexDynamicAdaptor<nanoflann::L2_Simple_Adaptor<float, FlatDataset>,
                                               FlatDataset, -1, uint32_t>;

/// k-nearest result set that ignores indices at or beyond a limit (e.g. the most recent
/// keyframes, which are excluded from loop search).
class LimitedKnnResult {
 public:
  using DistanceType = float;
  using IndexType = uint32_t;
  LimitedKnnResult(size_t k, size_t limit) : k_(k), limit_(limit) {}
  bool addPoint(float dist, uint32_t index) {
    if (index >= limit_) return true;
    if (items_.size() == k_ && dist >= items_.back().second) return true;
    auto it =
        std::upper_bound(items_.begin(), items_.end(), dist,
                         [](float d, const std::pair<size_t, float>& e) { return d < e.second; });
    items_.insert(it, {index, dist});
    if (items_.size() > k_) items_.pop_back();
    return true;
  }
  float worstDist() const {
    return items_.size() < k_ ? std::numeric_limits<float>::max() : items_.back().second;
  }
  bool full() const { return items_.size() == k_; }
  size_t size() const { return items_.size(); }
  std::vector<std::pair<size_t, float>> items_;

 private:
  size_t k_;
  size_t limit_;
};

class LimitedRadiusResult {
 public:
  using DistanceType = float;
  using IndexType = uint32_t;
  LimitedRadiusResult(float radius_sq, size_t limit) : radius_sq_(radius_sq), limit_(limit) {}
  bool addPoint(float dist, uint32_t index) {
    if (index < limit_ && dist < radius_sq_) items_.push_back({index, dist});
    return true;
  }
  float worstDist() const { return radius_sq_; }
  bool full() const { return true; }
  size_t size() const { return items_.size(); }
  std::vector<std::pair<size_t, float>> items_;

 private:
  float radius_sq_;
  size_t limit_;
};

}  // namespace

struct DynamicKdIndex::Impl {
  explicit Impl(int dim) {
    dataset.dim = dim;
    tree = std::make_unique<Tree>(dim, dataset, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  }
  FlatDataset dataset;
  std::unique_ptr<Tree> tree;
};

DynamicKdIndex::DynamicKdIndex(int dimension)
    : dimension_(std::max(1, dimension)), impl_(std::make_unique<Impl>(dimension_)) {}

DynamicKdIndex::~DynamicKdIndex() = default;

size_t DynamicKdIndex::size() const {
  return impl_->dataset.kdtree_get_point_count();
}

bool DynamicKdIndex::add(const float* values) {
  if (values == nullptr) return false;
  const size_t index = size();
  impl_->dataset.data.insert(impl_->dataset.data.end(), values, values + dimension_);
  impl_->tree->addPoints(static_cast<uint32_t>(index), static_cast<uint32_t>(index));
  return true;
}

std::vector<std::pair<size_t, float>> DynamicKdIndex::knn(const float* query, size_t k,
                                                          size_t index_limit) const {
  if (k == 0 || size() == 0 || query == nullptr) return {};
  LimitedKnnResult result(k, index_limit);
  impl_->tree->findNeighbors(result, query, nanoflann::SearchParams());
  return result.items_;
}

std::vector<std::pair<size_t, float>> DynamicKdIndex::radius(const float* query, float radius,
                                                             size_t index_limit) const {
  if (size() == 0 || query == nullptr || !(radius > 0.f)) return {};
  LimitedRadiusResult result(radius * radius, index_limit);
  impl_->tree->findNeighbors(result, query, nanoflann::SearchParams());
  std::sort(result.items_.begin(), result.items_.end(),
            [](const auto& a, const auto& b) { return a.second < b.second; });
  return result.items_;
}

}  // namespace osm_graph_slam
