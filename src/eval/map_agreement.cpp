#include "osm_graph_slam/eval/map_agreement.h"

#include <pcl/kdtree/kdtree_flann.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <map>

#include "osm_graph_slam/cloud/voxel_filter.h"
#include "osm_graph_slam/lines/line_geometry.h"
#include "osm_graph_slam/osm/building_set.h"

namespace osm_graph_slam {
namespace {

PointCloudPtr accumulate(const std::vector<PosedCloud>& keyframes, double voxel, double min_z,
                         double max_z) {
  PointCloudPtr all = std::make_shared<PointCloud>();
  for (const auto& [pose, cloud] : keyframes) {
    if (!cloud) continue;
    const Eigen::Isometry3f T = pose.cast<float>();
    for (const auto& p : cloud->points) {
      if (!std::isfinite(p.z) || p.z < min_z || p.z > max_z) continue;
      PointT q = p;
      q.getVector3fMap() = T * p.getVector3fMap();
      all->push_back(q);
    }
  }
  if (voxel <= 0.0 || all->empty()) return all;
  return voxelDownsample(all, voxel, true);
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(q * (v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

double maxVertexShift(const Building& a, const Building& b) {
  double shift = 0.0;
  for (size_t i = 0; i < a.outline_enu.size() && i < b.outline_enu.size(); ++i)
    shift = std::max(shift, (a.outline_enu[i] - b.outline_enu[i]).norm());
  return shift;
}

/// The building moved by the planar transform (x, y, yaw).
Building transformed(const Building& b, const Eigen::Vector3d& xyyaw) {
  Building out = b;
  const Eigen::Rotation2Dd r(xyyaw.z());
  for (auto& v : out.outline_enu) v = r * v + xyyaw.head<2>();
  return out;
}

}  // namespace

WallAgreement evaluateWallAgreement(const std::vector<PosedCloud>& keyframes,
                                    const std::vector<Building>& prior,
                                    const std::vector<Building>& corrected,
                                    const WallAgreementOptions& o) {
  std::map<std::pair<int64_t, int>, const Building*> corrected_by_id;
  for (const auto& b : corrected) corrected_by_id[{b.id, b.part}] = &b;
  std::vector<std::pair<const Building*, const Building*>> pairs, roofs;  // prior, corrected
  for (const auto& b : prior) {
    const auto it = corrected_by_id.find({b.id, b.part});
    if (it == corrected_by_id.end() || b.outline_enu.size() < 3) continue;
    (isRoofOnly(b) ? roofs : pairs).push_back({&b, it->second});
  }
  WallAgreement out;
  for (const auto& [p, c] : roofs)
    out.roof_only.push_back({p->id, p->part, 0, 0, maxVertexShift(*p, *c)});
  // Each wall point belongs to the building whose outline (prior or corrected) is nearest.
  std::vector<std::vector<double>> d_prior(pairs.size()), d_corrected(pairs.size());
  const PointCloudPtr walls = accumulate(keyframes, o.voxel, o.min_z, o.max_z);
  for (const auto& p : walls->points) {
    const Eigen::Vector2d x(p.x, p.y);
    for (size_t i = 0; i < roofs.size(); ++i) {
      out.roof_only[i].inside_prior += pointInPolygon(x, roofs[i].first->outline_enu);
      out.roof_only[i].inside_corrected += pointInPolygon(x, roofs[i].second->outline_enu);
    }
    size_t best = pairs.size();
    double best_d = o.max_distance, bp = 0, bc = 0;
    for (size_t i = 0; i < pairs.size(); ++i) {
      const double dp = distanceToPolygon(x, pairs[i].first->outline_enu);
      const double dc = distanceToPolygon(x, pairs[i].second->outline_enu);
      if (std::min(dp, dc) < best_d) best = i, best_d = std::min(dp, dc), bp = dp, bc = dc;
    }
    if (best == pairs.size()) continue;
    d_prior[best].push_back(bp);
    d_corrected[best].push_back(bc);
  }
  std::vector<double> pm, cm, p9, c9;
  for (size_t i = 0; i < pairs.size(); ++i) {
    const double shift = maxVertexShift(*pairs[i].first, *pairs[i].second);
    if (d_prior[i].size() < o.min_points) {
      ++out.unobserved;
      if (shift > out.max_unobserved_shift)
        out.max_unobserved_shift = shift, out.max_unobserved_shift_id = pairs[i].first->id;
      if (o.datum)
        out.max_unobserved_shift_after_datum =
            std::max(out.max_unobserved_shift_after_datum,
                     maxVertexShift(transformed(*pairs[i].first, *o.datum), *pairs[i].second));
      continue;
    }
    BuildingAgreement a;
    a.id = pairs[i].first->id;
    a.part = pairs[i].first->part;
    a.points = d_prior[i].size();
    a.prior_median = percentile(d_prior[i], 0.5);
    a.prior_p90 = percentile(d_prior[i], 0.9);
    a.corrected_median = percentile(d_corrected[i], 0.5);
    a.corrected_p90 = percentile(d_corrected[i], 0.9);
    a.shift = shift;
    out.points += a.points;
    pm.push_back(a.prior_median);
    cm.push_back(a.corrected_median);
    p9.push_back(a.prior_p90);
    c9.push_back(a.corrected_p90);
    out.observed.push_back(a);
  }
  out.prior_median = percentile(pm, 0.5);
  out.corrected_median = percentile(cm, 0.5);
  out.prior_p90 = percentile(p9, 0.5);
  out.corrected_p90 = percentile(c9, 0.5);
  return out;
}

MapSharpness evaluateMapSharpness(const std::vector<PosedCloud>& keyframes, double voxel,
                                  double radius, size_t min_neighbours) {
  MapSharpness out;
  const PointCloudPtr map = accumulate(keyframes, voxel, -1e9, 1e9);
  if (map->size() < min_neighbours) return out;
  pcl::KdTreeFLANN<PointT> tree;
  tree.setInputCloud(map);
  std::vector<int> idx;
  std::vector<float> d2;
  double sum = 0.0;
  for (const auto& p : map->points) {
    if (tree.radiusSearch(p, radius, idx, d2) < static_cast<int>(min_neighbours)) continue;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (int i : idx) mean += map->points[i].getVector3fMap().cast<double>();
    mean /= idx.size();
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (int i : idx) {
      const Eigen::Vector3d d = map->points[i].getVector3fMap().cast<double>() - mean;
      cov += d * d.transpose();
    }
    cov /= idx.size();
    sum += Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov, Eigen::EigenvaluesOnly)
               .eigenvalues()(0);
    ++out.points;
  }
  out.mean_plane_variance = out.points ? sum / out.points : 0.0;
  return out;
}

}  // namespace osm_graph_slam
