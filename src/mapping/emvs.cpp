#include "vwe_vo/mapping/emvs.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "vwe_vo/sensor/subsample.h"
#include "vwe_vo/vwe/ray_builder.h"

namespace vwe_vo {

namespace {

bool finitePose(const Pose3& T) {
  return T.matrix().allFinite();
}

bool validPixel(const CameraModel& camera, const PixelEvent& e) {
  return camera.inside(e.x, e.y);
}

// Voxel hash key of integer cell coordinates (21 bits each, wrapping far outside +-1e6 cells).
uint64_t cellKey(int64_t ix, int64_t iy, int64_t iz) {
  const uint64_t m = (1ULL << 21) - 1;
  return (uint64_t(ix) & m) | ((uint64_t(iy) & m) << 21) | ((uint64_t(iz) & m) << 42);
}

// keep[i] = 1 if point i has at least min_neighbours others within radius_m.
std::vector<uint8_t> radiusInlierMask(const std::vector<MapPoint>& points, double radius_m,
                                      int min_neighbours) {
  std::vector<uint8_t> keep(points.size(), 1);
  if (radius_m <= 0.0 || min_neighbours <= 0 || points.empty()) return keep;
  const double inv = 1.0 / radius_m;
  const float r2 = float(radius_m * radius_m);
  std::unordered_map<uint64_t, std::vector<int>> cells;
  cells.reserve(points.size());
  std::vector<Eigen::Matrix<int64_t, 3, 1>> cell_of(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3f& p = points[i].p;
    cell_of[i] = {int64_t(std::floor(p.x() * inv)), int64_t(std::floor(p.y() * inv)),
                  int64_t(std::floor(p.z() * inv))};
    cells[cellKey(cell_of[i].x(), cell_of[i].y(), cell_of[i].z())].push_back(int(i));
  }
  for (size_t i = 0; i < points.size(); ++i) {
    int found = 0;
    for (int dz = -1; dz <= 1 && found < min_neighbours; ++dz)
      for (int dy = -1; dy <= 1 && found < min_neighbours; ++dy)
        for (int dx = -1; dx <= 1 && found < min_neighbours; ++dx) {
          const auto it =
              cells.find(cellKey(cell_of[i].x() + dx, cell_of[i].y() + dy, cell_of[i].z() + dz));
          if (it == cells.end()) continue;
          for (int j : it->second) {
            if (size_t(j) == i || (points[j].p - points[i].p).squaredNorm() > r2) continue;
            if (++found >= min_neighbours) break;
          }
        }
    keep[i] = found >= min_neighbours;
  }
  return keep;
}

// Median of the selected depths in a size x size window around each selected pixel.
cv::Mat maskedMedian(const cv::Mat& depth, const cv::Mat& mask, int size) {
  cv::Mat out = cv::Mat::zeros(depth.size(), CV_32F);
  const int h = size / 2;
  std::vector<float> values;
  values.reserve(size_t(size) * size);
  for (int y = 0; y < depth.rows; ++y)
    for (int x = 0; x < depth.cols; ++x) {
      if (!mask.at<uint8_t>(y, x)) continue;
      values.clear();
      for (int v = std::max(0, y - h); v <= std::min(depth.rows - 1, y + h); ++v) {
        const uint8_t* m = mask.ptr<uint8_t>(v);
        const float* d = depth.ptr<float>(v);
        for (int u = std::max(0, x - h); u <= std::min(depth.cols - 1, x + h); ++u)
          if (m[u]) values.push_back(d[u]);
      }
      auto mid = values.begin() + values.size() / 2;
      std::nth_element(values.begin(), mid, values.end());
      out.at<float>(y, x) = *mid;
    }
  return out;
}

}  // namespace

EmvsCounts& EmvsCounts::operator+=(const EmvsCounts& o) {
  events += o.events;
  voted += o.voted;
  skipped_time += o.skipped_time;
  skipped_nan += o.skipped_nan;
  skipped_behind += o.skipped_behind;
  skipped_outside += o.skipped_outside;
  votes += o.votes;
  selected += o.selected;
  outliers += o.outliers;
  points += o.points;
  return *this;
}

EmvsOptions::EmvsOptions() {
  volume.grid_scale = 1.0;
  volume.margin_px = 0;
  volume.num_planes = 40;
  volume.z_min_m = 0.5;
  volume.z_max_m = 8.0;
  volume.num_threads = 2;
}

void EmvsOptions::validate(const std::string& section) const {
  auto fail = [&](const std::string& m) { throw std::invalid_argument(section + "." + m); };
  volume.validate(section + ".volume");
  if (!(volume.z_max_m > volume.z_min_m))
    fail("volume.z_max_m must be larger than volume.z_min_m (a depth map needs finite depths)");
  if (adaptive_kernel_size < 3 || adaptive_kernel_size % 2 == 0 || adaptive_kernel_size > 101)
    fail("adaptive_kernel_size must be odd in [3, 101]");
  if (!(adaptive_sigma_px >= 0.0) || !std::isfinite(adaptive_sigma_px))
    fail("adaptive_sigma_px must be >= 0");
  if (!std::isfinite(adaptive_c)) fail("adaptive_c must be finite");
  if (!(min_confidence >= 0.0) || !std::isfinite(min_confidence))
    fail("min_confidence must be >= 0");
  if (median_filter_size < 1 || median_filter_size % 2 == 0 || median_filter_size > 31)
    fail("median_filter_size must be odd in [1, 31]");
  if (!(local_max_ratio >= 0.0 && local_max_ratio <= 1.0))
    fail("local_max_ratio must be in [0, 1]");
  if (local_max_window_px < 1 || local_max_window_px % 2 == 0 || local_max_window_px > 101)
    fail("local_max_window_px must be odd in [1, 101]");
  if (!(max_depth_m > 0.0)) fail("max_depth_m must be positive");
  if (!(outlier_radius_m >= 0.0) || !std::isfinite(outlier_radius_m))
    fail("outlier_radius_m must be >= 0");
  if (outlier_min_neighbours < 0 || outlier_min_neighbours > 1000)
    fail("outlier_min_neighbours must be in [0, 1000]");
  if (!(kf_distance_m > 0.0) || !std::isfinite(kf_distance_m))
    fail("kf_distance_m must be positive");
  if (!(kf_rotation_deg > 0.0) || !std::isfinite(kf_rotation_deg))
    fail("kf_rotation_deg must be positive");
  if (max_events_per_keyframe == 0) fail("max_events_per_keyframe must be positive");
  if (nms_radius_px < 0 || nms_radius_px > 10) fail("nms_radius_px must be in [0, 10]");
  if (nms_planes < 0) fail("nms_planes must be >= 0");
  if (!(min_ray_contrast >= 0.0) || !std::isfinite(min_ray_contrast))
    fail("min_ray_contrast must be >= 0 (0: off)");
  if (max_pending_events == 0) fail("max_pending_events must be positive");
  if (!(max_event_rate_hz >= 0 && std::isfinite(max_event_rate_hz)))
    fail("max_event_rate_hz must be >= 0 (0: vote every event)");
}

DepthExtraction extractDepth(const ProjectiveVolume& volume, const EmvsOptions& options) {
  const int W = volume.width(), H = volume.height(), L = volume.numPlanes();
  const size_t N = size_t(W) * H;
  DepthExtraction out;
  out.confidence = cv::Mat::zeros(H, W, CV_32F);
  out.depth_m = cv::Mat::zeros(H, W, CV_32F);
  out.mask = cv::Mat::zeros(H, W, CV_8U);
  float* conf = out.confidence.ptr<float>();
  std::vector<uint16_t> arg(N, 0);
  std::vector<float> ray_sum(options.min_ray_contrast > 0.0 ? N : 0, 0.0f);
  const float* grid = volume.data().data();
  // Plane by plane: contiguous reads of the plane-major grid.
  for (int l = 0; l < L; ++l) {
    const float* plane = grid + size_t(l) * N;
    for (size_t i = 0; i < N; ++i) {
      if (plane[i] > conf[i]) {
        conf[i] = plane[i];
        arg[i] = uint16_t(l);
      }
    }
    if (!ray_sum.empty())
      for (size_t i = 0; i < N; ++i) ray_sum[i] += plane[i];
  }
  double max_conf = 0.0;
  cv::minMaxLoc(out.confidence, nullptr, &max_conf);
  if (!(max_conf > 0.0)) return out;

  // Adaptive Gaussian threshold on the confidence scaled to [0, 255] (EMVS, without 8-bit
  // rounding).
  cv::Mat scaled = out.confidence * (255.0 / max_conf), local_mean;
  const int k = options.adaptive_kernel_size;
  cv::GaussianBlur(scaled, local_mean, cv::Size(k, k), options.adaptive_sigma_px,
                   options.adaptive_sigma_px, cv::BORDER_REPLICATE);
  // Peak over mean along each pixel's depth ray: a pixel whose rays meet at one depth peaks
  // sharply, one crossed by the rays of others (or near the focus of expansion, where a ray
  // stays on its pixel at every depth) has a flat profile.
  const float ray_contrast = float(options.min_ray_contrast) / float(L);
  cv::Mat depth = cv::Mat::zeros(H, W, CV_32F);
  float* d = depth.ptr<float>();
  uint8_t* m = out.mask.ptr<uint8_t>();
  const float* s = scaled.ptr<float>();
  const float* mean = local_mean.ptr<float>();
  const float c = float(options.adaptive_c), min_conf = float(options.min_confidence);
  const float local_ratio = float(options.local_max_ratio);
  cv::Mat local_max_map;
  if (local_ratio > 0.0f) {
    const int w = options.local_max_window_px;
    cv::dilate(out.confidence, local_max_map,
               cv::getStructuringElement(cv::MORPH_RECT, cv::Size(w, w)));
  }
  const float* local_max = local_ratio > 0.0f ? local_max_map.ptr<float>() : nullptr;
  const int r = options.nms_radius_px;
  const int dl = options.nms_planes > 0 ? options.nms_planes : L;
  const double step = volume.planeInverseDepth(1) - volume.planeInverseDepth(0);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const size_t i = size_t(y) * W + x;
      if (!(conf[i] > 0.0f && conf[i] >= min_conf && s[i] > mean[i] + c)) continue;
      if (local_max && conf[i] < local_ratio * local_max[i]) continue;
      if (!ray_sum.empty() && conf[i] < ray_contrast * ray_sum[i]) continue;
      const int l = arg[i];
      // Non-maximum suppression in the DSI, jointly in image position and depth: the pixels
      // beside a point, whose rays cross the point's rays (the streaks in the confidence map),
      // peak lower than the point's voxel at a nearby depth and are rejected. Ties keep the
      // first pixel in scan order.
      bool is_max = true;
      for (int v = std::max(0, y - r); v <= std::min(H - 1, y + r) && is_max; ++v)
        for (int u = std::max(0, x - r); u <= std::min(W - 1, x + r) && is_max; ++u) {
          if (u == x && v == y) continue;
          const size_t j = size_t(v) * W + u;
          if (std::abs(int(arg[j]) - l) <= dl) {
            if (conf[j] > conf[i] || (conf[j] == conf[i] && j < i)) is_max = false;
            continue;
          }
          for (int q = std::max(0, l - dl); q <= std::min(L - 1, l + dl); ++q) {
            const float g = grid[size_t(q) * N + j];
            if (g > conf[i] || (g == conf[i] && j < i)) {
              is_max = false;
              break;
            }
          }
        }
      if (!is_max) continue;
      double rho = volume.planeInverseDepth(l);
      if (options.subpixel && l > 0 && l < L - 1) {
        // The depth profile of a focused pixel is a cusp, not a parabola: the centroid of the
        // peak above its lower neighbour, in plane units (planes are uniform in inverse depth).
        const double a = grid[size_t(l - 1) * N + i], b = conf[i], cc = grid[size_t(l + 1) * N + i];
        const double base = std::min(a, cc);
        const double den = (a - base) + (b - base) + (cc - base);
        const double delta = den > 0.0 ? std::max(-0.5, std::min(0.5, (cc - a) / den)) : 0.0;
        rho += delta * step;
      }
      d[i] = float(1.0 / rho);
      m[i] = 1;
      ++out.selected;
    }
  out.depth_m = options.median_filter_size > 1
                    ? maskedMedian(depth, out.mask, options.median_filter_size)
                    : depth;
  return out;
}

void extractKeyframe(const ProjectiveVolume& volume, const EmvsOptions& options,
                     const Pose3& T_odom_cam, EmvsKeyframe* kf) {
  DepthExtraction ex = extractDepth(volume, options);
  kf->T_odom_cam = T_odom_cam;
  kf->confidence = ex.confidence;
  kf->counts.selected = ex.selected;
  std::vector<MapPoint> points;
  std::vector<int> pixel;
  const double fx = volume.fx(), fy = volume.fy(), cx = volume.cx(), cy = volume.cy();
  for (int y = 0; y < ex.depth_m.rows; ++y)
    for (int x = 0; x < ex.depth_m.cols; ++x) {
      float& z = ex.depth_m.at<float>(y, x);
      if (!(z > 0.0f)) continue;
      if (z > options.max_depth_m) {
        z = 0.0f;
        continue;
      }
      MapPoint p;
      p.p = Eigen::Vector3f(float((x - cx) / fx) * z, float((y - cy) / fy) * z, z);
      p.confidence = ex.confidence.at<float>(y, x);
      points.push_back(p);
      pixel.push_back(y * ex.depth_m.cols + x);
    }
  const std::vector<uint8_t> keep =
      radiusInlierMask(points, options.outlier_radius_m, options.outlier_min_neighbours);
  kf->points_cam.clear();
  kf->points_odom.clear();
  const Eigen::Isometry3f T = T_odom_cam.cast<float>();
  float* depth = ex.depth_m.ptr<float>();
  for (size_t i = 0; i < points.size(); ++i) {
    if (!keep[i]) {
      depth[pixel[i]] = 0.0f;  // the depth map shows what the cloud holds
      ++kf->counts.outliers;
      continue;
    }
    kf->points_cam.push_back(points[i]);
    MapPoint q = points[i];
    q.p = T * points[i].p;
    kf->points_odom.push_back(q);
  }
  kf->depth_m = ex.depth_m;
  kf->counts.points = kf->points_cam.size();
}

size_t removeRadiusOutliers(std::vector<MapPoint>* points, double radius_m, int min_neighbours) {
  const std::vector<uint8_t> keep = radiusInlierMask(*points, radius_m, min_neighbours);
  size_t n = 0;
  for (size_t i = 0; i < points->size(); ++i)
    if (keep[i]) (*points)[n++] = (*points)[i];
  const size_t removed = points->size() - n;
  points->resize(n);
  return removed;
}

// ---------------------------------------------------------------------------------------------
// EmvsMapper

EmvsMapper::EmvsMapper(const EmvsOptions& options, const CameraModel& camera)
    : options_(options), camera_(camera), pool_(options.volume.num_threads) {
  options_.validate();
  const CameraCalibration& c = camera.calibration();
  volume_ = std::make_unique<ProjectiveVolume>(options_.volume, c.width, c.height, c.fx, c.fy, c.cx,
                                               c.cy);
}

void EmvsMapper::addEvents(const EventVector& events) {
  for (const PixelEvent& e : events) {
    const int64_t newest =
        !pending_.empty() ? pending_.back().t_ns : (active_ ? t_last_ns_ : INT64_MIN);
    if (e.t_ns < newest) {
      ++dropped_out_of_order_;
      continue;
    }
    if (options_.max_event_rate_hz > 0 && !options_.rate_limit_whole_keyframes) {
      const double burst = std::max(1.0, 0.01 * options_.max_event_rate_hz);
      tokens_ = t_tokens_ns_ == INT64_MIN
                    ? 1.0
                    : std::min(burst, tokens_ + nsToSec(e.t_ns - t_tokens_ns_) *
                                                    options_.max_event_rate_hz);
      t_tokens_ns_ = e.t_ns;
      if (tokens_ < 1.0) {
        ++thinned_;
        continue;
      }
      tokens_ -= 1.0;
    }
    pending_.push_back(e);
  }
  while (pending_.size() > options_.max_pending_events) {
    // The trajectory lags (a busy back-end): every second event waiting goes, evenly in time, so
    // the keyframes it reaches later keep their whole time span at half the density (memory
    // stays bounded, no keyframe loses its start).
    thinned_pending_ += keepEverySecond(&pending_);
  }
}

void EmvsMapper::startKeyframe(int64_t t_ns, const Pose3& T_odom_cam) {
  active_ = true;
  t_kf_ns_ = t_last_ns_ = t_ns;
  T_kf_odom_ = T_odom_cam.inverse();
  kf_events_.clear();
  kf_slices_.clear();
}

void EmvsMapper::addToKeyframe(const PixelEvent& e, int64_t t_pose_ns, const Pose3& T_odom_cam) {
  if (kf_slices_.empty() || kf_slices_.back().t_ns != t_pose_ns)
    kf_slices_.push_back({t_pose_ns, T_odom_cam});
  kf_events_.push_back({e.x, e.y, uint32_t(kf_slices_.size() - 1)});
  ++counts_.events;
  t_last_ns_ = e.t_ns;
}

bool EmvsMapper::closeKeyframe(EmvsKeyframe* kf) {
  if (options_.max_event_rate_hz > 0 && options_.rate_limit_whole_keyframes) {
    // The budget grows with data time, up to one second's worth (the first keyframe always
    // passes); a keyframe is voted while the budget is not in debt, and spends all its events.
    const double rate = options_.max_event_rate_hz;
    tokens_ = t_tokens_ns_ == INT64_MIN
                  ? rate
                  : std::min(rate, tokens_ + nsToSec(t_last_ns_ - t_tokens_ns_) * rate);
    t_tokens_ns_ = t_last_ns_;
    if (tokens_ < 0.0) {
      thinned_ += kf_events_.size();
      ++keyframes_skipped_;
      dropKeyframe();
      return false;
    }
    tokens_ -= double(kf_events_.size());
  }
  volume_->clear(rays_);
  kf->t_begin_ns = t_kf_ns_;
  kf->t_end_ns = t_last_ns_;
  // Reference view at the median event.
  const PoseSlice& ref = kf_slices_.empty() ? PoseSlice{t_kf_ns_, T_kf_odom_.inverse()}
                                            : kf_slices_[kf_events_[kf_events_.size() / 2].slice];
  const Pose3 T_odom_ref = ref.T_odom_cam, T_ref_odom = ref.T_odom_cam.inverse();
  std::vector<RayPose<float>> poses(kf_slices_.size());
  for (size_t k = 0; k < kf_slices_.size(); ++k) {
    const Pose3 T_ref_cam = T_ref_odom * kf_slices_[k].T_odom_cam;
    poses[k] =
        RayPose<float>(T_ref_cam.linear().cast<float>(), T_ref_cam.translation().cast<float>(),
                       options_.per_camera_min_depth ? float(options_.volume.z_min_m) : 0.0f);
  }
  // Rays in float, split over the threads; a ray pointing away from the reference view is
  // marked with a NaN and dropped below.
  const size_t n = kf_events_.size();
  rays_.resize(n);
  const VolumeRayBuilder<float> make_ray(*volume_);
  const int chunks = 4 * pool_.numThreads();
  pool_.run(chunks, [&](int chunk, int) {
    const size_t begin = n * size_t(chunk) / size_t(chunks),
                 end = n * size_t(chunk + 1) / size_t(chunks);
    for (size_t i = begin; i < end; ++i) {
      const KeyframeEvent& e = kf_events_[i];
      if (!make_ray(poses[e.slice], camera_.bearing(e.x, e.y), &rays_[i]))
        rays_[i].u0 = std::numeric_limits<float>::quiet_NaN();
    }
  });
  size_t kept = 0;
  for (size_t i = 0; i < n; ++i)
    if (!std::isnan(rays_[i].u0)) rays_[kept++] = rays_[i];
  rays_.resize(kept);
  counts_.skipped_behind += n - kept;
  counts_.voted += kept;
  counts_.votes += volume_->vote(rays_, false);  // a DSI: no contrast
  kf->t_kf_ns = ref.t_ns;
  kf->counts = counts_;
  extractKeyframe(*volume_, options_, T_odom_ref, kf);
  dropKeyframe();
  ++num_keyframes_;
  return true;
}

std::vector<EmvsKeyframe> EmvsMapper::process(const PoseFunction& T_odom_cam, int64_t t_final_ns) {
  std::vector<EmvsKeyframe> done;
  std::vector<Pose3> poses;
  std::vector<uint8_t> status;  // 0 ok, 1 not covered, 2 not finite
  const int64_t slice_ns = secToNs(options_.volume.pose_slice_s);
  while (!pending_.empty() && pending_.front().t_ns <= t_final_ns) {
    // The events of one pose slice (poseSliceTime, the VWE's rule) share the pose at its middle;
    // where the trajectory does not cover the middle, each event uses its own pose. Coverage
    // is judged per event unless the trajectory covers both ends of the slice's events.
    const int64_t t_slice = poseSliceTime(pending_.front().t_ns, slice_ns);
    size_t n = 0;
    while (n < pending_.size() && pending_[n].t_ns <= t_final_ns &&
           poseSliceTime(pending_[n].t_ns, slice_ns) == t_slice)
      ++n;
    const int64_t t_a = pending_.front().t_ns, t_b = pending_[n - 1].t_ns;
    Pose3 T_a, T_b, T_slice = Pose3::Identity();
    const bool middle = T_odom_cam(t_slice, &T_slice) && finitePose(T_slice);
    const bool covered = middle && T_odom_cam(t_a, &T_a) && T_odom_cam(t_b, &T_b) &&
                         finitePose(T_a) && finitePose(T_b);
    if (!covered) {
      poses.assign(n, Pose3::Identity());
      status.assign(n, 0);
      for (size_t i = 0; i < n; ++i) {
        if (!T_odom_cam(pending_[i].t_ns, &poses[i]))
          status[i] = 1;
        else if (!finitePose(poses[i]))
          status[i] = 2;
      }
    }
    bool checked = false;  // keyframe criteria judged for the slice's pose
    for (size_t i = 0; i < n; ++i) {
      const PixelEvent& e = pending_[i];
      if (!validPixel(camera_, e)) {
        ++counts_.events;
        ++counts_.skipped_outside;
        continue;
      }
      if (!covered && status[i] != 0) {
        ++counts_.events;
        ++(status[i] == 1 ? counts_.skipped_time : counts_.skipped_nan);
        continue;
      }
      const Pose3& T_odom_cam_i = middle ? T_slice : poses[i];
      if (!middle || !checked) {
        if (active_) {
          const Pose3 T_kf_cam = T_kf_odom_ * T_odom_cam_i;
          const bool moved = T_kf_cam.translation().norm() > options_.kf_distance_m;
          const bool turned =
              rotationAngle(T_kf_cam.linear()) * kDegPerRad > options_.kf_rotation_deg;
          if (moved || turned) {
            EmvsKeyframe kf;
            if (closeKeyframe(&kf)) done.push_back(std::move(kf));
          }
        }
        if (!active_) startKeyframe(e.t_ns, T_odom_cam_i);
        checked = true;
      }
      if (kf_events_.size() >= options_.max_events_per_keyframe) {
        EmvsKeyframe kf;
        if (closeKeyframe(&kf)) done.push_back(std::move(kf));
        startKeyframe(e.t_ns, T_odom_cam_i);
      }
      addToKeyframe(e, middle ? t_slice : e.t_ns, T_odom_cam_i);
    }
    pending_.erase(pending_.begin(), pending_.begin() + long(n));
  }
  return done;
}

bool EmvsMapper::finish(EmvsKeyframe* keyframe) {
  if (!active_) return false;
  return closeKeyframe(keyframe);
}

void EmvsMapper::reset() {
  pending_.clear();
  tokens_ = 0.0;
  t_tokens_ns_ = INT64_MIN;
  dropKeyframe();
}

void EmvsMapper::dropKeyframe() {
  kf_events_.clear();
  kf_slices_.clear();
  counts_ = EmvsCounts();
  active_ = false;
}

// ---------------------------------------------------------------------------------------------
// GlobalMap

void GlobalMapOptions::validate(const std::string& section) const {
  if (!(voxel_size_m > 0.0) || !std::isfinite(voxel_size_m))
    throw std::invalid_argument(section + ".voxel_size_m must be positive");
  if (max_points == 0) throw std::invalid_argument(section + ".max_points must be positive");
}

GlobalMap::GlobalMap(const GlobalMapOptions& options) : options_(options) {
  options_.validate();
}

void GlobalMap::insert(const std::vector<MapPoint>& points_odom) {
  ++inserts_;
  const double inv = 1.0 / options_.voxel_size_m;
  for (const MapPoint& p : points_odom) {
    if (!p.p.allFinite()) continue;
    const Eigen::Vector3d q = p.p.cast<double>();
    Voxel& v = voxels_[cellKey(int64_t(std::floor(q.x() * inv)), int64_t(std::floor(q.y() * inv)),
                               int64_t(std::floor(q.z() * inv)))];
    v.sum += q;
    v.confidence_sum += p.confidence;
    ++v.count;
    v.last_insert = inserts_;
  }
  if (voxels_.size() <= options_.max_points) return;
  struct Rank {
    uint64_t last_insert;
    uint32_t count;
    uint64_t key;
  };
  std::vector<Rank> ranks;
  ranks.reserve(voxels_.size());
  for (const auto& kv : voxels_)
    ranks.push_back({kv.second.last_insert, kv.second.count, kv.first});
  const size_t excess = voxels_.size() - options_.max_points;
  std::nth_element(ranks.begin(), ranks.begin() + long(excess - 1), ranks.end(),
                   [](const Rank& a, const Rank& b) {
                     return a.last_insert != b.last_insert
                                ? a.last_insert < b.last_insert
                                : (a.count != b.count ? a.count < b.count : a.key < b.key);
                   });
  for (size_t i = 0; i < excess; ++i) voxels_.erase(ranks[i].key);
  dropped_ += excess;
}

std::vector<MapPoint> GlobalMap::points() const {
  std::vector<MapPoint> out;
  out.reserve(voxels_.size());
  for (const auto& kv : voxels_) {
    MapPoint p;
    p.p = (kv.second.sum / kv.second.count).cast<float>();
    p.confidence = float(kv.second.confidence_sum / kv.second.count);
    out.push_back(p);
  }
  return out;
}

void GlobalMap::clear() {
  voxels_.clear();
  inserts_ = 0;
}

cv::Mat colorizeDepth(const cv::Mat& depth_m, double z_min_m, double z_max_m) {
  cv::Mat scaled(depth_m.size(), CV_8U, cv::Scalar(0)), out;
  const double rho_near = 1.0 / z_min_m, rho_far = 1.0 / z_max_m;
  for (int y = 0; y < depth_m.rows; ++y)
    for (int x = 0; x < depth_m.cols; ++x) {
      const float z = depth_m.at<float>(y, x);
      if (!(z > 0.0f)) continue;
      const double a = (1.0 / z - rho_far) / (rho_near - rho_far);
      scaled.at<uint8_t>(y, x) = uint8_t(std::lround(255.0 * std::max(0.0, std::min(1.0, a))));
    }
  cv::applyColorMap(scaled, out, cv::COLORMAP_JET);
  out.setTo(cv::Scalar(0, 0, 0), depth_m <= 0.0f);
  return out;
}

}  // namespace vwe_vo
