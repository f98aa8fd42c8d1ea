#include "vwe_vo/core/projective_volume.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace vwe_vo {
namespace {
constexpr int kPlaneGroup = 4;  // planes voted per pass over a large ray array
}  // namespace

void VolumeOptions::validate() const {
  auto fail = [](const std::string& m) { throw std::invalid_argument("VolumeOptions: " + m); };
  if (!(grid_scale > 0.05 && grid_scale <= 2.0)) fail("grid_scale must be in (0.05, 2]");
  if (margin_px < 0 || margin_px > 200) fail("margin_px must be in [0, 200]");
  if (num_planes < 2 || num_planes > 512) fail("num_planes must be in [2, 512]");
  if (!(z_min_m > 0)) fail("z_min_m must be positive");
  if (!(z_max_m > z_min_m)) fail("z_max_m must be larger than z_min_m");
  if (num_threads < 1 || num_threads > 64) fail("num_threads must be in [1, 64]");
}

bool makeVolumeRay(const Vec3& o, const Vec3& d, double fx, double fy, double cx, double cy, VolumeRay* ray) {
  if (!(d.z() > 1e-9)) return false;
  const double ax = d.x() / d.z(), ay = d.y() / d.z();
  ray->u0 = float(fx * ax + cx);
  ray->v0 = float(fy * ay + cy);
  ray->du = float(fx * (o.x() - o.z() * ax));
  ray->dv = float(fy * (o.y() - o.z() * ay));
  // lambda = (z - o_z) / d_z > 0  <=>  z > o_z  <=>  rho < 1 / o_z (when o_z > 0)
  ray->rho_max = o.z() > 0 ? float(1.0 / o.z()) : std::numeric_limits<float>::infinity();
  return true;
}

ProjectiveVolume::ProjectiveVolume(const VolumeOptions& options, int sensor_width, int sensor_height, double fx,
                                   double fy, double cx, double cy)
    : options_(options), pool_(options.num_threads) {
  options_.validate();
  if (sensor_width <= 0 || sensor_height <= 0 || !(fx > 0) || !(fy > 0))
    throw std::invalid_argument("ProjectiveVolume: invalid sensor " + std::to_string(sensor_width) + "x" +
                                std::to_string(sensor_height) + " or focal length");
  const double s = options_.grid_scale;
  const int m = options_.margin_px;
  width_ = int(std::ceil(sensor_width * s)) + 2 * m;
  height_ = int(std::ceil(sensor_height * s)) + 2 * m;
  fx_ = fx * s;
  fy_ = fy * s;
  // Pixel centres: sensor pixel x maps to grid pixel (x + 0.5) * s - 0.5 + margin.
  cx_ = (cx + 0.5) * s - 0.5 + m;
  cy_ = (cy + 0.5) * s - 0.5 + m;
  const int L = options_.num_planes;
  rho_.resize(L);
  const double rho_near = 1.0 / options_.z_min_m, rho_far = 1.0 / options_.z_max_m;
  for (int l = 0; l < L; ++l) rho_[l] = rho_near + (rho_far - rho_near) * l / (L - 1);
  grid_.assign(numVoxels(), 0.0f);
}

template <typename Fn>
inline void ProjectiveVolume::forEachVote(const VolumeRay& r, int l, Fn&& fn) const {
  const float rho = float(rho_[l]);
  if (!(rho < r.rho_max)) return;
  const float u = r.u0 + rho * r.du, v = r.v0 + rho * r.dv;
  if (!(u >= 0.0f && v >= 0.0f && u < float(width_ - 1) && v < float(height_ - 1))) return;
  const int ix = int(u), iy = int(v);
  const float ax = u - float(ix), ay = v - float(iy);
  const size_t idx = (size_t(l) * height_ + iy) * width_ + ix;
  fn(idx, ax, ay);
}

size_t ProjectiveVolume::vote(const std::vector<VolumeRay>& rays) {
  const int L = options_.num_planes, T = pool_.numThreads();
  std::vector<double> sums(T, 0.0), sqs(T, 0.0);
  std::vector<size_t> counts(T, 0);
  float* g = grid_.data();
  const size_t W = size_t(width_);
  // Sum of squares: accumulated vote by vote when the votes are few, or by one pass over the
  // plane afterwards when that is cheaper (more than a quarter of the plane would be touched).
  // Either way the cost is bounded by the votes, never more than the grid.
  const size_t plane_voxels = size_t(width_) * height_;
  const bool scan_planes = 4 * rays.size() >= plane_voxels;
  // Many rays (the DSI, big volumes): the ray array no longer fits in cache and streaming it
  // once per plane makes voting memory-bound; each pass over the rays serves a group of planes.
  const int group = scan_planes ? kPlaneGroup : 1;
  const int num_groups = (L + group - 1) / group;
  pool_.run(num_groups, [&](int chunk, int t) {
    const int l0 = chunk * group, l1 = std::min(L, l0 + group);
    double s = 0.0, q = 0.0;
    size_t n = 0;
    if (scan_planes) {
      for (const VolumeRay& r : rays) {
        for (int l = l0; l < l1; ++l) {
          forEachVote(r, l, [&](size_t idx, float ax, float ay) {
            g[idx] += (1 - ax) * (1 - ay);
            g[idx + 1] += ax * (1 - ay);
            g[idx + W] += (1 - ax) * ay;
            g[idx + W + 1] += ax * ay;
            ++n;
          });
        }
      }
      for (int l = l0; l < l1; ++l) {
        const float* plane = g + size_t(l) * plane_voxels;
        float qf[8] = {0, 0, 0, 0, 0, 0, 0, 0};
        size_t i = 0;
        for (; i + 8 <= plane_voxels; i += 8)
          for (int k = 0; k < 8; ++k) qf[k] += plane[i + k] * plane[i + k];
        for (; i < plane_voxels; ++i) q += double(plane[i]) * plane[i];
        for (int k = 0; k < 8; ++k) q += qf[k];
      }
      s = double(n);
    } else {
      for (int l = l0; l < l1; ++l) {
        for (const VolumeRay& r : rays) {
          forEachVote(r, l, [&](size_t idx, float ax, float ay) {
            const float w[4] = {(1 - ax) * (1 - ay), ax * (1 - ay), (1 - ax) * ay, ax * ay};
            const size_t id[4] = {idx, idx + 1, idx + W, idx + W + 1};
            for (int c = 0; c < 4; ++c) {
              const float old = g[id[c]];
              g[id[c]] = old + w[c];
              q += double(w[c]) * (2.0 * double(old) + double(w[c]));
            }
            ++n;
          });
        }
      }
      s = double(n);
    }
    sums[t] += s;
    sqs[t] += q;
    counts[t] += n;
  });
  size_t votes = 0;
  for (int t = 0; t < T; ++t) {
    sum_ += sums[t];
    sum_sq_ += sqs[t];
    votes += counts[t];
  }
  last_votes_ += votes;
  return votes;
}

double ProjectiveVolume::variance() const {
  const double n = double(numVoxels());
  const double mean = sum_ / n;
  return sum_sq_ / n - mean * mean;
}

void ProjectiveVolume::varianceRaySensitivities(const std::vector<VolumeRay>& rays,
                                                std::vector<Eigen::Vector4d>* out) const {
  const int L = options_.num_planes, T = pool_.numThreads();
  const float mean = float(sum_ / double(numVoxels()));
  const size_t W = size_t(width_);
  std::vector<std::vector<Eigen::Vector4d>> per_thread(T, std::vector<Eigen::Vector4d>(rays.size(), Eigen::Vector4d::Zero()));
  const float* g = grid_.data();
  pool_.run(L, [&](int l, int t) {
    const double rho = rho_[l];
    auto& acc = per_thread[t];
    for (size_t i = 0; i < rays.size(); ++i) {
      forEachVote(rays[i], l, [&](size_t idx, float ax, float ay) {
        const float r00 = g[idx] - mean, r10 = g[idx + 1] - mean, r01 = g[idx + W] - mean, r11 = g[idx + W + 1] - mean;
        // d(sum_c r_c w_c)/du and /dv for the bilinear weights w_c(ax, ay).
        const double gu = double((r10 - r00) * (1 - ay) + (r11 - r01) * ay);
        const double gv = double((r01 - r00) * (1 - ax) + (r11 - r10) * ax);
        acc[i] += Eigen::Vector4d(gu, gu * rho, gv, gv * rho);
      });
    }
  });
  out->assign(rays.size(), Eigen::Vector4d::Zero());
  for (int t = 0; t < T; ++t)
    for (size_t i = 0; i < rays.size(); ++i) (*out)[i] += per_thread[t][i];
}

void ProjectiveVolume::clear(const std::vector<VolumeRay>& rays) {
  // Zero what the votes touched, or whole planes when that is cheaper.
  if (4 * last_votes_ >= numVoxels()) {
    std::fill(grid_.begin(), grid_.end(), 0.0f);
  } else {
    float* g = grid_.data();
    const size_t W = size_t(width_);
    pool_.run(options_.num_planes, [&](int l, int) {
      for (const VolumeRay& r : rays)
        forEachVote(r, l, [&](size_t idx, float, float) { g[idx] = g[idx + 1] = g[idx + W] = g[idx + W + 1] = 0.0f; });
    });
  }
  sum_ = sum_sq_ = 0.0;
  last_votes_ = 0;
}

}  // namespace vwe_vo
