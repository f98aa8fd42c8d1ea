#include "vwe_vo/vwe/projective_volume.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <type_traits>

namespace vwe_vo {
namespace {
constexpr int kPlaneGroup = 4;         // planes voted per pass over a large ray array
constexpr int kSensitivityChunks = 4;  // plane chunks of contrastOfRays()
// A plane with more than 1/this votes per voxel is zeroed by a sweep (a fill streams a plane
// much faster than the votes can be revisited), otherwise by revisiting its votes.
constexpr size_t kZeroSweepVotesPerVoxel = 64;

/// One bilinear vote at (ix + ax, iy + ay) of a plane W voxels wide, idx = iy * W + ix.
inline void addVote(float* plane, size_t idx, size_t W, float ax, float ay) {
  plane[idx] += (1 - ax) * (1 - ay);
  plane[idx + 1] += ax * (1 - ay);
  plane[idx + W] += (1 - ax) * ay;
  plane[idx + W + 1] += ax * ay;
}

/// The squares of one bilinear vote's weights, summed: ((1-ax)^2 + ax^2) ((1-ay)^2 + ay^2).
inline float selfSquares(float ax, float ay) {
  return ((1 - ax) * (1 - ax) + ax * ax) * ((1 - ay) * (1 - ay) + ay * ay);
}
}  // namespace

const char* contrastName(Contrast contrast) {
  return contrast == Contrast::kVariance ? "variance" : "density_per_vote";
}

void VolumeOptions::validate(const std::string& section) const {
  auto fail = [&](const std::string& m) { throw std::invalid_argument(section + "." + m); };
  if (!(grid_scale > 0.05 && grid_scale <= 2.0)) fail("grid_scale must be in (0.05, 2]");
  if (margin_px < 0 || margin_px > 200) fail("margin_px must be in [0, 200]");
  if (num_planes < 2 || num_planes > 512) fail("num_planes must be in [2, 512]");
  if (!(z_min_m > 0)) fail("z_min_m must be positive");
  if (!(z_max_m > z_min_m || z_max_m < 0))
    fail("z_max_m must be larger than z_min_m, or negative (planes through infinity)");
  if (num_threads < 1 || num_threads > 64) fail("num_threads must be in [1, 64]");
  if (!(pose_slice_s >= 0 && pose_slice_s <= 0.01)) fail("pose_slice_s must be in [0, 0.01]");
}

ProjectiveVolume::ProjectiveVolume(const VolumeOptions& options, int sensor_width,
                                   int sensor_height, double fx, double fy, double cx, double cy)
    : options_(options), pool_(options.num_threads) {
  options_.validate();
  if (sensor_width <= 0 || sensor_height <= 0 || !(fx > 0) || !(fy > 0))
    throw std::invalid_argument("ProjectiveVolume: invalid sensor " + std::to_string(sensor_width) +
                                "x" + std::to_string(sensor_height) + " or focal length");
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
  // A negative z_max_m puts the far planes past inverse depth 0: a ray is a line, and
  // u0 + rho du continues it through infinity (see VolumeOptions::z_max_m).
  const double rho_near = 1.0 / options_.z_min_m, rho_far = 1.0 / options_.z_max_m;
  for (int l = 0; l < L; ++l) rho_[l] = rho_near + (rho_far - rho_near) * l / (L - 1);
  grid_.assign(numVoxels(), 0.0f);
}

template <typename Fn>
inline void ProjectiveVolume::forEachPlaneVote(const VolumeRay& r, float rho, Fn&& fn) const {
  if (!(rho < r.rho_max)) return;
  const float u = r.u0 + rho * r.du, v = r.v0 + rho * r.dv;
  if (!(u >= 0.0f && v >= 0.0f && u < float(width_ - 1) && v < float(height_ - 1))) return;
  const int ix = int(u), iy = int(v);
  fn(size_t(iy) * width_ + ix, u - float(ix), v - float(iy));
}

template <typename Fn>
inline void ProjectiveVolume::forEachPlaneVoteBatched(float rho, size_t begin, size_t end,
                                                      Fn&& fn) const {
  // The same arithmetic as forEachPlaneVote(), on the rays' columns a batch at a time: the
  // first loop has no branches and vectorises, the second only touches the grid.
  constexpr int kBatch = 64;
  alignas(64) int idx[kBatch];
  alignas(64) float ax[kBatch], ay[kBatch];
  const float umax = float(width_ - 1), vmax = float(height_ - 1);
  const int width = width_;
  const float* u0 = soa_.u0.data();
  const float* v0 = soa_.v0.data();
  const float* du = soa_.du.data();
  const float* dv = soa_.dv.data();
  const float* rho_max = soa_.rho_max.data();
  for (size_t b = begin; b < end; b += kBatch) {
    const int m = int(std::min<size_t>(kBatch, end - b));
    for (int k = 0; k < m; ++k) {
      const float u = u0[b + k] + rho * du[b + k], v = v0[b + k] + rho * dv[b + k];
      const bool in = (rho < rho_max[b + k]) & (u >= 0.0f) & (v >= 0.0f) & (u < umax) & (v < vmax);
      const float uc = in ? u : 0.0f, vc = in ? v : 0.0f;
      const int ix = int(uc), iy = int(vc);
      ax[k] = uc - float(ix);
      ay[k] = vc - float(iy);
      idx[k] = in ? iy * width + ix : -1;
    }
    for (int k = 0; k < m; ++k)
      if (idx[k] >= 0) fn(b + size_t(k), size_t(idx[k]), ax[k], ay[k]);
  }
}

template <typename Fn>
inline void ProjectiveVolume::forEachVote(const VolumeRay& r, int l, Fn&& fn) const {
  const size_t offset = size_t(l) * width_ * height_;
  forEachPlaneVote(r, float(rho_[l]),
                   [&](size_t idx, float ax, float ay) { fn(offset + idx, ax, ay); });
}

double ProjectiveVolume::peakDepth(const VolumeRay& ray) const {
  if (grid_.empty()) return 0.0;
  const size_t W = size_t(width_);
  float best = 0.0f;
  int best_l = -1;
  for (int l = 0; l < options_.num_planes; ++l)
    forEachVote(ray, l, [&](size_t idx, float ax, float ay) {
      const float* g = grid_.data() + idx;
      const float value = (1 - ax) * (1 - ay) * g[0] + ax * (1 - ay) * g[1] + (1 - ax) * ay * g[W] +
                          ax * ay * g[W + 1];
      if (value > best) best = value, best_l = l;
    });
  return best_l < 0 ? 0.0 : planeDepth(best_l);
}

size_t ProjectiveVolume::vote(const std::vector<VolumeRay>& rays, bool for_contrast) {
  if (grid_.empty()) grid_.assign(numVoxels(), 0.0f);
  const int L = options_.num_planes;
  const size_t W = size_t(width_);
  float* g = grid_.data();
  // Many rays (the DSI, big volumes): the ray array no longer fits in cache and streaming it
  // once per plane makes voting memory-bound; each pass over the rays serves a group of planes.
  const bool many_rays = 4 * rays.size() >= size_t(width_) * height_;
  const int group = many_rays ? kPlaneGroup : 1;
  const int num_groups = (L + group - 1) / group;
  plane_counts_.assign(size_t(num_groups), 0);
  plane_self_.assign(size_t(num_groups), 0.0);
  soa_.assign(rays);
  const size_t N = rays.size(), plane_voxels = W * height_;
  // A block of rays serves the group's planes while its columns are in cache. Only the four
  // read-modify-writes per vote (and, for a contrast, the vote's own squares): the sum of
  // squares is gathered by clear().
  auto run = [&](auto own_squares) {
    pool_.run(num_groups, [&](int chunk, int) {
      const int l0 = chunk * group, l1 = std::min(L, l0 + group);
      size_t n = 0;
      double self = 0.0;
      constexpr size_t kBlock = 1024;
      for (size_t b = 0; b < N; b += kBlock)
        for (int l = l0; l < l1; ++l) {
          float* plane = g + size_t(l) * plane_voxels;
          const size_t e = std::min(N, b + kBlock);
          float block_self = 0.0f;
          forEachPlaneVoteBatched(float(rho_[l]), b, e,
                                  [&](size_t, size_t idx, float ax, float ay) {
                                    addVote(plane, idx, W, ax, ay);
                                    if constexpr (decltype(own_squares)::value)
                                      block_self += selfSquares(ax, ay);
                                    ++n;
                                  });
          self += double(block_self);
        }
      plane_counts_[size_t(chunk)] = n;
      plane_self_[size_t(chunk)] = self;
    });
  };
  if (for_contrast)
    run(std::true_type());
  else
    run(std::false_type());
  size_t votes = 0;
  for (size_t n : plane_counts_) votes += n;
  for (double q : plane_self_) self_ += q;
  if (!for_contrast) self_ = std::numeric_limits<double>::quiet_NaN();
  sum_ += double(votes);  // every vote adds weights summing to one
  last_votes_ += votes;
  return votes;
}

double ProjectiveVolume::contrast() const {
  double q = 0.0;
  for (float v : grid_) q += double(v) * v;
  return contrastOf(q, sum_, self_);
}

double ProjectiveVolume::contrastOf(double sum_squares, double sum, double self_squares) const {
  if (options_.contrast == Contrast::kDensityPerVote)
    return sum > 0 ? (sum_squares - self_squares) / sum : 0.0;
  const double n = double(numVoxels());
  const double mean = sum / n;
  return sum_squares / n - mean * mean;
}

double ProjectiveVolume::contrastOfRays(const std::vector<VolumeRay>& rays, size_t* votes,
                                        std::vector<Eigen::Vector4d>* sensitivities) {
  const int L = options_.num_planes, T = pool_.numThreads();
  const size_t W = size_t(width_), plane_voxels = W * height_, N = rays.size();
  if (scratch_.size() < size_t(T)) scratch_.resize(size_t(T));
  for (auto& plane : scratch_)
    if (plane.size() != plane_voxels) plane.assign(plane_voxels, 0.0f);
  // A fixed number of plane chunks (not one per thread): the sums, and their order, do not
  // depend on the thread count.
  const int num_chunks = std::min(L, kSensitivityChunks);
  if (sensitivities) {
    chunk_sens_.resize(size_t(num_chunks));
    for (auto& acc : chunk_sens_) acc.assign(N, Eigen::Vector4d::Zero());
  }
  plane_counts_.assign(size_t(L), 0);
  plane_squares_.assign(size_t(L), 0.0);
  plane_self_.assign(size_t(L), 0.0);
  soa_.assign(rays);
  // The density per vote leaves out each vote's own weights (see Contrast): their squares, and
  // in the sensitivities their derivatives d|w|^2/du = (4 ax - 2) ((1-ay)^2 + ay^2) (v alike).
  const bool others_only = options_.contrast == Contrast::kDensityPerVote;
  pool_.run(num_chunks, [&](int c, int t) {
    float* g = scratch_[size_t(t)].data();
    const int l0 = L * c / num_chunks, l1 = L * (c + 1) / num_chunks;
    for (int l = l0; l < l1; ++l) {
      const float rho = float(rho_[l]);
      size_t n = 0;
      if (!sensitivities) {
        // The sum of squares is gathered while voting: adding w to a voxel that holds V adds
        // w (2 V + w) to sum V^2, of which w^2 is the vote's own (left out for the density per
        // vote: 2 w V, the pairs it makes with the votes before it, counted both ways).
        // Afterwards the plane only needs zeroing.
        const float own = others_only ? 0.0f : 1.0f;
        double q0 = 0.0, q1 = 0.0;
        forEachPlaneVoteBatched(rho, 0, soa_.size, [&](size_t, size_t idx, float ax, float ay) {
          float* c0 = g + idx;
          float* c1 = c0 + W;
          const float w00 = (1 - ax) * (1 - ay), w10 = ax * (1 - ay), w01 = (1 - ax) * ay,
                      w11 = ax * ay;
          const float v00 = c0[0], v10 = c0[1], v01 = c1[0], v11 = c1[1];
          q0 += double(w00 * (2 * v00 + own * w00) + w10 * (2 * v10 + own * w10));
          q1 += double(w01 * (2 * v01 + own * w01) + w11 * (2 * v11 + own * w11));
          c0[0] = v00 + w00, c0[1] = v10 + w10, c1[0] = v01 + w01, c1[1] = v11 + w11;
          ++n;
        });
        plane_counts_[size_t(l)] = n;
        plane_squares_[size_t(l)] = q0 + q1;  // without the own squares already
        zeroPlane(g, rho, n);
        continue;
      }
      forEachPlaneVoteBatched(rho, 0, soa_.size, [&](size_t, size_t idx, float ax, float ay) {
        addVote(g, idx, W, ax, ay);
        ++n;
      });
      plane_counts_[size_t(l)] = n;
      // d(sum_c V_c w_c)/du and /dv for the bilinear weights w_c(ax, ay). The mean of the
      // volume drops out: the weights' derivatives sum to zero. The same reads give the sum of
      // squares: sum_voxels V^2 = sum_votes sum_c w_c V_c (every V is the sum of its votes' w).
      Eigen::Vector4d* acc = chunk_sens_[size_t(c)].data();
      const double drho = rho_[l];
      double q = 0.0, self = 0.0;
      forEachPlaneVoteBatched(rho, 0, soa_.size, [&](size_t i, size_t idx, float ax, float ay) {
        const float v00 = g[idx], v10 = g[idx + 1], v01 = g[idx + W], v11 = g[idx + W + 1];
        const float top = v00 + (v10 - v00) * ax, bottom = v01 + (v11 - v01) * ax;
        q += double(top + (bottom - top) * ay);
        float gu = (v10 - v00) * (1 - ay) + (v11 - v01) * ay;
        float gv = (v01 - v00) * (1 - ax) + (v11 - v10) * ax;
        if (others_only) {
          const float sx = (1 - ax) * (1 - ax) + ax * ax, sy = (1 - ay) * (1 - ay) + ay * ay;
          self += double(sx * sy);
          gu -= (2 * ax - 1) * sy;
          gv -= (2 * ay - 1) * sx;
        }
        acc[i] += Eigen::Vector4d(gu, double(gu) * drho, gv, double(gv) * drho);
      });
      plane_squares_[size_t(l)] = q;
      plane_self_[size_t(l)] = self;
      zeroPlane(g, rho, n);
    }
  });
  size_t n = 0;
  double q = 0.0, self = 0.0;
  for (int l = 0; l < L; ++l) {
    n += plane_counts_[size_t(l)];
    q += plane_squares_[size_t(l)];
    self += plane_self_[size_t(l)];
  }
  if (votes) *votes = n;
  if (sensitivities) {
    // d(sum V^2) = 2 sum_votes grad V . du; sum V = n does not move (see the header).
    const double scale = options_.contrast == Contrast::kDensityPerVote
                             ? (n > 0 ? 2.0 / double(n) : 0.0)
                             : 2.0 / double(numVoxels());
    sensitivities->assign(N, Eigen::Vector4d::Zero());
    for (const auto& acc : chunk_sens_)
      for (size_t i = 0; i < N; ++i) (*sensitivities)[i] += acc[i];
    for (Eigen::Vector4d& s : *sensitivities) s *= scale;
  }
  return contrastOf(q, double(n), self);
}

void ProjectiveVolume::zeroPlane(float* plane, float rho, size_t votes) const {
  const size_t W = size_t(width_), plane_voxels = W * height_;
  if (kZeroSweepVotesPerVoxel * votes >= plane_voxels) {
    std::fill(plane, plane + plane_voxels, 0.0f);
    return;
  }
  forEachPlaneVoteBatched(rho, 0, soa_.size, [&](size_t, size_t idx, float, float) {
    plane[idx] = plane[idx + 1] = plane[idx + W] = plane[idx + W + 1] = 0.0f;
  });
}

void ProjectiveVolume::RayColumns::assign(const std::vector<VolumeRay>& rays) {
  size = rays.size();
  u0.resize(size), v0.resize(size), du.resize(size), dv.resize(size), rho_max.resize(size);
  for (size_t i = 0; i < size; ++i) {
    const VolumeRay& r = rays[i];
    u0[i] = r.u0, v0[i] = r.v0, du[i] = r.du, dv[i] = r.dv, rho_max[i] = r.rho_max;
  }
}

double ProjectiveVolume::takeSquares(float* plane, float rho, bool sweep) const {
  const size_t W = size_t(width_), plane_voxels = W * height_;
  if (sweep) {
    // Dense votes: one sweep over the plane.
    float q8[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    double q = 0.0;
    size_t i = 0;
    for (; i + 8 <= plane_voxels; i += 8)
      for (int k = 0; k < 8; ++k) q8[k] += plane[i + k] * plane[i + k];
    for (; i < plane_voxels; ++i) q += double(plane[i]) * plane[i];
    for (int k = 0; k < 8; ++k) q += q8[k];
    std::fill(plane, plane + plane_voxels, 0.0f);
    return q;
  }
  // Sparse votes: visit what they touched; a voxel met twice is zero the second time.
  double q0 = 0.0, q1 = 0.0;
  forEachPlaneVoteBatched(rho, 0, soa_.size, [&](size_t, size_t idx, float, float) {
    float* c0 = plane + idx;
    float* c1 = c0 + W;
    q0 += double(c0[0] * c0[0] + c0[1] * c0[1]);
    q1 += double(c1[0] * c1[0] + c1[1] * c1[1]);
    c0[0] = c0[1] = c1[0] = c1[1] = 0.0f;
  });
  return q0 + q1;
}

double ProjectiveVolume::clear(const std::vector<VolumeRay>& rays) {
  if (grid_.empty()) return 0.0;
  const int L = options_.num_planes;
  const size_t plane_voxels = size_t(width_) * height_;
  const bool dense = 4 * last_votes_ >= numVoxels();
  plane_squares_.assign(size_t(L), 0.0);
  if (!dense) soa_.assign(rays);
  pool_.run(L, [&](int l, int) {
    // Dense votes: every plane is swept; sparse: takeSquares() visits the votes.
    plane_squares_[size_t(l)] =
        takeSquares(grid_.data() + size_t(l) * plane_voxels, float(rho_[l]), dense);
  });
  double q = 0.0;
  for (double p : plane_squares_) q += p;
  const double c = contrastOf(q, sum_, self_);
  sum_ = 0.0;
  self_ = 0.0;
  last_votes_ = 0;
  return c;
}

}  // namespace vwe_vo
