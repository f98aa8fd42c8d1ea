#include "vwe_vo/core/frontend.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace vwe_vo {

const char* toString(ArcStatus s) {
  switch (s) {
    case ArcStatus::kOk: return "OK";
    case ArcStatus::kStandstill: return "STANDSTILL";
    case ArcStatus::kLost: return "LOST";
    case ArcStatus::kLowEvents: return "LOW_EVENTS";
  }
  return "?";
}

void FrontendOptions::validate() const {
  auto fail = [](const std::string& m) { throw std::invalid_argument("FrontendOptions: " + m); };
  volume.validate();
  if (!(window_duration_s > 0.005 && window_duration_s <= 5.0)) fail("window_duration_s must be in (0.005, 5] s");
  if (window_by_count && window_events < 100) fail("window_events must be at least 100");
  if (max_events_per_volume < 100) fail("max_events_per_volume must be at least 100");
  if (!(std::isfinite(nominal_speed_mps) && nominal_speed_mps >= 0 && nominal_speed_mps < 60))
    fail("nominal_speed_mps must be in [0, 60) m/s");
  if (!(omega_max_rad_s > 0 && omega_max_rad_s <= 10)) fail("omega_max_rad_s must be in (0, 10] rad/s");
  if (!(scan_half_range_rad_s > 0)) fail("scan_half_range_rad_s must be positive");
  if (!(scan_step_rad_s > 0 && scan_step_rad_s < scan_half_range_rad_s)) fail("scan_step_rad_s must be in (0, scan_half_range_rad_s)");
  if (!(refine_tolerance_rad_s > 0 && refine_tolerance_rad_s < scan_step_rad_s)) fail("refine_tolerance_rad_s must be in (0, scan_step_rad_s)");
  if (!(standstill_event_rate_hz >= 0)) fail("standstill_event_rate_hz must be >= 0");
  if (!(standstill_speed_mps >= 0)) fail("standstill_speed_mps must be >= 0");
  if (!(min_confidence >= 0 && min_confidence < 1)) fail("min_confidence must be in [0, 1)");
  if (!(gyro_prior_half_range_rad_s > 0)) fail("gyro_prior_half_range_rad_s must be positive");
  if (!(max_backwards_jump_s >= 0)) fail("max_backwards_jump_s must be >= 0");
}

Frontend::Frontend(const FrontendOptions& options, const CameraModel& camera, const Pose3& T_base_cam)
    : options_(options),
      camera_(camera),
      T_base_cam_(T_base_cam),
      volume_((options.validate(), options.volume), camera.width(), camera.height(), camera.calibration().fx,
              camera.calibration().fy, camera.calibration().cx, camera.calibration().cy),
      objective_(camera_, &volume_) {}

void Frontend::reset() {
  buffer_.clear();
  next_window_start_ns_ = -1;
  odometry_.clear();
  gyro_.clear();
  last_omega_ = 0.0;
  lost_ = true;
  chain_.reset();
  ++stats_.resets;
}

bool Frontend::addEvents(const EventVector& events) {
  bool did_reset = false;
  for (const PixelEvent& e : events) {
    ++stats_.events_in;
    if (!camera_.inside(e.x, e.y)) {
      ++stats_.events_outside;
      continue;
    }
    if (!buffer_.empty() && e.t_ns < buffer_.newestTime()) {
      if (dtSec(buffer_.newestTime(), e.t_ns) > options_.max_backwards_jump_s) {
        reset();
        did_reset = true;
      } else {
        ++stats_.events_out_of_order;
        continue;
      }
    }
    if (next_window_start_ns_ < 0) next_window_start_ns_ = e.t_ns;
    buffer_.push(e);
  }
  return did_reset;
}

void Frontend::addOdometry(int64_t t_ns, double v_mps, double yaw_rate_rad_s) {
  if (!std::isfinite(v_mps) || !std::isfinite(yaw_rate_rad_s)) return;
  odometry_.push_back({t_ns, v_mps, yaw_rate_rad_s});
  while (odometry_.size() > 20000) odometry_.pop_front();
}

void Frontend::addGyro(int64_t t_ns, double yaw_rate_rad_s) {
  if (!std::isfinite(yaw_rate_rad_s)) return;
  gyro_.push_back({t_ns, 0.0, yaw_rate_rad_s});
  while (gyro_.size() > 20000) gyro_.pop_front();
}

bool Frontend::nextWindow(EventVector* window, int64_t* t0, int64_t* t1) const {
  if (buffer_.empty() || next_window_start_ns_ < 0) return false;
  *t0 = next_window_start_ns_;
  if (options_.window_by_count) {
    const size_t i0 = buffer_.lowerBound(*t0);
    if (buffer_.size() - i0 < options_.window_events + 1) return false;
    if (window) *window = buffer_.windowByCount(*t0, options_.window_events);
    *t1 = buffer_[i0 + options_.window_events].t_ns;
    return true;
  }
  *t1 = *t0 + secToNs(options_.window_duration_s);
  if (buffer_.newestTime() < *t1) return false;
  if (window) *window = buffer_.window(*t0, *t1);
  return true;
}

size_t Frontend::pendingWindows() const {
  if (buffer_.empty() || next_window_start_ns_ < 0) return 0;
  if (options_.window_by_count) return (buffer_.size() - buffer_.lowerBound(next_window_start_ns_)) / (options_.window_events + 1);
  const double span = dtSec(buffer_.newestTime(), next_window_start_ns_);
  return span > 0 ? size_t(span / options_.window_duration_s) : 0;
}

size_t Frontend::dropBacklog(size_t keep) {
  size_t dropped = 0;
  EventVector unused;
  int64_t t0, t1;
  while (pendingWindows() > keep && nextWindow(nullptr, &t0, &t1)) {
    next_window_start_ns_ = t1;
    buffer_.dropBefore(t1);
    if (chain_) chain_->append(last_omega_, 0.0, t1);  // unknown motion: hold the pose
    ++dropped;
  }
  stats_.windows_dropped += dropped;
  if (dropped) lost_ = true;
  return dropped;
}

double Frontend::speedAt(int64_t t0, int64_t t1, bool* standstill) const {
  double sum = 0;
  int n = 0;
  for (const RateSample& s : odometry_)
    if (s.t_ns >= t0 && s.t_ns <= t1) sum += s.v, ++n;
  if (n == 0) {
    *standstill = false;
    return options_.nominal_speed_mps;
  }
  const double v = sum / n;
  *standstill = std::abs(v) < options_.standstill_speed_mps;
  return v;
}

bool Frontend::gyroAt(int64_t t0, int64_t t1, double* yaw_rate) const {
  double sum = 0;
  int n = 0;
  for (const RateSample& s : gyro_)
    if (s.t_ns >= t0 && s.t_ns <= t1) sum += s.yaw_rate, ++n;
  if (n == 0) return false;
  *yaw_rate = sum / n;
  return true;
}

double Frontend::contrast(const EventVector& events, int64_t t_ref_ns, double omega, double v) {
  const AckermannArcModel model(omega, v, t_ref_ns, T_base_cam_);
  ++stats_.evaluations;
  return objective_.evaluate(events, model).variance;
}

ArcEstimate Frontend::estimateWindow(const EventVector& events, int64_t t_ref_ns, double v, double center,
                                     double half_range) {
  ArcEstimate arc;
  arc.t_ref_ns = t_ref_ns;
  arc.v = v;
  arc.num_events = uint32_t(events.size());
  const double wmax = options_.omega_max_rad_s, step = options_.scan_step_rad_s;
  auto scan = [&](double lo, double hi, double* best_w, double* best_f, double* min_f) {
    lo = std::max(lo, -wmax);
    hi = std::min(hi, wmax);
    const int n = std::max(2, int(std::ceil((hi - lo) / step)) + 1);
    for (int i = 0; i < n; ++i) {
      const double w = lo + (hi - lo) * i / (n - 1);
      const double f = contrast(events, t_ref_ns, w, v);
      ++arc.evaluations;
      if (f > *best_f) *best_f = f, *best_w = w;
      *min_f = std::min(*min_f, f);
    }
    return std::make_pair(lo, hi);
  };
  double best_w = center, best_f = -1.0, min_f = 1e300;
  auto range = scan(center - half_range, center + half_range, &best_w, &best_f, &min_f);
  const bool at_edge = (best_w - range.first < 1.5 * step && range.first > -wmax) ||
                       (range.second - best_w < 1.5 * step && range.second < wmax);
  if (at_edge) range = scan(-wmax, wmax, &best_w, &best_f, &min_f);
  // Golden-section refinement inside the bracket around the best scan point.
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  double a = std::max(-wmax, best_w - step), b = std::min(wmax, best_w + step);
  double c = b - g * (b - a), d = a + g * (b - a);
  double fc = contrast(events, t_ref_ns, c, v), fd = contrast(events, t_ref_ns, d, v);
  arc.evaluations += 2;
  while (b - a > options_.refine_tolerance_rad_s) {
    if (fc > fd) {
      b = d, d = c, fd = fc;
      c = b - g * (b - a);
      fc = contrast(events, t_ref_ns, c, v);
    } else {
      a = c, c = d, fc = fd;
      d = a + g * (b - a);
      fd = contrast(events, t_ref_ns, d, v);
    }
    ++arc.evaluations;
  }
  const double w_ref = fc > fd ? c : d, f_ref = std::max(fc, fd);
  if (f_ref >= best_f) best_w = w_ref, best_f = f_ref;
  arc.omega = best_w;
  arc.contrast = best_f;
  arc.confidence = best_f > 0 ? std::clamp((best_f - min_f) / best_f, 0.0, 1.0) : 0.0;
  arc.status = arc.confidence < options_.min_confidence ? ArcStatus::kLost : ArcStatus::kOk;
  return arc;
}

std::vector<ArcEstimate> Frontend::process() {
  std::vector<ArcEstimate> arcs;
  EventVector window;
  int64_t t0, t1;
  while (nextWindow(&window, &t0, &t1)) {
    ArcEstimate arc;
    const double duration = dtSec(t1, t0);
    bool odom_standstill = false;
    const double v = speedAt(t0, t1, &odom_standstill);
    const double rate = double(window.size()) / std::max(duration, 1e-6);
    const int64_t t_ref = window.empty() ? t0 + (t1 - t0) / 2 : window.front().t_ns + (window.back().t_ns - window.front().t_ns) / 2;
    if (odom_standstill || rate < options_.standstill_event_rate_hz) {
      arc.status = ArcStatus::kStandstill;
      arc.omega = 0.0;
      arc.v = 0.0;
      arc.confidence = 1.0;
    } else if (window.size() < options_.min_events) {
      arc.status = ArcStatus::kLowEvents;
      arc.omega = last_omega_;
      arc.v = v;
    } else {
      const EventVector sub = subsampleEvents(window, options_.max_events_per_volume, options_.seed + stats_.windows);
      double center = lost_ ? 0.0 : last_omega_;
      double half = lost_ ? options_.omega_max_rad_s : options_.scan_half_range_rad_s;
      double gyro = 0.0;
      if (options_.use_gyro_prior && gyroAt(t0, t1, &gyro)) center = gyro, half = options_.gyro_prior_half_range_rad_s;
      arc = estimateWindow(sub, t_ref, v, center, half);
      lost_ = arc.status == ArcStatus::kLost;
      if (arc.status == ArcStatus::kOk) last_omega_ = arc.omega;
    }
    arc.t_ref_ns = t_ref;
    arc.t_start_ns = t0;
    arc.t_end_ns = t1;
    arc.window_events = window.size();
    if (arc.status != ArcStatus::kOk && arc.status != ArcStatus::kLost) arc.num_events = 0;
    if (!chain_) chain_ = std::make_unique<ArcChain>(Pose3::Identity(), t0);
    chain_->append(arc.omega, arc.v, t1);
    arcs.push_back(arc);
    ++stats_.windows;
    next_window_start_ns_ = t1;
    buffer_.dropBefore(t1);
  }
  return arcs;
}

Pose3 Frontend::T_odom_base(int64_t t_ns) const { return chain_ ? chain_->T_odom_base(t_ns) : Pose3::Identity(); }

}  // namespace vwe_vo
