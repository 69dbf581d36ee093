#include "osm_graph_slam/multi_cue/multi_cue_image.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "osm_graph_slam/common/timing.h"

namespace osm_graph_slam {

namespace {

using Clock = std::chrono::steady_clock;

MultiCueImage emptyImage(const SphericalProjectionParams& projection) {
  MultiCueImage image;
  image.projection = projection;
  const size_t n = projection.size();
  image.range.assign(n, 0.0f);
  image.intensity.assign(n, 0.0f);
  image.point.assign(n, Eigen::Vector3f::Zero());
  image.normal.assign(n, Eigen::Vector3f::Zero());
  image.subpixel.assign(n, Eigen::Vector2f::Zero());
  image.mask.assign(n, 0);
  return image;
}

/// Where a return falls: its continuous pixel and range; pixel -1 when outside the image.
struct Projected {
  int pixel = -1;
  float u = 0.0f, v = 0.0f, range = 0.0f;
};

Projected projectOne(const SphericalProjectionParams& projection, const Eigen::Vector3f& p) {
  Projected out;
  if (projection.project(p, &out.u, &out.v, &out.range))
    out.pixel = static_cast<int>(out.v) * projection.cols + static_cast<int>(out.u);
  return out;
}

int threadsOf(int num_threads) {
  return num_threads > 0 ? num_threads : tbb::task_arena::automatic;
}

/// Writes the return into its pixel unless a nearer one is there already (the depth buffer).
void splat(MultiCueImage& image, const Projected& at, const Eigen::Vector3f& p, float intensity) {
  if (at.pixel < 0) return;
  const int i = at.pixel;
  const float u = at.u, v = at.v, r = at.range;
  if (image.hasPoint(i) && image.range[i] <= r) return;
  image.range[i] = r;
  image.intensity[i] = intensity;
  image.point[i] = p;
  image.subpixel[i] = Eigen::Vector2f(u, v);
  image.mask[i] = MultiCueImage::kPoint;
}

bool onOneSurface(float range_a, float range_b, double max_jump_ratio) {
  return std::abs(range_a - range_b) < max_jump_ratio * std::min(range_a, range_b);
}

/// Of the two neighbours of pixel i along one axis (-1 and +1 steps), the one on the same surface
/// with the closer range; returns the step (-1 or +1) and sets *neighbour, or 0 when neither is.
int sameSurfaceNeighbour(const MultiCueImage& image, int i, int neighbour_minus, int neighbour_plus,
                         double max_jump_ratio, int* neighbour) {
  int best_step = 0;
  float best_jump = std::numeric_limits<float>::infinity();
  const int candidates[2] = {neighbour_minus, neighbour_plus};
  for (int k = 0; k < 2; ++k) {
    const int j = candidates[k];
    if (j < 0 || !image.hasPoint(j)) continue;
    if (!onOneSurface(image.range[i], image.range[j], max_jump_ratio)) continue;
    const float jump = std::abs(image.range[i] - image.range[j]);
    if (jump < best_jump) {
      best_jump = jump;
      best_step = k == 0 ? -1 : 1;
      *neighbour = j;
    }
  }
  return best_step;
}

/// The next pyramid level when rows and columns are even: a coarse pixel covers exactly 2 x 2
/// fine ones, so the nearest of their returns is what re-projecting them through the depth buffer
/// gives, without projecting again.
MultiCueImage decimate(const MultiCueImage& finer) {
  MultiCueImage coarse = emptyImage(finer.projection.coarser());
  coarse.has_intensity = finer.has_intensity;
  for (int row = 0; row < coarse.rows(); ++row) {
    for (int col = 0; col < coarse.cols(); ++col) {
      int nearest = -1;
      for (int i : {finer.index(2 * row, 2 * col), finer.index(2 * row, 2 * col + 1),
                    finer.index(2 * row + 1, 2 * col), finer.index(2 * row + 1, 2 * col + 1)}) {
        if (finer.hasPoint(i) && (nearest < 0 || finer.range[i] < finer.range[nearest]))
          nearest = i;
      }
      if (nearest < 0) continue;
      const int i = coarse.index(row, col);
      coarse.range[i] = finer.range[nearest];
      coarse.intensity[i] = finer.intensity[nearest];
      coarse.point[i] = finer.point[nearest];
      coarse.subpixel[i] = 0.5f * finer.subpixel[nearest];
      coarse.mask[i] = MultiCueImage::kPoint;
    }
  }
  return coarse;
}

/// The next pyramid level: the returns of `finer` re-projected at half the resolution.
MultiCueImage coarserLevel(const MultiCueImage& finer) {
  if (finer.rows() % 2 == 0 && finer.cols() % 2 == 0) return decimate(finer);
  std::vector<Eigen::Vector3f> points;
  std::vector<float> intensity;
  points.reserve(finer.range.size());
  intensity.reserve(finer.range.size());
  for (int i = 0; i < finer.projection.size(); ++i) {
    if (!finer.hasPoint(i)) continue;
    points.push_back(finer.point[i]);
    intensity.push_back(finer.intensity[i]);
  }
  return projectPoints(points, intensity, finer.has_intensity, finer.projection.coarser());
}

}  // namespace

size_t MultiCueImage::pointCount() const {
  return std::count_if(mask.begin(), mask.end(), [](uint8_t m) { return m & kPoint; });
}

size_t MultiCueImage::normalCount() const {
  return std::count_if(mask.begin(), mask.end(), [](uint8_t m) { return m & kNormal; });
}

bool cloudHasIntensity(const PointCloud& cloud) {
  return std::any_of(cloud.points.begin(), cloud.points.end(), [](const PointT& p) {
    return std::isfinite(p.intensity) && p.intensity != 0.0f;
  });
}

MultiCueImage projectCloud(const PointCloud& cloud, const SphericalProjectionParams& projection,
                           int num_threads) {
  MultiCueImage image = emptyImage(projection);
  image.has_intensity = cloudHasIntensity(cloud);
  // The trigonometry in parallel, the depth buffer in the cloud's order.
  std::vector<Projected> projected(cloud.size());
  tbb::task_arena arena(threadsOf(num_threads));
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, cloud.size(), 4096),
                      [&](const tbb::blocked_range<size_t>& r) {
                        for (size_t k = r.begin(); k < r.end(); ++k)
                          projected[k] = projectOne(projection, cloud[k].getVector3fMap());
                      });
  });
  for (size_t k = 0; k < cloud.size(); ++k) {
    const PointT& p = cloud[k];
    const float intensity = image.has_intensity && std::isfinite(p.intensity) ? p.intensity : 0.0f;
    splat(image, projected[k], p.getVector3fMap(), intensity);
  }
  return image;
}

MultiCueImage projectPoints(const std::vector<Eigen::Vector3f>& points,
                            const std::vector<float>& intensity, bool has_intensity,
                            const SphericalProjectionParams& projection) {
  MultiCueImage image = emptyImage(projection);
  image.has_intensity = has_intensity;
  for (size_t k = 0; k < points.size(); ++k) {
    splat(image, projectOne(projection, points[k]), points[k], has_intensity ? intensity[k] : 0.0f);
  }
  return image;
}

namespace {

/// computeNormals for one image row (each pixel writes only its own normal).
void computeRowNormals(MultiCueImage& image, int row, double ratio) {
  const int rows = image.rows(), cols = image.cols();
  const bool wraps = image.projection.fullCircle();
  for (int col = 0; col < cols; ++col) {
    const int i = image.index(row, col);
    image.mask[i] &= ~MultiCueImage::kNormal;
    image.normal[i].setZero();
    if (!image.hasPoint(i)) continue;
    const int left = col > 0 ? i - 1 : (wraps ? image.index(row, cols - 1) : -1);
    const int right = col + 1 < cols ? i + 1 : (wraps ? image.index(row, 0) : -1);
    const int up = row > 0 ? i - cols : -1;
    const int down = row + 1 < rows ? i + cols : -1;
    int h = -1, v = -1;
    const int h_step = sameSurfaceNeighbour(image, i, left, right, ratio, &h);
    const int v_step = sameSurfaceNeighbour(image, i, up, down, ratio, &v);
    if (h_step == 0 || v_step == 0) continue;
    // Both tangents point along +u and +v, so the cross product's sign is fixed before the
    // normal is turned to face the sensor.
    const Eigen::Vector3f along_u = float(h_step) * (image.point[h] - image.point[i]);
    const Eigen::Vector3f along_v = float(v_step) * (image.point[v] - image.point[i]);
    Eigen::Vector3f n = along_u.cross(along_v);
    const float norm = n.norm();
    if (!(norm > 1e-9f * along_u.norm() * along_v.norm()) || norm == 0.0f) continue;
    n /= norm;
    if (n.dot(image.point[i]) > 0.0f) n = -n;
    image.normal[i] = n;
    image.mask[i] |= MultiCueImage::kNormal;
  }
}

}  // namespace

void computeNormals(MultiCueImage& image, const SurfaceContinuityParams& continuity,
                    int num_threads) {
  tbb::task_arena arena(threadsOf(num_threads));
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<int>(0, image.rows(), 4),
                      [&](const tbb::blocked_range<int>& r) {
                        for (int row = r.begin(); row < r.end(); ++row)
                          computeRowNormals(image, row, continuity.max_range_jump_ratio);
                      });
  });
}

MultiCuePyramid buildPyramid(const PointCloud& cloud, const SphericalProjectionParams& projection,
                             int levels, const SurfaceContinuityParams& continuity,
                             MultiCueBuildTimes* times, int num_threads) {
  MultiCuePyramid pyramid;
  MultiCueBuildTimes t;
  auto start = Clock::now();
  pyramid.levels.push_back(projectCloud(cloud, projection, num_threads));
  t.projection_ms += msSince(start);
  for (int level = 1; level < levels; ++level) {
    start = Clock::now();
    pyramid.levels.push_back(coarserLevel(pyramid.levels.back()));
    t.projection_ms += msSince(start);
  }
  start = Clock::now();
  for (MultiCueImage& image : pyramid.levels) computeNormals(image, continuity, num_threads);
  t.normals_ms += msSince(start);
  if (times) *times = t;
  return pyramid;
}

}  // namespace osm_graph_slam
