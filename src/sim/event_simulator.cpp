#include "vwe_vo/sim/event_simulator.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>

namespace vwe_vo {
namespace sim {

namespace {
// Natural log of a positive normal float to ~1e-7 relative, branch-free and inlinable (the
// per-pixel log was ~8 % of the simulator's time as a libm call): x = m 2^e with m in
// [sqrt(1/2), sqrt(2)), log m = 2 atanh(s), s = (m - 1) / (m + 1), |s| < 0.172.
inline float fastLog(float x) {
  uint32_t bits;
  std::memcpy(&bits, &x, sizeof(bits));
  // Subtracting the bits of sqrt(1/2) moves the exponent boundary so m lands in [sqrt(1/2),
  // sqrt(2)).
  const uint32_t shifted = bits - 0x3f3504f3u;
  const int e = static_cast<int32_t>(shifted) >> 23;
  const uint32_t mbits = bits - (static_cast<uint32_t>(e) << 23);
  float m;
  std::memcpy(&m, &mbits, sizeof(m));
  const float s = (m - 1.0f) / (m + 1.0f), s2 = s * s;
  const float log_m =
      2.0f * s * (1.0f + s2 * (1.0f / 3 + s2 * (1.0f / 5 + s2 * (1.0f / 7 + s2 * (1.0f / 9)))));
  return static_cast<float>(e) * 0.69314718f + log_m;
}

// fastLog on 4 floats (GCC / Clang vector extensions), with the same operations in the same
// order: results are bit-identical to the scalar version.
typedef float Vf4 __attribute__((vector_size(16)));
typedef int32_t Vi4 __attribute__((vector_size(16)));
typedef uint32_t Vu4 __attribute__((vector_size(16)));
inline Vf4 fastLog4(Vf4 x) {
  const Vu4 bits = (Vu4)x;
  const Vi4 e = (Vi4)(bits - 0x3f3504f3u) >> 23;
  const Vf4 m = (Vf4)(bits - ((Vu4)e << 23));
  const Vf4 s = (m - 1.0f) / (m + 1.0f), s2 = s * s;
  const Vf4 log_m =
      2.0f * s * (1.0f + s2 * (1.0f / 3 + s2 * (1.0f / 5 + s2 * (1.0f / 7 + s2 * (1.0f / 9)))));
  return __builtin_convertvector(e, Vf4) * 0.69314718f + log_m;
}
}  // namespace

void EventSimulatorOptions::validate() const {
  auto need = [](bool ok, const char* field, const char* what) {
    if (!ok)
      throw std::invalid_argument(std::string("EventSimulatorOptions.") + field + " " + what);
  };
  need(contrast_threshold > 0.01 && contrast_threshold < 5, "contrast_threshold",
       "must be in (0.01, 5)");
  need(threshold_sigma >= 0 && threshold_sigma < contrast_threshold, "threshold_sigma",
       "must be in [0, contrast_threshold)");
  need(min_threshold > 0 && min_threshold <= contrast_threshold, "min_threshold",
       "must be in (0, contrast_threshold]");
  need(refractory_s >= 0 && refractory_s < 1, "refractory_s", "must be in [0, 1)");
  need(noise_rate_hz >= 0 && noise_rate_hz < 1e4, "noise_rate_hz", "must be in [0, 1e4)");
  need(num_hot_pixels >= 0 && num_hot_pixels < 100000, "num_hot_pixels", "must be in [0, 1e5)");
  need(hot_pixel_rate_hz >= 0 && hot_pixel_rate_hz < 1e5, "hot_pixel_rate_hz",
       "must be in [0, 1e5)");
  need(log_eps > 0 && log_eps < 1, "log_eps", "must be in (0, 1)");
  need(supersampling >= 1 && supersampling <= 4, "supersampling", "must be in [1, 4]");
  need(max_pixel_motion_px > 0.01 && max_pixel_motion_px <= 10, "max_pixel_motion_px",
       "must be in (0.01, 10]");
  need(max_log_step > 0 && max_log_step <= 1, "max_log_step", "must be in (0, 1]");
  need(min_render_step_s >= 1e-6 && min_render_step_s <= max_render_step_s, "min_render_step_s",
       "must be in [1e-6, max_render_step_s]");
  need(max_render_step_s <= 0.1, "max_render_step_s", "must be <= 0.1");
  need(illumination_low > 0 && illumination_low <= 1, "illumination_low", "must be in (0, 1]");
  need(illumination_period_s > 0, "illumination_period_s", "must be > 0");
  need(illumination_ramp_s > 0 && illumination_ramp_s < illumination_period_s,
       "illumination_ramp_s", "must be in (0, illumination_period_s)");
  need(dark_noise_rate_hz >= 0 && dark_noise_rate_hz < 1e4, "dark_noise_rate_hz",
       "must be in [0, 1e4)");
  need(num_threads >= 1 && num_threads <= 64, "num_threads", "must be in [1, 64]");
}

EventSimulator::EventSimulator(const Scene& scene, const CameraModel& camera,
                               const Pose3& T_base_cam, const VehicleTrajectory& trajectory,
                               const EventSimulatorOptions& options)
    : camera_(camera),
      scene_(scene),
      T_base_cam_(T_base_cam),
      trajectory_(trajectory),
      options_(options),
      noise_rng_(options.seed * 0x2545F4914F6CDD1DULL + 99) {
  options_.validate();
  renderer_ = std::make_unique<SceneRenderer>(scene_, camera_, options_.supersampling);
  depth_renderer_ = std::make_unique<SceneRenderer>(scene_, camera_, 1);
  pool_ = std::make_unique<ThreadPool>(options_.num_threads);
  width_ = camera_.width();
  height_ = camera_.height();
  const size_t n = static_cast<size_t>(width_) * height_;
  intensity_.resize(n);
  depth_.resize(n);
  log_prev_.resize(n);
  log_ref_.resize(n);
  c_on_.resize(n);
  c_off_.resize(n);
  last_event_ns_.assign(n, std::numeric_limits<int64_t>::min() / 2);
  // Threshold mismatch: fixed per pixel from the seed.
  std::mt19937_64 rng(options_.seed);
  std::normal_distribution<double> c(options_.contrast_threshold, options_.threshold_sigma);
  for (size_t i = 0; i < n; ++i) {
    c_on_[i] = static_cast<float>(std::max(options_.min_threshold, c(rng)));
    c_off_[i] = static_cast<float>(std::max(options_.min_threshold, c(rng)));
  }
  std::uniform_int_distribution<int> pix(0, static_cast<int>(n) - 1);
  for (int i = 0; i < options_.num_hot_pixels; ++i) hot_pixels_.push_back(pix(rng));
  // Initial render: the reference of every pixel is its log intensity at t = 0.
  renderer_->render(T_odom_cam(0), intensity_.data(), depth_.data(), pool_.get());
  const float log_illum = static_cast<float>(std::log(illumination(0)));
  for (size_t i = 0; i < n; ++i) {
    log_prev_[i] =
        fastLog(std::exp(log_illum) * intensity_[i] + static_cast<float>(options_.log_eps));
    log_ref_[i] = log_prev_[i];
  }
  if (options_.supersampling > 1)
    depth_renderer_->render(T_odom_cam(0), nullptr, depth_.data(), pool_.get());
  stats_.renders = 1;
  tiles_x_ = renderer_->numTileCols();
  tiles_y_ = renderer_->numTileRows();
  stats_.tile_renders = static_cast<uint64_t>(tiles_x_) * tiles_y_;
  tile_allowed_ns_.assign(stats_.tile_renders, 0);
  tile_t_ns_.assign(stats_.tile_renders, 0);
  tile_due_.assign(stats_.tile_renders, 0);
  thread_events_.resize(pool_->numThreads());
  thread_drops_.resize(pool_->numThreads());
}

EventSimulator::~EventSimulator() = default;

double EventSimulator::illumination(int64_t t_ns) const {
  if (options_.illumination == IlluminationMode::kConstant) return 1.0;
  const double P = options_.illumination_period_s, R = options_.illumination_ramp_s;
  const double phase = std::fmod(std::max(0.0, nsToSec(t_ns)), 2.0 * P);
  // Fraction of the way to dark (0 bright, 1 dark), ramps at the end of each half period.
  double dark;
  if (phase < P - R)
    dark = 0.0;
  else if (phase < P)
    dark = (phase - (P - R)) / R;
  else if (phase < 2 * P - R)
    dark = 1.0;
  else
    dark = 1.0 - (phase - (2 * P - R)) / R;
  dark = dark * dark * (3.0 - 2.0 * dark);
  // Exponential ramp: log illumination changes smoothly and at a bounded rate.
  return std::exp(dark * std::log(options_.illumination_low));
}

double EventSimulator::noiseRate(int64_t t_ns) const {
  double rate = options_.noise_rate_hz;
  if (options_.illumination == IlluminationMode::kToggle && options_.illumination_low < 1.0) {
    const double darkness = (1.0 - illumination(t_ns)) / (1.0 - options_.illumination_low);
    rate += options_.dark_noise_rate_hz * std::clamp(darkness, 0.0, 1.0);
  }
  return rate;
}

int64_t EventSimulator::planStep(int64_t t_ns) {
  // Camera twist from a 1 ms finite difference of the true pose (includes any vibration).
  const int64_t h_ns = 1000000;
  const Pose3 T_c0_c1 = T_odom_cam(t_ns).inverse() * T_odom_cam(t_ns + h_ns);
  const double h = nsToSec(h_ns);
  const Eigen::AngleAxisd aa(T_c0_c1.linear());
  const Eigen::Vector3f w = (aa.axis() * aa.angle() / h).cast<float>();
  const Eigen::Vector3f v = (T_c0_c1.translation() / h).cast<float>();
  const float px_per_rad =
      static_cast<float>(std::max(camera_.calibration().fx, camera_.calibration().fy));
  // Per tile, the max over a grid of its pixels of the bearing's angular speed, in pixels.
  const int tile = SceneRenderer::kTile;
  std::vector<float> own(tile_allowed_ns_.size(), 0.f);
  for (int y = 4; y < height_; y += 8)
    for (int x = 4; x < width_; x += 8) {
      const Eigen::Vector3f& f = camera_.bearing(x, y);
      const float z = depth_[static_cast<size_t>(y) * width_ + x];
      Eigen::Vector3f dP = -w.cross(f);
      if (z > 0) dP -= v * (f.z() / z);  // v / range, range = z / f.z
      const Eigen::Vector3f df = dP - f * f.dot(dP);
      float& r = own[(y / tile) * tiles_x_ + x / tile];
      r = std::max(r, df.norm() / f.z() * px_per_rad);
    }
  log_rate_ = 0.0;
  if (options_.illumination != IlluminationMode::kConstant)
    log_rate_ = std::abs(std::log(illumination(t_ns + h_ns)) - std::log(illumination(t_ns))) / h;
  // A tile also takes its neighbours' motion: a nearer object may move in from next door.
  int64_t min_allowed_ns = std::numeric_limits<int64_t>::max();
  for (int ty = 0; ty < tiles_y_; ++ty)
    for (int tx = 0; tx < tiles_x_; ++tx) {
      float r = 0.f;
      for (int j = std::max(0, ty - 1); j <= std::min(tiles_y_ - 1, ty + 1); ++j)
        for (int i = std::max(0, tx - 1); i <= std::min(tiles_x_ - 1, tx + 1); ++i)
          r = std::max(r, own[j * tiles_x_ + i]);
      double allowed_s = options_.max_render_step_s;
      if (r > 0) allowed_s = std::min(allowed_s, options_.max_pixel_motion_px / r);
      if (log_rate_ > 0) allowed_s = std::min(allowed_s, options_.max_log_step / log_rate_);
      const int64_t allowed_ns = std::max(secToNs(options_.min_render_step_s), secToNs(allowed_s));
      tile_allowed_ns_[ty * tiles_x_ + tx] = allowed_ns;
      min_allowed_ns = std::min(min_allowed_ns, allowed_ns);
    }
  return std::max(secToNs(options_.min_render_step_s), min_allowed_ns / kRenderSubsteps);
}

void EventSimulator::processTileRow(int r, int thread, int64_t t1_ns, float log_illum1) {
  EventVector& ev = thread_events_[thread];
  uint64_t drops = 0;
  const float illum1 = std::exp(log_illum1);
  const float eps = static_cast<float>(options_.log_eps);
  const int64_t refractory_ns = secToNs(options_.refractory_s);
  const int tile = SceneRenderer::kTile;
  for (int tx = 0; tx < tiles_x_; ++tx) {
    const int k = r * tiles_x_ + tx;
    if (!tile_due_[k]) continue;
    const int64_t t0_ns = tile_t_ns_[k];
    tile_t_ns_[k] = t1_ns;
    const double span = static_cast<double>(t1_ns - t0_ns);
    renderer_->renderTile(tx, r, intensity_.data(),
                          options_.supersampling > 1 ? nullptr : depth_.data());
    if (options_.supersampling > 1) depth_renderer_->renderTile(tx, r, nullptr, depth_.data());
    const int x0 = tx * tile;
    const int y1 = std::min(height_, (r + 1) * tile), x1 = std::min(width_, x0 + tile);
    for (int y = r * tile; y < y1; ++y) {
      // New log intensity of the tile's pixels in this row, 4 at a time.
      Vf4 lin[SceneRenderer::kTile / 4] = {}, L1v[SceneRenderer::kTile / 4];
      const size_t p0 = static_cast<size_t>(y) * width_ + x0;
      std::memcpy(lin, intensity_.data() + p0, sizeof(float) * (x1 - x0));
      for (int i = 0; i < (x1 - x0 + 3) / 4; ++i) L1v[i] = fastLog4(illum1 * lin[i] + eps);
      for (int x = x0; x < x1; ++x) {
        const size_t p = p0 + (x - x0);
        const float L0 = log_prev_[p];
        const float L1 = L1v[(x - x0) / 4][(x - x0) % 4];
        log_prev_[p] = L1;
        float ref = log_ref_[p];
        // The reference stays within (L - C_off, L + C_on) of the last log intensity, so a pixel
        // within both thresholds now has no crossing in either direction.
        if (L1 - ref < c_on_[p] && ref - L1 < c_off_[p]) continue;
        const float dL = L1 - L0;
        if (dL > 0.f) {
          const float C = c_on_[p];
          while (L1 - ref >= C) {
            ref += C;
            const double a = std::clamp(static_cast<double>((ref - L0) / dL), 0.0, 1.0);
            const int64_t te = t0_ns + static_cast<int64_t>(a * span + 0.5);
            if (te - last_event_ns_[p] >= refractory_ns) {
              ev.push_back(PixelEvent{te, static_cast<uint16_t>(x), static_cast<uint16_t>(y), 1});
              last_event_ns_[p] = te;
            } else {
              ++drops;
            }
          }
        } else if (dL < 0.f) {
          const float C = c_off_[p];
          while (ref - L1 >= C) {
            ref -= C;
            const double a = std::clamp(static_cast<double>((ref - L0) / dL), 0.0, 1.0);
            const int64_t te = t0_ns + static_cast<int64_t>(a * span + 0.5);
            if (te - last_event_ns_[p] >= refractory_ns) {
              ev.push_back(PixelEvent{te, static_cast<uint16_t>(x), static_cast<uint16_t>(y), -1});
              last_event_ns_[p] = te;
            } else {
              ++drops;
            }
          }
        }
        log_ref_[p] = ref;
      }
    }
  }
  thread_drops_[thread] += drops;
}

void EventSimulator::step(int64_t t0_ns, int64_t t1_ns, int64_t next_step_ns, bool flush,
                          EventVector* out) {
  // A tile skipped now is next rendered one step later: render it now if by then it would be
  // past its deadline (moved more than max_pixel_motion_px, or seen too large an illumination
  // change, since its last render).
  int due_rows = 0;
  for (int ty = 0; ty < tiles_y_; ++ty) {
    bool row_due = false;
    for (int tx = 0; tx < tiles_x_; ++tx) {
      const int k = ty * tiles_x_ + tx;
      const bool due = flush || t1_ns + next_step_ns > tile_t_ns_[k] + tile_allowed_ns_[k];
      tile_due_[k] = due;
      stats_.tile_renders += due;
      row_due = row_due || due;
    }
    due_rows += row_due;
  }
  if (due_rows > 0) {
    renderer_->prepare(T_odom_cam(t1_ns));
    if (options_.supersampling > 1) depth_renderer_->prepare(T_odom_cam(t1_ns));
  }
  const float log_illum1 = static_cast<float>(std::log(illumination(t1_ns)));
  const int threads = pool_->numThreads();
  for (auto& e : thread_events_) e.clear();
  std::fill(thread_drops_.begin(), thread_drops_.end(), 0);
  if (due_rows > 0)
    pool_->run(tiles_y_, [&](int r, int thread) { processTileRow(r, thread, t1_ns, log_illum1); });
  ++stats_.renders;

  const size_t first = out->size();
  size_t n_signal = 0;
  for (int k = 0; k < threads; ++k) {
    n_signal += thread_events_[k].size();
    out->insert(out->end(), thread_events_[k].begin(), thread_events_[k].end());
    stats_.signal_events += thread_events_[k].size();
    stats_.refractory_drops += thread_drops_[k];
  }
  // Background activity (Poisson in time and uniform over pixels) and hot pixels.
  const double dt = dtSec(t1_ns, t0_ns);
  const double mid_rate = noiseRate(t0_ns + (t1_ns - t0_ns) / 2);
  const size_t n_pix = static_cast<size_t>(width_) * height_;
  std::poisson_distribution<long> n_noise(mid_rate * static_cast<double>(n_pix) * dt);
  std::uniform_int_distribution<int64_t> when(t0_ns + 1, t1_ns);
  std::uniform_int_distribution<size_t> where(0, n_pix - 1);
  std::bernoulli_distribution on(0.5);
  const long count = mid_rate > 0 ? n_noise(noise_rng_) : 0;
  for (long i = 0; i < count; ++i) {
    const size_t p = where(noise_rng_);
    out->push_back(PixelEvent{when(noise_rng_), static_cast<uint16_t>(p % width_),
                              static_cast<uint16_t>(p / width_),
                              static_cast<int8_t>(on(noise_rng_) ? 1 : -1)});
  }
  if (!hot_pixels_.empty()) {
    std::poisson_distribution<long> n_hot(options_.hot_pixel_rate_hz * dt);
    for (int p : hot_pixels_) {
      const long k = n_hot(noise_rng_);
      for (long i = 0; i < k; ++i)
        out->push_back(PixelEvent{when(noise_rng_), static_cast<uint16_t>(p % width_),
                                  static_cast<uint16_t>(p / width_), 1});
    }
  }
  stats_.noise_events += out->size() - first - n_signal;
}

void EventSimulator::simulateUntil(int64_t t_end_ns, EventVector* out) {
  if (!out) throw std::invalid_argument("EventSimulator::simulateUntil: null output");
  const size_t first = out->size();
  while (t_now_ns_ < t_end_ns) {
    const int64_t step_ns = planStep(t_now_ns_);
    // Steps of a fraction of the fastest tile's interval, but never past a tile's deadline
    // (unless the step is at its lower bound).
    int64_t deadline = std::numeric_limits<int64_t>::max();
    for (size_t k = 0; k < tile_t_ns_.size(); ++k)
      deadline = std::min(deadline, tile_t_ns_[k] + tile_allowed_ns_[k]);
    const int64_t min_step_ns = std::max<int64_t>(1000, secToNs(options_.min_render_step_s));
    const int64_t t1 =
        std::min({t_end_ns, t_now_ns_ + step_ns, std::max(deadline, t_now_ns_ + min_step_ns)});
    // The last step renders every tile, so no later event can precede t_end_ns.
    step(t_now_ns_, t1, step_ns, t1 == t_end_ns, out);
    t_now_ns_ = t1;
  }
  // Deterministic order whatever the thread interleaving and tile schedule: time, then row,
  // column, polarity (a total order: equal keys are equal events).
  sortEvents(out->begin() + first, out->end());
}

void EventSimulator::sortEvents(EventVector::iterator begin, EventVector::iterator end) {
  const size_t n = static_cast<size_t>(end - begin);
  if (n < 2) return;
  auto less = [](const PixelEvent& a, const PixelEvent& b) {
    if (a.t_ns != b.t_ns) return a.t_ns < b.t_ns;
    if (a.y != b.y) return a.y < b.y;
    if (a.x != b.x) return a.x < b.x;
    return a.polarity < b.polarity;
  };
  // Counting sort into ~n/8 buckets of equal time span (monotonic in t), then each small bucket
  // by the full order: the same result as one comparison sort, in about a third of the time.
  int64_t t_min = begin->t_ns, t_max = begin->t_ns;
  for (auto it = begin; it != end; ++it) {
    t_min = std::min(t_min, it->t_ns);
    t_max = std::max(t_max, it->t_ns);
  }
  const size_t n_buckets = std::max<size_t>(1, n / 8);
  const double scale = static_cast<double>(n_buckets) / (static_cast<double>(t_max - t_min) + 1.0);
  auto bucket = [&](const PixelEvent& e) {
    return std::min(n_buckets - 1,
                    static_cast<size_t>(static_cast<double>(e.t_ns - t_min) * scale));
  };
  sort_start_.assign(n_buckets + 1, 0);
  for (auto it = begin; it != end; ++it) ++sort_start_[bucket(*it) + 1];
  for (size_t b = 0; b < n_buckets; ++b) sort_start_[b + 1] += sort_start_[b];
  sort_scratch_.resize(n);
  for (auto it = begin; it != end; ++it) sort_scratch_[sort_start_[bucket(*it)]++] = *it;
  // sort_start_[b] is now the end of bucket b.
  size_t b0 = 0;
  for (size_t b = 0; b < n_buckets; ++b) {
    std::sort(sort_scratch_.begin() + b0, sort_scratch_.begin() + sort_start_[b], less);
    b0 = sort_start_[b];
  }
  std::copy(sort_scratch_.begin(), sort_scratch_.end(), begin);
}

cv::Mat1f EventSimulator::depthMap(int64_t t_ns) {
  cv::Mat1f d(height_, width_);
  depth_renderer_->render(T_odom_cam(t_ns), nullptr, reinterpret_cast<float*>(d.data), pool_.get());
  return d;
}

cv::Mat1f EventSimulator::intensityImage(int64_t t_ns) {
  cv::Mat1f img(height_, width_);
  renderer_->render(T_odom_cam(t_ns), reinterpret_cast<float*>(img.data), nullptr, pool_.get());
  img *= illumination(t_ns);
  return img;
}

}  // namespace sim
}  // namespace vwe_vo
