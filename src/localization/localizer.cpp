#include "osm_graph_slam/localization/localizer.h"

#include <pcl/common/transforms.h>
#include <pcl/kdtree/kdtree_flann.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <tuple>
#include <unordered_map>
#include <vector>

#include "osm_graph_slam/cloud/map_cloud.h"
#include "osm_graph_slam/cloud/voxel_filter.h"
#include "osm_graph_slam/common/attitude.h"
#include "osm_graph_slam/common/cell_key.h"
#include "osm_graph_slam/localization/osm_wall_matcher.h"

namespace osm_graph_slam {
namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

double rotationAngle(const Eigen::Matrix3d& r) {
  return Eigen::AngleAxisd(r).angle();
}

/// Map points bucketed in square 2D cells, for fast crops around a position.
class MapGrid {
 public:
  MapGrid(const PointCloudConstPtr& cloud, double cell) : cloud_(cloud), cell_(cell) {
    for (size_t i = 0; i < cloud->size(); ++i) {
      const auto& p = (*cloud)[i];
      cells_[key(cellOf(p.x), cellOf(p.y))].push_back(static_cast<int>(i));
    }
  }
  PointCloudPtr crop(const Eigen::Vector2d& centre, double radius) const {
    auto out = std::make_shared<PointCloud>();
    const int64_t x0 = cellOf(centre.x() - radius), x1 = cellOf(centre.x() + radius);
    const int64_t y0 = cellOf(centre.y() - radius), y1 = cellOf(centre.y() + radius);
    const double r2 = radius * radius;
    for (int64_t x = x0; x <= x1; ++x)
      for (int64_t y = y0; y <= y1; ++y) {
        const auto it = cells_.find(key(x, y));
        if (it == cells_.end()) continue;
        for (int i : it->second) {
          const auto& p = (*cloud_)[i];
          const double dx = p.x - centre.x(), dy = p.y - centre.y();
          if (dx * dx + dy * dy <= r2) out->push_back(p);
        }
      }
    out->width = static_cast<uint32_t>(out->size());
    out->height = 1;
    out->is_dense = true;
    return out;
  }

 private:
  int64_t cellOf(double v) const { return static_cast<int64_t>(std::floor(v / cell_)); }
  static int64_t key(int64_t x, int64_t y) { return packCellKey(x, y); }
  PointCloudConstPtr cloud_;
  double cell_;
  std::unordered_map<int64_t, std::vector<int>> cells_;
};

PointCloudPtr voxelize(const PointCloudConstPtr& cloud, double leaf) {
  // The back-end's hash-grid voxel filter (no 32-bit index overflow on city-sized maps).
  return mergeClouds({{Eigen::Isometry3d::Identity(), cloud}}, leaf);
}

}  // namespace

const char* toString(LocalizationStatus status) {
  switch (status) {
    case LocalizationStatus::kUninitialized:
      return "uninitialized";
    case LocalizationStatus::kTracking:
      return "tracking";
    case LocalizationStatus::kPredicted:
      return "predicted";
    case LocalizationStatus::kOffMap:
      return "off_map";
    case LocalizationStatus::kRelocalized:
      return "relocalized";
  }
  return "unknown";
}

struct Localizer::Impl {
  PointCloudPtr map;         ///< at map_voxel_size
  PointCloudPtr coarse_map;  ///< at global_voxel_size
  std::unique_ptr<MapGrid> grid, coarse_grid;
  std::unique_ptr<Registration> tracker;   ///< scan-to-local-map
  std::unique_ptr<Registration> odometry;  ///< scan-to-previous-scan, off the map
  PointCloudConstPtr previous_scan;        ///< the last matchable scan (odometry target)
  std::optional<GnssFix> gnss;             ///< the latest setGnssFix
  double gnss_checked_stamp = -1.0;
  int gnss_disagreements = 0;  ///< fixes in a row that contradicted the tracked pose
  std::unique_ptr<Registration> coarse, fine;  ///< global localisation
  PointCloudPtr local_map;
  Eigen::Vector2d local_centre = Eigen::Vector2d::Constant(std::numeric_limits<double>::max());
  std::vector<Eigen::Vector2d> keyframe_xy;
  Eigen::MatrixXf ring_keys;  ///< one column per keyframe, then one per side view
  /// Scan Context of a keyframe's cloud seen from a point beside it (global_side_view_offset).
  struct SideView {
    int keyframe = 0;
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  ///< the viewpoint (map)
    ScanContext descriptor;
  };
  std::vector<SideView> side_views;
  std::unique_ptr<LandmarkLoopSource> landmarks;  ///< geometric_hierarchy / combined, per keyframe
  std::unique_ptr<LandmarkMapRecognizer> landmark_map;  ///< ... against the map's landmarks
  std::unique_ptr<OsmWallMatcher> walls;                ///< enableOsmWalls
  std::vector<Eigen::Vector2d> osm_path_centres;        ///< wall search centres without a fix
  double scan_stamp = 0.0;                              ///< of the scan being processed (GNSS age)
  /// Scan time of the last walls search, and how many in a row found nothing (back-off).
  double walls_search_stamp = -std::numeric_limits<double>::infinity();
  int walls_failures = 0;
};

/// A map keyframe to register the scan against, with the initial guess of the scan's pose.
struct Localizer::Place {
  int index = 0;  ///< map keyframe
  Eigen::Isometry3d guess = Eigen::Isometry3d::Identity();
  double descriptor_distance = -1.0;  ///< Scan Context's (-1: a hierarchy or walls place)
  double wall_fitness = 0.0;          ///< the line matcher's (osm_walls)
  const char* source = "scan_context";
};

Localizer::Localizer(const LocalizationParams& params, std::shared_ptr<const MapPackage> map)
    : params_(params), map_(std::move(map)), impl_(std::make_unique<Impl>()), ukf_(params.ukf) {
  impl_->map = voxelize(map_->map_cloud, params_.map_voxel_size);
  impl_->coarse_map = voxelize(impl_->map, params_.global_voxel_size);
  impl_->grid = std::make_unique<MapGrid>(impl_->map, 10.0);
  impl_->coarse_grid = std::make_unique<MapGrid>(impl_->coarse_map, 10.0);
  impl_->tracker = createRegistration(params_.registration);
  impl_->odometry = createRegistration(params_.registration);
  RegistrationParams coarse = params_.registration;
  coarse.max_correspondence_distance = params_.global_coarse_max_correspondence;
  impl_->coarse = createRegistration(coarse);
  impl_->fine = createRegistration(params_.registration);
  if (params_.global_method != "scan_context" && params_.global_method != "geometric_hierarchy" &&
      params_.global_method != "combined")
    throw std::invalid_argument("localization: unknown global_method '" + params_.global_method +
                                "' (scan_context | geometric_hierarchy | combined)");
  if (params_.landmark_map != "keyframes" && params_.landmark_map != "global")
    throw std::invalid_argument("localization: unknown landmark_map '" + params_.landmark_map +
                                "' (keyframes | global)");
  if (params_.global_method != "scan_context") buildLandmarkIndex();
  learnDescriptorLimit();
  const size_t n = map_->keyframes.size();
  addSideViews();
  const size_t views = impl_->side_views.size();
  impl_->ring_keys.resize(n > 0 ? map_->keyframes.front().descriptor.ring_key.size() : 0,
                          n + views);
  auto set_key = [&](size_t col, const ScanContext& d) {
    if (d.ring_key.size() == impl_->ring_keys.rows())
      impl_->ring_keys.col(col) = d.ring_key;
    else
      impl_->ring_keys.col(col).setConstant(1e3f);
  };
  for (size_t i = 0; i < n; ++i) {
    const MapKeyframe& kf = map_->keyframes[i];
    impl_->keyframe_xy.push_back(kf.pose.translation().head<2>());
    set_key(i, kf.descriptor);
  }
  for (size_t v = 0; v < views; ++v) set_key(n + v, impl_->side_views[v].descriptor);
  learnOverlapLimit();  // needs the ring keys
}

Localizer::~Localizer() = default;

namespace {
/// The q-quantile (0..1) of the values (nearest rank; moves them).
double quantile(std::vector<double>& values, double q) {
  const size_t k =
      std::min(values.size() - 1, static_cast<size_t>(std::max(0.0, q) * double(values.size())));
  std::nth_element(values.begin(), values.begin() + k, values.end());
  return values[k];
}
}  // namespace

void Localizer::addSideViews() {
  // Scan Context changes quickly with a sideways offset (a place entered from another lane, a
  // corner cut differently): each keyframe's cloud is also described as seen from points beside
  // it, so that a scan taken there still finds the keyframe. The registration checks as usual.
  const double d = params_.global_side_view_offset;
  if (d <= 0.0) return;
  for (size_t i = 0; i < map_->keyframes.size(); ++i) {
    const MapKeyframe& kf = map_->keyframes[i];
    const PointCloudConstPtr cloud = kf.cloud.load();
    if (!cloud || cloud->empty()) continue;
    for (const double side : {-d, d}) {
      Impl::SideView& v = impl_->side_views.emplace_back();
      v.keyframe = static_cast<int>(i);
      v.pose = kf.pose * Eigen::Translation3d(0.0, side, 0.0);
      PointCloud shifted(*cloud);
      for (auto& p : shifted.points) p.y -= static_cast<float>(side);
      v.descriptor = computeScanContext(shifted, map_->scan_context);
    }
  }
}

void Localizer::learnDescriptorLimit() {
  // Distances between descriptors of different places of this map: what a wrong candidate
  // looks like with this sensor in this city. Deterministic sampling (a fixed seed).
  const size_t n = map_->keyframes.size();
  std::vector<double> impostor;
  std::mt19937 rng(1);
  const size_t wanted = static_cast<size_t>(std::max(0, params_.global_impostor_pairs));
  for (size_t trial = 0; n > 1 && trial < 20 * wanted && impostor.size() < wanted; ++trial) {
    const MapKeyframe& a = map_->keyframes[rng() % n];
    const MapKeyframe& b = map_->keyframes[rng() % n];
    if ((a.pose.translation() - b.pose.translation()).head<2>().norm() <
        params_.global_impostor_distance)
      continue;
    impostor.push_back(matchScanContexts(a.descriptor, b.descriptor, map_->scan_context).distance);
  }
  descriptor_limit_ = params_.global_max_descriptor_distance;
  stats_.global_impostor_pairs = impostor.size();
  // Too few pairs (a map of one small place): the fixed limit alone.
  if (impostor.size() >= 100 && params_.global_false_match_rate > 0.0) {
    descriptor_limit_ =
        std::min(descriptor_limit_, quantile(impostor, params_.global_false_match_rate));
  }
  stats_.global_descriptor_limit = descriptor_limit_;
}

OverlapLimit learnOverlapLimitFrom(std::vector<double> own, std::vector<double> impostor,
                                   double min_overlap, double rate) {
  OverlapLimit out;
  out.limit = min_overlap;
  if (!own.empty()) out.own_low = quantile(own, rate);
  if (!impostor.empty()) out.impostor_high = quantile(impostor, 1.0 - rate);
  // The impostors' overlap is the limit where it lies below what the own places reach. Where
  // impostors overlap as much as the own places (repeated buildings), the overlap cannot tell
  // places apart: the fixed limit, and the ambiguity test and the confirmation decide. Too few
  // own places to say what a right answer looks like: the fixed limit too.
  out.separable = own.size() >= 10 && !impostor.empty() && out.impostor_high < out.own_low;
  if (out.separable) out.limit = std::max(min_overlap, out.impostor_high);
  return out;
}

void Localizer::learnOverlapLimit() {
  // What the overlap of a registered scan looks like at its own place and at the other places
  // that Scan Context would propose for it, in this map with this sensor.
  const auto t0 = Clock::now();
  overlap_limit_ = params_.global_min_overlap;
  const size_t n = map_->keyframes.size();
  const size_t samples =
      std::min(n, static_cast<size_t>(std::max(0, params_.global_overlap_samples)));
  std::vector<double> own, impostor;
  for (size_t s = 0; s < samples; ++s) {
    const size_t index = (2 * s + 1) * n / (2 * samples);  // evenly spread over the drive
    const MapKeyframe& kf = map_->keyframes[index];
    const PointCloudConstPtr cloud = kf.cloud.load();
    if (!cloud || cloud->size() < static_cast<size_t>(params_.min_points)) continue;
    const Eigen::Vector2d centre = impl_->keyframe_xy[index];
    const double own_overlap = ownPlaceOverlap(index);
    if (own_overlap >= 0.0) own.push_back(own_overlap);
    // The other places Scan Context proposes for it.
    const PointCloudPtr coarse_source = voxelize(cloud, params_.global_voxel_size);
    const std::vector<Place> places = distinctPlaces(
        scanContextPlaces(kf.descriptor, &centre, params_.global_impostor_distance, false),
        params_.global_overlap_impostor_places);
    for (const Place& place : places) {
      GlobalCandidate record;
      if (registerAtPlace(cloud, coarse_source, place, record)) impostor.push_back(record.overlap);
    }
  }
  stats_.global_overlap_own = own.size();
  stats_.global_overlap_impostors = impostor.size();
  const OverlapLimit limit = learnOverlapLimitFrom(own, impostor, params_.global_min_overlap,
                                                   params_.global_false_match_rate);
  overlap_limit_ = limit.limit;
  stats_.global_overlap_own_low = limit.own_low;
  stats_.global_overlap_impostor_high = limit.impostor_high;
  stats_.global_overlap_limit = overlap_limit_;
  stats_.global_overlap_learn_ms = msSince(t0);
}

PlaceFit measurePlaceFit(const PointCloud& cloud, const Eigen::Isometry3d& pose,
                         const PointCloudConstPtr& map_region, const Eigen::Vector2d& centre,
                         double radius, double inlier_distance, double structure_z) {
  PlaceFit out;
  const double max_d2 = inlier_distance * inlier_distance;
  out.structure_cost = max_d2;
  if (!map_region || map_region->empty()) return out;
  pcl::KdTreeFLANN<PointT> tree;
  tree.setInputCloud(map_region);
  PointCloud aligned;
  pcl::transformPointCloud(cloud, aligned, pose.matrix().cast<float>());
  std::vector<int> idx(1);
  std::vector<float> d2(1);
  const double inside2 = std::pow(std::max(0.0, radius - 1.0), 2);
  size_t considered = 0, inliers = 0, structure = 0, structure_inliers = 0;
  double cost = 0.0, structure_cost = 0.0;
  for (size_t i = 0; i < aligned.size(); ++i) {
    const auto& p = aligned[i];
    if (std::pow(p.x - centre.x(), 2) + std::pow(p.y - centre.y(), 2) > inside2) continue;
    ++considered;
    const bool found = tree.nearestKSearch(p, 1, idx, d2) > 0;
    const bool inlier = found && d2[0] <= max_d2;
    const double truncated = inlier ? double(d2[0]) : max_d2;
    inliers += inlier ? 1 : 0;
    cost += truncated;
    if (cloud[i].z > structure_z) {
      ++structure;
      structure_inliers += inlier ? 1 : 0;
      structure_cost += truncated;
    }
  }
  if (considered == 0) return out;
  out.overlap = double(inliers) / double(considered);
  out.structure_overlap = structure == 0 ? 0.0 : double(structure_inliers) / double(structure);
  // A scan of bare ground has nothing else to tell the place by: all its points then.
  out.structure_cost =
      structure == 0 ? cost / double(considered) : structure_cost / double(structure);
  return out;
}

double Localizer::ownPlaceOverlap(size_t index) const {
  // Its own place, seen without its own points (another pass sees the place from elsewhere),
  // mapped by keyframes thinned to kOwnSpacing (a map of every keyframe per sample costs
  // seconds on a city map). The map was built at the keyframe poses: no registration needed.
  constexpr double kOwnSpacing = 5.0;  // [m]
  const MapKeyframe& kf = map_->keyframes[index];
  const Eigen::Vector2d& centre = impl_->keyframe_xy[index];
  const double radius = globalSearchRadius();
  std::vector<PosedCloud> others;
  std::vector<Eigen::Vector2d> picked{centre};
  for (size_t j = 0; j < map_->keyframes.size(); ++j) {
    const Eigen::Vector2d& xy = impl_->keyframe_xy[j];
    if (j == index || !map_->keyframes[j].cloud || (xy - centre).norm() > radius) continue;
    bool near = false;
    for (const auto& q : picked) near = near || (xy - q).norm() < kOwnSpacing;
    if (near) continue;
    picked.push_back(xy);
    others.push_back({map_->keyframes[j].pose, map_->keyframes[j].cloud});
  }
  const PointCloudPtr target =
      MapGrid(mergeClouds(others, params_.map_voxel_size), 10.0).crop(centre, radius);
  if (target->size() < static_cast<size_t>(params_.min_points)) return -1.0;
  const PointCloudConstPtr cloud = kf.cloud.load();
  return cloud ? overlapAt(*cloud, kf.pose, target, centre, radius).overlap : -1.0;
}

double Localizer::distanceToMap(const Eigen::Vector3d& position) const {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& xy : impl_->keyframe_xy)
    best = std::min(best, (xy - position.head<2>()).squaredNorm());
  return std::sqrt(best);
}

void Localizer::reset() {
  ukf_ = PoseUkf(params_.ukf);
  impl_->previous_scan.reset();
  recent_rejections_.clear();
  searching_ = true;
  confirming_ = false;
  recent_fitness_.clear();
  recent_next_ = 0;
  impl_->gnss_disagreements = 0;
}

void Localizer::setGnssFix(double stamp, const Eigen::Vector2d& xy, double std) {
  if (!xy.allFinite()) return;
  impl_->gnss = GnssFix{stamp, xy, std::isfinite(std) ? std::max(0.0, std) : 0.0};
}

const Eigen::Vector2d* Localizer::recentGnssFix(double stamp, double* limit) const {
  const auto& fix = impl_->gnss;
  const bool georeferenced = map_->has_origin;
  if (!fix || !georeferenced || params_.gnss_check_distance <= 0.0 ||
      std::abs(stamp - fix->stamp) > params_.gnss_max_age)
    return nullptr;
  *limit = std::max(params_.gnss_check_distance, 5.0 * fix->std);
  return &fix->xy;
}

bool Localizer::gnssContradictsTracking(const Eigen::Isometry3d& pose, double stamp) {
  double limit = 0.0;
  const Eigen::Vector2d* fix = recentGnssFix(stamp, &limit);
  if (!fix || impl_->gnss->stamp == impl_->gnss_checked_stamp) return false;
  impl_->gnss_checked_stamp = impl_->gnss->stamp;
  const bool far = (pose.translation().head<2>() - *fix).norm() > limit;
  impl_->gnss_disagreements = far ? impl_->gnss_disagreements + 1 : 0;
  return impl_->gnss_disagreements >= std::max(1, params_.gnss_check_fixes);
}

void Localizer::setInitialPose(const Eigen::Isometry3d& pose, double stamp) {
  impl_->gnss_disagreements = 0;
  ukf_.initialize(pose, params_.init_position_std, params_.init_orientation_std,
                  params_.init_velocity_std, params_.init_rate_std);
  last_stamp_ = stamp;
  impl_->previous_scan.reset();
  recent_rejections_.clear();
  searching_ = false;
  confirming_ = false;
  recent_fitness_.clear();
  recent_next_ = 0;
}

GlobalLocalizationResult Localizer::globalLocalize(const PointCloudConstPtr& cloud) {
  last_global_ = searchGlobally(cloud, /*walls_due=*/true);
  return last_global_;
}

GlobalLocalizationResult Localizer::globalLocalizeAt(const PointCloudConstPtr& cloud,
                                                     double stamp) {
  // Walls searches that find nothing back off: lost off the map each costs 0.5-1 s in vain. The
  // wait after the n-th failure in a row is global_osm_interval / 2^(4-n), at most the interval
  // (a time jump back: due at once).
  const double since = stamp - impl_->walls_search_stamp;
  const double wait =
      params_.global_osm_interval / std::pow(2.0, std::max(0, 4 - impl_->walls_failures));
  const bool due = !(since >= 0.0 && since < wait);
  const size_t searches = stats_.global_osm_searches;
  last_global_ = searchGlobally(cloud, due);
  if (stats_.global_osm_searches > searches) {
    impl_->walls_failures = last_global_.success ? 0 : impl_->walls_failures + 1;
    impl_->walls_search_stamp = stamp;
  }
  return last_global_;
}

GlobalLocalizationResult Localizer::searchGlobally(const PointCloudConstPtr& cloud,
                                                   bool walls_due) {
  GlobalLocalizationResult result;
  const auto t0 = Clock::now();
  ++stats_.global_attempts;
  if (!cloud || cloud->size() < static_cast<size_t>(params_.min_points) ||
      map_->keyframes.empty()) {
    result.message = "too few points or an empty map";
    stats_.global_ms += msSince(t0);
    ++stats_.global_failures;
    return result;
  }
  // The keyframes first; their side views only when no keyframe's place passes (a scan off the
  // map drive's path): searching every view at once tripled the registrations of a search and
  // made re-localisation at real time slower than the drive (localization.test at rate 1).
  bool ambiguous = verifyPlaces(cloud, candidatePlaces(cloud), result);
  if (!result.success && !ambiguous && !impl_->side_views.empty() &&
      params_.global_method != "geometric_hierarchy") {
    const std::vector<Place> side = distinctPlaces(
        scanContextPlaces(computeScanContext(*cloud, map_->scan_context), nullptr, 0.0, true),
        params_.global_candidates);
    ambiguous = verifyPlaces(cloud, side, result);
    stats_.global_by_side_view += result.success ? 1 : 0;
  }
  if (!result.success && !ambiguous && impl_->walls && walls_due) {
    ambiguous = verifyPlaces(cloud, osmWallPlaces(cloud), result);
    stats_.global_by_osm_walls += result.success ? 1 : 0;
  }
  if (!result.success) {
    ++stats_.global_failures;
    stats_.global_ambiguous += ambiguous ? 1 : 0;
    if (result.candidates_tried == 0)
      result.message = params_.global_method == "geometric_hierarchy"
                           ? "no map keyframe with a matching landmark layout"
                           : "no keyframe with a similar Scan Context or landmark layout";
    else if (!ambiguous)
      result.message = "no candidate passed registration (" +
                       std::to_string(result.candidates_tried) + " tried)";
  } else if (result.source == "geometric_hierarchy") {
    ++stats_.global_by_hierarchy;
  }
  stats_.global_ms += msSince(t0);
  return result;
}

bool Localizer::verifyPlaces(const PointCloudConstPtr& cloud, const std::vector<Place>& places,
                             GlobalLocalizationResult& result) {
  if (places.empty()) return false;
  const PointCloudPtr coarse_source = voxelize(cloud, params_.global_voxel_size);
  struct Passed {
    Eigen::Isometry3d pose;
    double score;
  };
  std::vector<Passed> passed;
  std::vector<size_t> fitting_walls;  ///< osm_walls places that passed the fitness test
  size_t best = 0;
  double best_score = std::numeric_limits<double>::infinity();
  for (const Place& c : places) {
    ++result.candidates_tried;
    GlobalCandidate& record = result.candidates.emplace_back();
    const bool fits = registerAtPlace(cloud, coarse_source, c, record);
    if (fits && record.source == "osm_walls") fitting_walls.push_back(result.candidates.size() - 1);
    if (!fits || record.overlap < overlap_limit_) continue;
    // A walls place was proposed by 2D lines only: its structure (above the ground) must be
    // explained in 3D too, the ground alone fits a slab of street turned by 90 degrees.
    if (record.source == "osm_walls" &&
        record.structure_overlap < params_.global_osm_min_structure_overlap) {
      record.outcome = "structure";
      continue;
    }
    record.outcome = "passed";
    // The ground fits anywhere: places are told apart by how much of the structure they explain.
    const double score = record.structure_cost;
    passed.push_back({record.pose, score});
    if (score < best_score) {
      best = result.candidates.size() - 1;
      best_score = score;
      result.success = true;
      result.pose = record.pose;
      result.keyframe_id = record.keyframe_id;
      result.source = c.source;
      result.descriptor_distance = c.descriptor_distance;
      result.fitness = record.fitness;
      result.overlap = record.overlap;
    }
  }
  // Perceptual aliasing (a street of identical facades): another place that fits almost as well
  // makes the answer ambiguous; no answer is better than a wrong one.
  for (const Passed& p : passed) {
    if (!result.success) break;
    const double apart = (p.pose.translation() - result.pose.translation()).norm();
    if (apart > 2.0 && p.score < params_.global_ambiguity_ratio * best_score) {
      result.success = false;
      result.message = "ambiguous: two places " + std::to_string(apart) + " m apart fit alike";
      return true;
    }
  }
  return result.success && wallsAmbiguous(result, best, fitting_walls);
}

bool Localizer::wallsAmbiguous(GlobalLocalizationResult& result, size_t best,
                               const std::vector<size_t>& fitting) const {
  // A walls place has no descriptor behind it: the walls and the registration must both single
  // it out. Another place the registration fits (its overlap may be low: a scan off the map
  // drive's path sees what the map never saw) whose walls score within the matcher's ambiguity
  // margin makes the answer ambiguous (repeated buildings along a street or a town).
  const GlobalCandidate& winner = result.candidates[best];
  if (winner.source != "osm_walls") return false;
  const double margin = impl_->walls->matcher().params().initial_ambiguity_margin;
  for (size_t i : fitting) {
    const GlobalCandidate& other = result.candidates[i];
    const double apart = (other.pose.translation() - winner.pose.translation()).head<2>().norm();
    if (i == best || apart <= 2.0 || std::abs(other.wall_fitness - winner.wall_fitness) > margin)
      continue;
    result.success = false;
    result.message = "ambiguous: the walls of two places " + std::to_string(apart) +
                     " m apart match alike and both register";
    return true;
  }
  return false;
}

bool Localizer::registerAtPlace(const PointCloudConstPtr& cloud,
                                const PointCloudConstPtr& coarse_source, const Place& place,
                                GlobalCandidate& record) const {
  const MapKeyframe& kf = map_->keyframes[place.index];
  const Eigen::Vector2d centre = kf.pose.translation().head<2>();
  const double radius = globalSearchRadius();
  record.keyframe_id = kf.id;
  record.source = place.source;
  record.descriptor_distance = place.descriptor_distance;
  record.wall_fitness = place.wall_fitness;
  record.outcome = "coarse_failed";
  impl_->coarse->setTarget(impl_->coarse_grid->crop(centre, radius));
  // The coarse step only brings the fine one closer: one that ran out of iterations (a guess
  // metres off) still hands over its guess, and the fine fit, fitness and overlap decide.
  const RegistrationResult coarse = impl_->coarse->align(coarse_source, place.guess);
  if (!coarse.converged) return false;
  const PointCloudPtr target = impl_->grid->crop(centre, radius);
  impl_->fine->setTarget(target);
  const RegistrationResult fine = impl_->fine->align(cloud, coarse.transform);
  record.pose = fine.transform;
  record.fitness = fine.fitness;
  record.outcome = fine.converged ? "fitness" : "fine_failed";
  if (!fine.converged || fine.fitness > params_.global_max_fitness) return false;
  const PlaceFit fit = overlapAt(*cloud, fine.transform, target, centre, radius);
  record.overlap = fit.overlap;
  record.structure_overlap = fit.structure_overlap;
  record.structure_cost = fit.structure_cost;
  record.outcome = "overlap";
  return true;
}

PlaceFit Localizer::overlapAt(const PointCloud& cloud, const Eigen::Isometry3d& pose,
                              const PointCloudConstPtr& target, const Eigen::Vector2d& centre,
                              double radius) const {
  return measurePlaceFit(
      cloud, pose, target, centre, radius, params_.global_overlap_distance,
      params_.global_structure_height - map_->scan_context.sensor_height);  // base_link z
}

void Localizer::buildLandmarkIndex() {
  if (params_.landmark_map == "keyframes") {
    impl_->landmarks =
        std::make_unique<LandmarkLoopSource>(params_.landmark_extraction, params_.landmarks);
    for (const MapKeyframe& kf : map_->keyframes) {
      const PointCloudConstPtr cloud = kf.cloud.load();
      impl_->landmarks->add(cloud ? cloud : std::make_shared<PointCloud>());
    }
    return;
  }
  std::vector<KeyframeLandmarks> observed;
  std::vector<Eigen::Vector2d> path;
  for (const MapKeyframe& kf : map_->keyframes) {
    KeyframeLandmarks& k = observed.emplace_back();
    k.pose = planarPose(kf.pose);
    if (const PointCloudConstPtr cloud = kf.cloud.load())
      k.landmarks = landmarkCenters(extractLandmarks(*cloud, params_.landmark_extraction));
    path.push_back(kf.pose.translation().head<2>());
  }
  impl_->landmark_map = std::make_unique<LandmarkMapRecognizer>(
      discoverLandmarks(observed, params_.landmark_map_params), path, params_.landmark_map_params,
      params_.landmarks);
}

std::vector<Localizer::Place> Localizer::candidatePlaces(const PointCloudConstPtr& cloud) {
  std::vector<Place> places;
  if (impl_->landmark_map) {  // first, as below
    const auto match = impl_->landmark_map->query(
        landmarkCenters(extractLandmarks(*cloud, params_.landmark_extraction)));
    if (match) places.push_back(placeAt(match->pose, "geometric_hierarchy"));
  }
  if (impl_->landmarks) {  // first: its guess holds the translation too
    const auto proposal = impl_->landmarks->propose(cloud, impl_->landmarks->size());
    if (proposal) {
      Place& p = places.emplace_back();
      p.index = static_cast<int>(proposal->index);
      p.guess = map_->keyframes[proposal->index].pose * proposal->relative_pose;
      p.source = "geometric_hierarchy";
    }
  }
  if (params_.global_method != "geometric_hierarchy") addScanContextPlaces(cloud, places);
  // Close keyframes give the same answer: keep places 5 m apart, at most global_candidates.
  return distinctPlaces(places, params_.global_candidates);
}

size_t Localizer::enableOsmWalls(const WallPointExtractorParams& walls,
                                 const LineSegmentExtractorParams& segments,
                                 const LineMatcherParams& matcher) {
  if (!params_.global_osm_walls || map_->buildings.empty()) return 0;
  LineMatcherParams m = matcher;
  m.initial_max_translation = params_.global_osm_search_radius;
  m.min_fitness = params_.global_osm_min_fitness;
  m.min_matched_segments = params_.global_osm_min_matched;
  impl_->walls = std::make_unique<OsmWallMatcher>(map_->buildings, walls, segments, m);
  // Centres along the map drive's path, each keyframe within global_osm_spacing of one.
  impl_->osm_path_centres =
      spacedPathPoints(impl_->keyframe_xy, std::max(1.0, params_.global_osm_spacing));
  return map_->buildings.size();
}

Localizer::Place Localizer::placeAt(const Pose2& pose, const char* source) const {
  // The nearest keyframe gives the map region, the height and the slope.
  size_t nearest = 0;
  for (size_t i = 1; i < impl_->keyframe_xy.size(); ++i)
    if ((impl_->keyframe_xy[i] - pose.translation()).squaredNorm() <
        (impl_->keyframe_xy[nearest] - pose.translation()).squaredNorm())
      nearest = i;
  const Eigen::Isometry3d& kf = map_->keyframes[nearest].pose;
  const Eigen::Vector2d rp = rollPitchOf(Eigen::Matrix3d(kf.linear()));
  Place p;
  p.index = static_cast<int>(nearest);
  p.guess.linear() = rotationFromRollPitchYaw(rp.x(), rp.y(), pose.theta);
  p.guess.translation() << pose.x, pose.y, kf.translation().z();
  p.source = source;
  return p;
}

std::vector<Eigen::Vector2d> Localizer::osmSearchCentres(const Eigen::Vector2d* fix,
                                                         double fix_limit) const {
  if (!fix) return impl_->osm_path_centres;
  // The fix, and the path's centres from which a place within the fix's limit is searched: the
  // walls seen from where the map drive was match better than those seen from a fix metres off.
  std::vector<Eigen::Vector2d> centres{*fix};
  for (const Eigen::Vector2d& c : impl_->osm_path_centres)
    if ((c - *fix).norm() <= fix_limit + params_.global_osm_search_radius) centres.push_back(c);
  return centres;
}

std::vector<Localizer::Place> Localizer::osmWallPlaces(const PointCloudConstPtr& cloud) {
  const auto t0 = Clock::now();
  ++stats_.global_osm_searches;
  const OsmWallMatcher& walls = *impl_->walls;
  const std::vector<LineSegment2> scan_walls = walls.scanWalls(*cloud);
  struct Hypothesis {
    Pose2 pose;
    double fitness;
  };
  std::vector<Hypothesis> found;
  double fix_limit = 0.0;
  const Eigen::Vector2d* fix = recentGnssFix(impl_->scan_stamp, &fix_limit);
  if (static_cast<int>(scan_walls.size()) >= params_.global_osm_min_segments) {
    for (const Eigen::Vector2d& centre : osmSearchCentres(fix, fix_limit)) {
      const std::vector<LineSegment2> map_walls =
          walls.wallsSeenFrom(centre, params_.global_osm_wall_radius);
      if (map_walls.empty()) continue;
      const LineMatchResult m =
          walls.matcher().matchGlobal(scan_walls, map_walls, Pose2(centre.x(), centre.y(), 0.0),
                                      /*rotation_unbounded=*/true);
      if (m.success && (!fix || (m.transform.translation() - *fix).norm() <= fix_limit))
        found.push_back({m.transform, m.fitness});
    }
  }
  std::sort(found.begin(), found.end(),
            [](const Hypothesis& a, const Hypothesis& b) { return a.fitness > b.fitness; });
  // Neighbouring centres find the same walls: keep hypotheses 2 m apart, best first.
  std::vector<Place> places;
  for (const Hypothesis& h : found) {
    if (static_cast<int>(places.size()) >= params_.global_candidates) break;
    bool near = false;
    for (const Place& p : places)
      near = near || (p.guess.translation().head<2>() - h.pose.translation()).norm() < 2.0;
    if (near) continue;
    places.push_back(placeAt(h.pose, "osm_walls"));
    places.back().wall_fitness = h.fitness;
  }
  stats_.global_osm_ms += msSince(t0);
  return places;
}

std::vector<Localizer::Place> Localizer::distinctPlaces(const std::vector<Place>& places,
                                                        int max_places) const {
  std::vector<Place> distinct;
  for (const Place& c : places) {
    if (static_cast<int>(distinct.size()) >= max_places) break;
    bool near = false;
    for (const Place& d : distinct)
      near = near || (impl_->keyframe_xy[c.index] - impl_->keyframe_xy[d.index]).norm() < 5.0;
    if (!near) distinct.push_back(c);
  }
  return distinct;
}

void Localizer::addScanContextPlaces(const PointCloudConstPtr& cloud,
                                     std::vector<Place>& places) const {
  const std::vector<Place> found =
      scanContextPlaces(computeScanContext(*cloud, map_->scan_context), nullptr, 0.0, false);
  places.insert(places.end(), found.begin(), found.end());
}

std::vector<Localizer::Place> Localizer::scanContextPlaces(const ScanContext& query,
                                                           const Eigen::Vector2d* away_from,
                                                           double away_distance,
                                                           bool side_views) const {
  // 1. Ring-key retrieval (rotation invariant), 2. Scan Context distance and yaw.
  const int n = static_cast<int>(map_->keyframes.size());
  const int begin = side_views ? n : 0;
  const int end = side_views ? static_cast<int>(impl_->ring_keys.cols()) : n;
  std::vector<std::pair<float, int>> by_ring;
  by_ring.reserve(end - begin);
  auto keyframe_of = [&](int col) { return col < n ? col : impl_->side_views[col - n].keyframe; };
  if (query.ring_key.size() == impl_->ring_keys.rows())
    for (int c = begin; c < end; ++c)
      if (!away_from || (impl_->keyframe_xy[keyframe_of(c)] - *away_from).norm() >= away_distance)
        by_ring.emplace_back((impl_->ring_keys.col(c) - query.ring_key).squaredNorm(), c);
  // global_ring_key_candidates keyframes' worth of views.
  const int views_per_keyframe = n > 0 ? std::max(1, (end - begin + n - 1) / n) : 1;
  const int k =
      std::min<int>(params_.global_ring_key_candidates * views_per_keyframe, by_ring.size());
  std::partial_sort(by_ring.begin(), by_ring.begin() + k, by_ring.end());
  std::vector<Place> by_descriptor;
  for (int i = 0; i < k; ++i) {
    const int col = by_ring[i].second;
    const bool side = col >= n;
    const Eigen::Isometry3d& view_pose =
        side ? impl_->side_views[col - n].pose : map_->keyframes[col].pose;
    const ScanContext& descriptor =
        side ? impl_->side_views[col - n].descriptor : map_->keyframes[col].descriptor;
    const ScanContextMatch m = matchScanContexts(query, descriptor, map_->scan_context);
    if (m.distance > descriptor_limit_) continue;
    Place& p = by_descriptor.emplace_back();
    p.index = keyframe_of(col);
    p.guess = view_pose;
    p.guess.linear() =
        view_pose.linear() * Eigen::AngleAxisd(m.yaw, Eigen::Vector3d::UnitZ()).matrix();
    p.descriptor_distance = m.distance;
  }
  std::sort(by_descriptor.begin(), by_descriptor.end(), [](const Place& a, const Place& b) {
    return a.descriptor_distance < b.descriptor_distance;
  });
  return by_descriptor;
}

PointCloudConstPtr Localizer::deskewedScan(const PointCloudConstPtr& cloud,
                                           const Eigen::Isometry3d& motion, double dt) const {
  return params_.deskew ? deskewedCopy(*cloud, params_.sensor_to_base, motion, dt, params_.sweep)
                        : cloud;
}

PointCloudConstPtr Localizer::reducedScan(const PointCloudConstPtr& scan) const {
  return params_.scan_voxel_size > 0.0 ? voxelDownsample(scan, params_.scan_voxel_size) : scan;
}

bool Localizer::carryByScanOdometry(const PointCloudConstPtr& cloud,
                                    const Eigen::Isometry3d& before,
                                    const Eigen::Isometry3d& predicted_motion, double dt) {
  if (!cloud || cloud->size() < static_cast<size_t>(params_.min_points)) {
    impl_->previous_scan.reset();  // a gap: the next step has nothing to register against
    return false;
  }
  const PointCloudConstPtr source = reducedScan(deskewedScan(cloud, predicted_motion, dt));
  const PointCloudConstPtr target = impl_->previous_scan;
  impl_->previous_scan = source;
  if (!target) return false;
  impl_->odometry->setTarget(target);
  const RegistrationResult r = impl_->odometry->align(source, predicted_motion);
  const Eigen::Isometry3d delta = predicted_motion.inverse() * r.transform;
  // The same gates as a map correction: a step that jumps from the prediction is not trusted.
  if (!r.converged || r.fitness > params_.max_fitness ||
      delta.translation().norm() > params_.max_correction_trans ||
      rotationAngle(delta.linear()) > params_.max_correction_angle)
    return false;
  ukf_.correct(before * r.transform, params_.off_map_step_position_std,
               params_.off_map_step_orientation_std);
  ++stats_.off_map_odometry;
  return true;
}

LocalizationOutput Localizer::process(double stamp, const PointCloudConstPtr& cloud,
                                      const std::optional<Eigen::Vector3d>& gyro,
                                      const std::optional<Eigen::Vector3d>& accel) {
  LocalizationOutput out;
  ++stats_.scans;
  // Not started (no initial pose) or diverged: global localisation on this scan.
  impl_->scan_stamp = stamp;
  if (searching_) {
    GlobalLocalizationResult g = globalLocalizeAt(cloud, stamp);
    double gnss_limit = 0.0;
    const Eigen::Vector2d* fix = recentGnssFix(stamp, &gnss_limit);
    if (g.success && fix && (g.pose.translation().head<2>() - *fix).norm() > gnss_limit) {
      g.success = false;  // a look-alike place far from where the receiver says we are
      g.message = "refused: farther than " + std::to_string(gnss_limit) + " m from the GNSS fix";
      last_global_ = g;  // the attempt's log shows the refusal
      ++stats_.global_gnss_refusals;
    }
    if (!g.success) {
      ++stats_.uninitialized;
      out.status = LocalizationStatus::kUninitialized;
      if (ukf_.initialized()) {  // diverged: keep predicting, flagged as not localised
        const Eigen::Isometry3d before = ukf_.pose();
        ukf_.predict(stamp - last_stamp_, gyro, accel);
        out.motion = before.inverse() * ukf_.pose();
        last_stamp_ = stamp;
        out.pose = ukf_.pose();
        out.covariance = ukf_.poseCovariance();
      }
      return out;
    }
    setInitialPose(g.pose, stamp);
    out.pose = g.pose;
    out.fitness = g.fitness;
    out.distance_to_map = distanceToMap(g.pose.translation());
    // The global pose came from this very scan: use it as the first correction as well.
    ukf_.correct(g.pose, params_.measurement_position_std, params_.measurement_orientation_std);
    out.covariance = ukf_.poseCovariance();
    if (params_.global_confirm_after > 0) {
      confirming_ = true;
      confirm_wait_ = 0;
      ++stats_.uninitialized;
      out.status = LocalizationStatus::kUninitialized;
      return out;
    }
    ++stats_.relocalizations;
    out.status = LocalizationStatus::kRelocalized;
    return out;
  }

  auto t0 = Clock::now();
  const Eigen::Isometry3d before = ukf_.pose();
  const double dt = stamp - last_stamp_;
  ukf_.predict(dt, gyro, accel);
  last_stamp_ = stamp;
  const Eigen::Isometry3d predicted = ukf_.pose();
  out.motion = before.inverse() * predicted;
  stats_.filter_ms += msSince(t0);
  out.distance_to_map = distanceToMap(predicted.translation());
  out.pose = predicted;
  if (out.distance_to_map > params_.off_map_distance) {
    ++stats_.off_map;
    out.status = LocalizationStatus::kOffMap;
    if (params_.off_map_odometry && carryByScanOdometry(cloud, before, out.motion, dt)) {
      out.pose = ukf_.pose();
      out.motion = before.inverse() * out.pose;
      out.distance_to_map = distanceToMap(out.pose.translation());
    }
    out.covariance = ukf_.poseCovariance();
    recent_rejections_.clear();  // nothing to fail against
    return out;
  }

  bool accepted = false;
  PointCloudConstPtr scan = cloud;  // deskewed by the predicted motion when tracked
  if (cloud && cloud->size() >= static_cast<size_t>(params_.min_points)) {
    t0 = Clock::now();
    const Eigen::Vector2d centre = predicted.translation().head<2>();
    if ((centre - impl_->local_centre).norm() > params_.local_map_update_distance ||
        !impl_->local_map) {
      impl_->local_map = impl_->grid->crop(centre, params_.local_map_radius);
      impl_->local_centre = centre;
      impl_->tracker->setTarget(impl_->local_map);
      ++stats_.local_map_builds;
      stats_.local_map_ms += msSince(t0);
      t0 = Clock::now();
    }
    scan = deskewedScan(cloud, out.motion, dt);
    const PointCloudConstPtr source = reducedScan(scan);
    impl_->previous_scan = source;  // the first step off the map registers against it
    const RegistrationResult r = impl_->tracker->align(source, predicted);
    stats_.registration_ms += msSince(t0);
    out.fitness = r.converged ? r.fitness : -1.0;
    const Eigen::Isometry3d delta = predicted.inverse() * r.transform;
    double fitness_limit = params_.max_fitness;
    if (params_.fitness_ratio > 0.0 && recent_fitness_.size() >= 5) {
      std::vector<double> sorted = recent_fitness_;
      std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
      fitness_limit = std::min(
          fitness_limit,
          std::max(params_.fitness_ratio_floor, params_.fitness_ratio * sorted[sorted.size() / 2]));
    }
    accepted = r.converged && r.fitness <= fitness_limit &&
               delta.translation().norm() <= params_.max_correction_trans &&
               rotationAngle(delta.linear()) <= params_.max_correction_angle;
    if (accepted) {
      if (recent_fitness_.size() < 20) {
        recent_fitness_.push_back(r.fitness);
      } else {
        recent_fitness_[recent_next_] = r.fitness;
        recent_next_ = (recent_next_ + 1) % recent_fitness_.size();
      }
      t0 = Clock::now();
      ukf_.correct(r.transform, params_.measurement_position_std,
                   params_.measurement_orientation_std);
      stats_.filter_ms += msSince(t0);
    }
  }
  out.pose = ukf_.pose();
  out.covariance = ukf_.poseCovariance();
  recent_rejections_.push_back(!accepted);
  const size_t window = static_cast<size_t>(params_.effectiveDivergenceWindow());
  while (recent_rejections_.size() > window) recent_rejections_.pop_front();
  const auto rejected = std::count(recent_rejections_.begin(), recent_rejections_.end(), true);
  const bool gnss_diverged = gnssContradictsTracking(out.pose, stamp);
  if ((!accepted && rejected >= params_.divergence_scans) || gnss_diverged) {
    recent_rejections_.clear();
    impl_->gnss_disagreements = 0;
    stats_.gnss_divergences += gnss_diverged ? 1 : 0;
    out.diverged_by_gnss = gnss_diverged;
    out.diverged = true;
    ++stats_.divergences;
    searching_ = true;  // global localisation from the next scan on
    confirming_ = false;
  }
  if (confirming_ && !searching_) {
    // Not reported until a second global answer agrees with the tracked pose.
    out.status = LocalizationStatus::kUninitialized;
    ++stats_.uninitialized;
    if (accepted && ++confirm_wait_ >= params_.global_confirm_after) {
      // Independent of the tracked pose, but on the scan deskewed by the tracked motion: a raw
      // scan in a turn is smeared by degrees and its answer lands a metre off.
      const GlobalLocalizationResult g = globalLocalizeAt(scan, stamp);
      if (g.success) {
        const Eigen::Isometry3d d = out.pose.inverse() * g.pose;
        if (d.translation().norm() < 1.0 && rotationAngle(d.linear()) < 2.0 * M_PI / 180.0) {
          confirming_ = false;
          ++stats_.relocalizations;
          out.status = LocalizationStatus::kRelocalized;
        } else {
          ++stats_.global_disagreements;
          searching_ = true;  // two answers disagree: start over
          confirming_ = false;
        }
      }
    }
    return out;
  }
  if (accepted) {
    ++stats_.tracking;
    out.status = LocalizationStatus::kTracking;
  } else {
    ++stats_.predicted;
    out.status = LocalizationStatus::kPredicted;
  }
  return out;
}

}  // namespace osm_graph_slam
