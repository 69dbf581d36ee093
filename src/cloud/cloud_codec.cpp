#include "osm_graph_slam/cloud/cloud_codec.h"

#include <zlib.h>

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

namespace osm_graph_slam {
namespace {

// Layout: magic, version, flags, points, resolution, origin (3), intensity min and step, stamp,
// frame_id (length + bytes), raw and stored payload sizes, payload, then a CRC-32 of everything
// before it. Little-endian, as every machine this runs on.
constexpr char kMagic[4] = {'O', 'G', 'S', 'C'};
constexpr uint16_t kVersion = 1;
constexpr uint16_t kDeflated = 1;
constexpr uint16_t kLossless = 2;  // float32 planes (resolution <= 0)
constexpr int kPlanes = 4;         // x, y, z, intensity: 2 bytes each, or 4 when lossless

class Writer {
 public:
  template <typename T>
  void put(const T& value) {
    const char* p = reinterpret_cast<const char*>(&value);
    bytes.append(p, sizeof(T));
  }
  std::string bytes;
};

class Reader {
 public:
  explicit Reader(const std::string& bytes) : bytes_(bytes) {}
  template <typename T>
  bool get(T& value) {
    if (bytes_.size() - pos_ < sizeof(T)) return false;
    std::memcpy(&value, bytes_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return true;
  }
  bool take(size_t n, const char*& data) {
    if (bytes_.size() - pos_ < n) return false;
    data = bytes_.data() + pos_;
    pos_ += n;
    return true;
  }
  size_t pos() const { return pos_; }

 private:
  const std::string& bytes_;
  size_t pos_ = 0;
};

uint32_t crc(const char* data, size_t n) {
  return static_cast<uint32_t>(::crc32(0L, reinterpret_cast<const Bytef*>(data), n));
}

// Byte-shuffled planes: plane k holds the points' 16-bit values, low bytes first, then high.
void putValue(std::vector<uint8_t>& planes, size_t n, int plane, size_t i, uint16_t v) {
  uint8_t* base = planes.data() + 2 * n * plane;
  base[i] = static_cast<uint8_t>(v & 0xff);
  base[n + i] = static_cast<uint8_t>(v >> 8);
}

uint16_t getValue(const uint8_t* planes, size_t n, int plane, size_t i) {
  const uint8_t* base = planes + 2 * n * plane;
  return static_cast<uint16_t>(base[i] | (base[n + i] << 8));
}

bool isFinite(const PointT& p) {
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) &&
         std::isfinite(p.intensity);
}

// Lossless planes: plane k holds the points' float bits, byte b of every point, then byte b + 1.
void putFloat(std::vector<uint8_t>& planes, size_t n, int plane, size_t i, float v) {
  uint32_t bits = 0;
  std::memcpy(&bits, &v, sizeof(bits));
  uint8_t* base = planes.data() + 4 * n * plane;
  for (int b = 0; b < 4; ++b) base[b * n + i] = static_cast<uint8_t>(bits >> (8 * b));
}

float getFloat(const uint8_t* planes, size_t n, int plane, size_t i) {
  const uint8_t* base = planes + 4 * n * plane;
  uint32_t bits = 0;
  for (int b = 0; b < 4; ++b) bits |= static_cast<uint32_t>(base[b * n + i]) << (8 * b);
  float v = 0.f;
  std::memcpy(&v, &bits, sizeof(v));
  return v;
}

PointCloudPtr fail(std::string* error, const std::string& why) {
  if (error) *error = why;
  return nullptr;
}

}  // namespace

std::string encodeCloud(const PointCloud& cloud, const CloudCodecParams& params) {
  std::vector<const PointT*> points;
  points.reserve(cloud.size());
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::max());
  Eigen::Vector3d hi = -lo;
  double i_lo = std::numeric_limits<double>::max(), i_hi = -i_lo;
  for (const auto& p : cloud.points) {
    if (!isFinite(p)) continue;
    points.push_back(&p);
    const Eigen::Vector3d v(p.x, p.y, p.z);
    lo = lo.cwiseMin(v), hi = hi.cwiseMax(v);
    i_lo = std::min<double>(i_lo, p.intensity), i_hi = std::max<double>(i_hi, p.intensity);
  }
  const size_t n = points.size();
  const Eigen::Vector3d origin = n ? Eigen::Vector3d(0.5 * (lo + hi)) : Eigen::Vector3d::Zero();
  // 65,534 steps span the widest axis: int16 from -32,767 to 32,767 around the box centre.
  const double extent = n ? (hi - lo).maxCoeff() : 0.0;
  const bool lossless = params.resolution <= 0.0;
  const double resolution =
      lossless ? 0.0 : std::max(params.resolution, extent / 65534.0 * (1.0 + 1e-9));
  const double i_step = n && i_hi > i_lo ? (i_hi - i_lo) / 65535.0 : 0.0;

  std::vector<uint8_t> planes((lossless ? 4 : 2) * kPlanes * n);
  for (size_t i = 0; i < n; ++i) {
    const PointT& p = *points[i];
    if (lossless) {
      const float values[kPlanes] = {p.x, p.y, p.z, p.intensity};
      for (int k = 0; k < kPlanes; ++k) putFloat(planes, n, k, i, values[k]);
      continue;
    }
    const double xyz[3] = {p.x, p.y, p.z};
    for (int k = 0; k < 3; ++k) {
      const long q = std::lround((xyz[k] - origin[k]) / resolution);
      putValue(planes, n, k, i, static_cast<uint16_t>(static_cast<int16_t>(q)));
    }
    const long qi = i_step > 0 ? std::lround((p.intensity - i_lo) / i_step) : 0;
    putValue(planes, n, 3, i, static_cast<uint16_t>(std::clamp<long>(qi, 0, 65535)));
  }

  std::string payload;
  uint16_t flags = lossless ? kLossless : 0;
  if (params.deflate_level > 0 && !planes.empty()) {
    uLongf size = compressBound(planes.size());
    payload.resize(size);
    if (compress2(reinterpret_cast<Bytef*>(&payload[0]), &size, planes.data(), planes.size(),
                  std::min(params.deflate_level, 9)) == Z_OK &&
        size < planes.size()) {
      payload.resize(size);
      flags |= kDeflated;
    }
  }
  if (!(flags & kDeflated)) payload.assign(planes.begin(), planes.end());

  Writer w;
  w.bytes.reserve(payload.size() + 128 + cloud.header.frame_id.size());
  w.bytes.append(kMagic, sizeof(kMagic));
  w.put(kVersion);
  w.put(flags);
  w.put(static_cast<uint32_t>(n));
  w.put(resolution);
  for (int k = 0; k < 3; ++k) w.put(origin[k]);
  w.put(n ? i_lo : 0.0);
  w.put(i_step);
  w.put(static_cast<uint64_t>(cloud.header.stamp));
  const std::string frame = cloud.header.frame_id.substr(0, 65535);
  w.put(static_cast<uint16_t>(frame.size()));
  w.bytes += frame;
  w.put(static_cast<uint32_t>(planes.size()));
  w.put(static_cast<uint32_t>(payload.size()));
  w.bytes += payload;
  w.put(crc(w.bytes.data(), w.bytes.size()));
  return w.bytes;
}

PointCloudPtr decodeCloud(const std::string& bytes, std::string* error) {
  if (bytes.size() < sizeof(kMagic) + sizeof(uint32_t) ||
      std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0)
    return fail(error, "not an encoded cloud (no OGSC magic)");
  uint32_t stored_crc = 0;
  std::memcpy(&stored_crc, bytes.data() + bytes.size() - sizeof(uint32_t), sizeof(uint32_t));
  if (crc(bytes.data(), bytes.size() - sizeof(uint32_t)) != stored_crc)
    return fail(error, "checksum mismatch (corrupt or truncated)");

  Reader r(bytes);
  const char* skip = nullptr;
  uint16_t version = 0, flags = 0, frame_size = 0;
  uint32_t n = 0, raw_size = 0, payload_size = 0;
  double resolution = 0, i_lo = 0, i_step = 0;
  double origin[3];
  uint64_t stamp = 0;
  const char* frame = nullptr;
  const char* payload = nullptr;
  if (!r.take(sizeof(kMagic), skip) || !r.get(version)) return fail(error, "truncated header");
  if (version != kVersion) return fail(error, "unknown version " + std::to_string(version));
  const bool header_ok = r.get(flags) && r.get(n) && r.get(resolution) && r.get(origin[0]) &&
                         r.get(origin[1]) && r.get(origin[2]) && r.get(i_lo) && r.get(i_step) &&
                         r.get(stamp) && r.get(frame_size) && r.take(frame_size, frame) &&
                         r.get(raw_size) && r.get(payload_size) && r.take(payload_size, payload);
  if (!header_ok || r.pos() + sizeof(uint32_t) != bytes.size())
    return fail(error, "truncated or oversized encoding");
  const bool lossless = flags & kLossless;
  if (raw_size != (lossless ? 4ull : 2ull) * kPlanes * n)
    return fail(error, "payload size does not match points");

  std::vector<uint8_t> planes(raw_size);
  if (flags & kDeflated) {
    uLongf size = raw_size;
    if (uncompress(planes.data(), &size, reinterpret_cast<const Bytef*>(payload), payload_size) !=
            Z_OK ||
        size != raw_size)
      return fail(error, "payload does not inflate to its size");
  } else if (payload_size == raw_size) {
    if (raw_size) std::memcpy(planes.data(), payload, raw_size);
  } else {
    return fail(error, "payload size does not match points");
  }

  auto cloud = std::make_shared<PointCloud>();
  cloud->header.frame_id.assign(frame, frame_size);
  cloud->header.stamp = stamp;
  cloud->resize(n);
  for (size_t i = 0; i < n; ++i) {
    PointT& p = cloud->points[i];
    if (lossless) {
      p.x = getFloat(planes.data(), n, 0, i);
      p.y = getFloat(planes.data(), n, 1, i);
      p.z = getFloat(planes.data(), n, 2, i);
      p.intensity = getFloat(planes.data(), n, 3, i);
      continue;
    }
    p.x = static_cast<float>(origin[0] +
                             static_cast<int16_t>(getValue(planes.data(), n, 0, i)) * resolution);
    p.y = static_cast<float>(origin[1] +
                             static_cast<int16_t>(getValue(planes.data(), n, 1, i)) * resolution);
    p.z = static_cast<float>(origin[2] +
                             static_cast<int16_t>(getValue(planes.data(), n, 2, i)) * resolution);
    p.intensity = static_cast<float>(i_lo + getValue(planes.data(), n, 3, i) * i_step);
  }
  cloud->width = n;
  cloud->height = 1;
  cloud->is_dense = true;
  return cloud;
}

double encodedResolution(const std::string& bytes) {
  constexpr size_t offset = sizeof(kMagic) + 2 * sizeof(uint16_t) + sizeof(uint32_t);
  double resolution = 0.0;
  if (decodeCloud(bytes) == nullptr || bytes.size() < offset + sizeof(double)) return 0.0;
  std::memcpy(&resolution, bytes.data() + offset, sizeof(double));
  return resolution;
}

}  // namespace osm_graph_slam
