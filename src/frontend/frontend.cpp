#include "vwe_vo/frontend/frontend.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>

#include "vwe_vo/common/validated.h"
#include "vwe_vo/sensor/subsample.h"

namespace vwe_vo {

namespace {

/// Maximises f on [a, b] by Brent's method, starting from x0 in (a, b) with f(x0) = f0 known.
/// When f(a) = fa and f(b) = fb are known too (finite), the first step is the parabola through
/// the three points instead of a golden-section step. Stops when the bracket is narrower than
/// tol (or after max_iter evaluations).
template <typename F>
double brentMaximize(F&& f, double a, double b, double x0, double f0, double fa, double fb,
                     double tol, int max_iter, double* f_best) {
  const double kGolden = 0.3819660112501051;
  double x = x0, w = x0, u = x0, fx = -f0, fw = -f0, fv = -f0, v = x0;  // minimise -f
  double d = 0.0, e = 0.0;
  if (std::isfinite(fa) && std::isfinite(fb) && a < x0 && x0 < b) {
    // w: the better, v: the other end; e larger than any step inside [a, b] admits the parabola.
    const bool a_better = fa >= fb;
    w = a_better ? a : b, fw = -(a_better ? fa : fb);
    v = a_better ? b : a, fv = -(a_better ? fb : fa);
    e = b - a;
  }
  for (int it = 0; it < max_iter; ++it) {
    const double m = 0.5 * (a + b);
    const double tol1 = 0.5 * tol, tol2 = 2.0 * tol1;
    if (std::abs(x - m) <= tol2 - 0.5 * (b - a)) break;
    bool golden = true;
    if (std::abs(e) > tol1) {
      const double r = (x - w) * (fx - fv), q0 = (x - v) * (fx - fw);
      double p = (x - v) * q0 - (x - w) * r, q = 2.0 * (q0 - r);
      if (q > 0) p = -p;
      q = std::abs(q);
      if (std::abs(p) < std::abs(0.5 * q * e) && p > q * (a - x) && p < q * (b - x)) {
        e = d;
        d = p / q;
        u = x + d;
        if (u - a < tol2 || b - u < tol2) d = x < m ? tol1 : -tol1;
        golden = false;
      }
    }
    if (golden) {
      e = (x < m ? b : a) - x;
      d = kGolden * e;
    }
    u = std::abs(d) >= tol1 ? x + d : x + (d > 0 ? tol1 : -tol1);
    const double fu = -f(u);
    if (fu <= fx) {
      (u < x ? b : a) = x;
      v = w, fv = fw, w = x, fw = fx, x = u, fx = fu;
    } else {
      (u < x ? a : b) = u;
      if (fu <= fw || w == x) {
        v = w, fv = fw, w = u, fw = fu;
      } else if (fu <= fv || v == x || v == w) {
        v = u, fv = fu;
      }
    }
  }
  *f_best = -fx;
  return x;
}

}  // namespace

const char* toString(ArcStatus s) {
  switch (s) {
    case ArcStatus::kOk:
      return "OK";
    case ArcStatus::kStandstill:
      return "STANDSTILL";
    case ArcStatus::kLost:
      return "LOST";
    case ArcStatus::kLowEvents:
      return "LOW_EVENTS";
  }
  return "?";
}

void FrontendOptions::validate(const std::string& section) const {
  auto fail = [&](const std::string& m) { throw std::invalid_argument(section + "." + m); };
  volume.validate(section + ".volume");
  if (!(window_duration_s > 0.005 && window_duration_s <= 5.0))
    fail("window_duration_s must be in (0.005, 5] s");
  if (!(window_stride_s >= 0 && window_stride_s <= window_duration_s))
    fail("window_stride_s must be in [0, window_duration_s] (0: equal to window_duration_s)");
  if (window_by_count && window_events < 100) fail("window_events must be at least 100");
  if (max_events_per_volume < 100) fail("max_events_per_volume must be at least 100");
  if (subsample_time_slices < 1 || size_t(subsample_time_slices) > max_events_per_volume / 10)
    fail("subsample_time_slices must be in [1, max_events_per_volume / 10]");
  if (!(std::isfinite(nominal_speed_mps) && nominal_speed_mps >= 0 && nominal_speed_mps < 60))
    fail("nominal_speed_mps must be in [0, 60) m/s");
  if (!(omega_max_rad_s > 0 && omega_max_rad_s <= 10))
    fail("omega_max_rad_s must be in (0, 10] rad/s");
  if (!(scan_half_range_rad_s > 0)) fail("scan_half_range_rad_s must be positive");
  if (!(scan_step_rad_s > 0 && scan_step_rad_s < scan_half_range_rad_s))
    fail("scan_step_rad_s must be in (0, scan_half_range_rad_s)");
  if (!(full_scan_step_rad_s >= scan_step_rad_s && full_scan_step_rad_s <= omega_max_rad_s))
    fail("full_scan_step_rad_s must be in [scan_step_rad_s, omega_max_rad_s]");
  if (full_scan_candidates < 1) fail("full_scan_candidates must be at least 1");
  if (full_scan_max_events > 0 && full_scan_max_events < 100)
    fail("full_scan_max_events must be 0 (all) or at least 100");
  if (!(refine_tolerance_rad_s > 0 && refine_tolerance_rad_s < scan_step_rad_s))
    fail("refine_tolerance_rad_s must be in (0, scan_step_rad_s)");
  if (!(standstill_event_rate_hz >= 0)) fail("standstill_event_rate_hz must be >= 0");
  if (!(parallax_mask_slope >= 0 && parallax_mask_slope <= 10))
    fail("parallax_mask_slope must be in [0, 10] (0: off)");
  if (!(roll_rate_step_rad_s >= 0 && roll_rate_step_rad_s <= 0.2))
    fail("roll_rate_step_rad_s must be in [0, 0.2] rad/s (0: off)");
  if (!(standstill_speed_mps >= 0)) fail("standstill_speed_mps must be >= 0");
  if (!(min_confidence >= 0 && min_confidence < 1)) fail("min_confidence must be in [0, 1)");
  if (!(slow_rate_fraction >= 0 && slow_rate_fraction < 1))
    fail("slow_rate_fraction must be in [0, 1) (0: off)");
  if (!(rescan_confidence >= 0 && rescan_confidence < 1))
    fail("rescan_confidence must be in [0, 1)");
  if (!(gyro_prior_half_range_rad_s > 0)) fail("gyro_prior_half_range_rad_s must be positive");
  if (!(max_backwards_jump_s >= 0)) fail("max_backwards_jump_s must be >= 0");
  one_sided.validate(volume, section);
  ground.validate(section + ".ground");
}

Frontend::Frontend(const FrontendOptions& options, const CameraModel& camera,
                   const Pose3& T_base_cam)
    : options_(options),
      camera_(camera),
      T_base_cam_(T_base_cam),
      volume_(validated(options).volume, camera.width(), camera.height(), camera.calibration().fx,
              camera.calibration().fy, camera.calibration().cx, camera.calibration().cy),
      objective_(camera_, &volume_),
      scan_objectives_(camera_, options_.volume),
      one_sided_(options_.one_sided, camera_, T_base_cam_) {
  if (options_.ground_mask || options_.parallax_mask_slope > 0)
    ground_mask_ =
        GroundMask(camera_, T_base_cam_, options_.ground_mask ? options_.volume.z_min_m : 0.0,
                   options_.parallax_mask_slope);
  if (options_.ground.weight > 0) {
    // The road's evaluations run on the VWE's threads' count, its events on the VWE's slices.
    options_.ground.objective.pose_slice_s = options_.volume.pose_slice_s;
    options_.ground.num_threads = options_.volume.num_threads;
    ground_yaw_ = std::make_unique<GroundYaw>(options_.ground, camera_, T_base_cam_);
    if (!ground_yaw_->enabled()) ground_yaw_.reset();  // no pixel sees the road in range
  }
  if (one_sided_.enabled()) {
    const VolumeOptions deeper = one_sided_.deeperPlanes(options_.volume);
    const CameraCalibration& c = camera.calibration();
    one_sided_volume_ = std::make_unique<ProjectiveVolume>(deeper, camera.width(), camera.height(),
                                                           c.fx, c.fy, c.cx, c.cy);
    one_sided_objective_ = std::make_unique<VweObjective>(camera_, one_sided_volume_.get());
    one_sided_scan_objectives_ = std::make_unique<VweObjectivePool>(camera_, deeper);
  }
}

const EventVector& Frontend::offGround(const EventVector& events, EventVector* storage) const {
  if (ground_mask_.maskedPixels() == 0) return events;
  *storage = ground_mask_.filter(events);
  return storage->size() >= options_.min_events ? *storage : events;
}

void Frontend::reset() {
  buffer_.clear();
  next_window_start_ns_ = -1;
  odometry_.clear();
  gyro_.clear();
  last_omega_ = 0.0;
  last_curvature_ = 0.0;
  lost_ = true;
  after_standstill_ = false;
  moving_rate_hz_ = 0.0;
  speed_factors_.clear();
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
  if (options_.window_by_count)
    return (buffer_.size() - buffer_.lowerBound(next_window_start_ns_)) /
           (options_.window_events + 1);
  const int64_t span =
      buffer_.newestTime() - next_window_start_ns_ - secToNs(options_.window_duration_s);
  return span >= 0 ? size_t(span / strideNs()) + 1 : 0;
}

size_t Frontend::dropBacklog(size_t keep, std::vector<ArcEstimate>* skipped) {
  size_t dropped = 0;
  int64_t t0, t1;
  while (pendingWindows() > keep && nextWindow(nullptr, &t0, &t1)) {
    // Unknown rotation: the last yaw rate is held; the speed is /odom's, else the position holds.
    bool standstill = false, measured = false;
    const double v_odom = speedAt(t0, t1, &standstill, &measured);
    const double v = measured && !standstill ? v_odom : 0.0;
    extendChain(t0, t1, last_omega_, v);
    if (skipped) {
      ArcEstimate arc;
      arc.t_start_ns = t0;
      arc.t_end_ns = t1;
      arc.t_ref_ns = t0 + (t1 - t0) / 2;
      arc.omega = last_omega_;
      arc.v = v;
      arc.status = ArcStatus::kLost;
      skipped->push_back(arc);
    }
    moveToNextWindow(t0, t1);
    ++dropped;
  }
  stats_.windows_dropped += dropped;
  if (dropped) lost_ = true;
  return dropped;
}

double Frontend::speedAt(int64_t t0, int64_t t1, bool* standstill, bool* measured) const {
  double sum = 0;
  int n = 0;
  for (const RateSample& s : odometry_)
    if (s.t_ns >= t0 && s.t_ns <= t1) sum += s.v, ++n;
  if (measured) *measured = n > 0;
  if (n == 0) {
    *standstill = false;
    return options_.nominal_speed_mps;
  }
  const double v = sum / n;
  *standstill = std::abs(v) < options_.standstill_speed_mps;
  return v;
}

double Frontend::accelerationAt(int64_t t0, int64_t t1) const {
  // The slope of the odometry's speeds over the window and 0.1 s either side.
  constexpr int64_t kMargin_ns = 100000000;
  const int64_t t_mid = t0 + (t1 - t0) / 2;
  double n = 0, st = 0, stt = 0, sv = 0, stv = 0;
  for (const RateSample& s : odometry_) {
    if (s.t_ns < t0 - kMargin_ns || s.t_ns > t1 + kMargin_ns) continue;
    const double t = dtSec(s.t_ns, t_mid);
    n += 1, st += t, stt += t * t, sv += s.v, stv += t * s.v;
  }
  const double det = n * stt - st * st;
  return n >= 3 && det > 1e-12 ? (n * stv - st * sv) / det : 0.0;
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

double Frontend::contrast(const EventVector& events, int64_t t_ref_ns, double omega, double v,
                          bool deep_planes) {
  if (deep_planes && !one_sided_objective_)
    throw std::logic_error("Frontend: deep planes need one_sided.balance > 0");
  AckermannArcModel model(omega, v, t_ref_ns, T_base_cam_);
  model.setRollRate(roll_rate_);
  ++stats_.evaluations;
  VweObjective& objective = deep_planes ? *one_sided_objective_ : objective_;
  return objective.evaluate(events, model).contrast;
}

std::vector<double> Frontend::contrasts(const EventVector& events, int64_t t_ref_ns,
                                        const std::vector<double>& omegas, double v,
                                        bool deep_planes) {
  if (deep_planes && !one_sided_scan_objectives_)
    throw std::logic_error("Frontend: deep planes need one_sided.balance > 0");
  std::vector<double> f(omegas.size());
  VweObjectivePool& pool = deep_planes ? *one_sided_scan_objectives_ : scan_objectives_;
  pool.run(int(omegas.size()), [&](int i, VweObjective& objective) {
    AckermannArcModel model(omegas[size_t(i)], v, t_ref_ns, T_base_cam_);
    model.setRollRate(roll_rate_);
    f[size_t(i)] = objective.evaluate(events, model).contrast;
  });
  stats_.evaluations += omegas.size();
  return f;
}

ArcEstimate Frontend::estimateWindow(const EventVector& events, int64_t t_ref_ns, double v,
                                     double center, double half_range, const WindowScan& setup) {
  ArcEstimate arc;
  arc.t_ref_ns = t_ref_ns;
  arc.v = v;
  arc.num_events = uint32_t(events.size());
  const double wmax = options_.omega_max_rad_s, step = options_.scan_step_rad_s;
  // Every evaluated point, by omega: the scans skip points that one already covers, and the
  // refinement brackets the best point by its evaluated neighbours.
  std::map<double, double> f_of_w;
  auto coveredIn = [&](const std::map<double, double>& f, double w) {
    const auto it = f.lower_bound(w - 0.5 * step);
    return it != f.end() && it->first <= w + 0.5 * step;
  };
  auto covered = [&](double w) { return coveredIn(f_of_w, w); };
  // Evaluates `evs` on a grid over [lo, hi] into f, skipping the points f already covers.
  auto scanInto = [&](const EventVector& evs, std::map<double, double>& f, double lo, double hi,
                      double scan_step) {
    lo = std::max(lo, -wmax);
    hi = std::min(hi, wmax);
    const int n = std::max(2, int(std::ceil((hi - lo) / scan_step - 1e-9)) + 1);
    std::vector<double> ws;
    for (int i = 0; i < n; ++i) {
      const double w = lo + (hi - lo) * i / (n - 1);
      if (!coveredIn(f, w)) ws.push_back(w);
    }
    // The points are independent: evaluated in parallel, one per thread.
    const std::vector<double> fs = contrasts(evs, t_ref_ns, ws, v, setup.deep_planes);
    for (size_t i = 0; i < ws.size(); ++i) f[ws[i]] = fs[i];
    arc.evaluations += int(ws.size());
    return std::make_pair(lo, hi);
  };
  auto scan = [&](double lo, double hi, double scan_step) {
    return scanInto(events, f_of_w, lo, hi, scan_step);
  };
  auto best = [&] {
    return std::max_element(f_of_w.begin(), f_of_w.end(),
                            [](const auto& p, const auto& q) { return p.second < q.second; });
  };
  // The full range coarse to fine: every full_scan_step_rad_s, then every scan_step_rad_s
  // around the best full_scan_candidates local maxima (the peak is a few scan steps wide, so
  // the coarse grid lands on its flank; the second candidate guards against a narrow peak
  // between coarse points losing to a broad one).
  auto fullScan = [&] {
    const double coarse = std::max(step, options_.full_scan_step_rad_s);
    const double lo = std::max(-wmax, setup.rescan_lo_rad_s),
                 hi = std::min(wmax, setup.rescan_hi_rad_s);
    // The coarse grid only has to find the basins, so with many events it votes every k-th of
    // them (full_scan_max_events). Its values are then on another scale (the density grows
    // with the events) and stay out of f_of_w; the full set is evaluated at its lowest point,
    // which the confidence needs.
    const size_t max_coarse = options_.full_scan_max_events;
    const bool thin = max_coarse > 0 && events.size() > max_coarse;
    std::map<double, double> thinned_f;
    if (thin) {
      const size_t k = (events.size() + max_coarse - 1) / max_coarse;
      EventVector few;
      few.reserve(events.size() / k + 1);
      for (size_t i = 0; i < events.size(); i += k) few.push_back(events[i]);
      scanInto(few, thinned_f, lo, hi, coarse);
    } else {
      scan(lo, hi, coarse);
    }
    const std::map<double, double>& grid = thin ? thinned_f : f_of_w;
    std::vector<std::pair<double, double>> maxima;  // (f, omega)
    for (auto it = grid.begin(); it != grid.end(); ++it) {
      const auto next = std::next(it);
      const bool left_lower = it == grid.begin() || std::prev(it)->second <= it->second;
      const bool right_lower = next == grid.end() || next->second <= it->second;
      if (left_lower && right_lower) maxima.emplace_back(it->second, it->first);
    }
    std::sort(maxima.rbegin(), maxima.rend());
    const size_t k = std::min(maxima.size(), size_t(options_.full_scan_candidates));
    for (size_t i = 0; i < k; ++i) scan(maxima[i].second - coarse, maxima[i].second + coarse, step);
    if (thin) {
      const double w_min =
          std::min_element(grid.begin(), grid.end(), [](const auto& p, const auto& q) {
            return p.second < q.second;
          })->first;
      if (!covered(w_min)) {
        f_of_w[w_min] = contrast(events, t_ref_ns, w_min, v, setup.deep_planes);
        ++arc.evaluations;
      }
    }
  };
  std::pair<double, double> range;
  if (center - half_range <= -wmax && center + half_range >= wmax) {
    fullScan();
    range = {-wmax, wmax};
  } else {
    range = scan(center - half_range, center + half_range, step);
  }
  double best_w = best()->first, best_f = best()->second;
  double min_f = std::min_element(f_of_w.begin(), f_of_w.end(), [](const auto& p, const auto& q) {
                   return p.second < q.second;
                 })->second;
  const bool at_edge = (best_w - range.first < 1.5 * step && range.first > -wmax) ||
                       (range.second - best_w < 1.5 * step && range.second < wmax);
  // A flat scan around the previous yaw rate means the peak is elsewhere: a turn that began
  // within the window (such a window's confidence stays below rescan_confidence, a correct
  // window's lies above it).
  const bool partial = range.first > -wmax || range.second < wmax;
  const bool flat = best_f > 0 && (best_f - min_f) / best_f < options_.rescan_confidence;
  if (at_edge || (partial && flat)) {
    fullScan();
    best_w = best()->first, best_f = best()->second;
    for (const auto& p : f_of_w) min_f = std::min(min_f, p.second);
  }
  // Brent's method (parabolic steps, golden-section fallback) between the evaluated neighbours
  // of the best point, starting with the parabola through the three: the objective is smooth
  // there, so it needs a handful of evaluations.
  const auto it = best();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  double a = std::max(-wmax, best_w - step), b = std::min(wmax, best_w + step), fa = nan, fb = nan;
  if (it != f_of_w.begin() && best_w - std::prev(it)->first <= 1.01 * step)
    a = std::prev(it)->first, fa = std::prev(it)->second;
  if (std::next(it) != f_of_w.end() && std::next(it)->first - best_w <= 1.01 * step)
    b = std::next(it)->first, fb = std::next(it)->second;
  double f_ref = best_f;
  auto f = [&](double w) {
    ++arc.evaluations;
    return contrast(events, t_ref_ns, w, v, setup.deep_planes);
  };
  const double w_ref =
      brentMaximize(f, a, b, best_w, best_f, fa, fb, options_.refine_tolerance_rad_s, 30, &f_ref);
  if (f_ref >= best_f) best_w = w_ref, best_f = f_ref;
  if (options_.roll_rate_step_rad_s > 0 && setup.roll_nuisance) {
    // The body's roll rate as a nuisance (FrontendOptions::roll_rate_step_rad_s): the parabola
    // through -d, 0, +d at the best omega, its vertex within +-2 d, the best of the evaluated
    // points kept; then omega again at that roll rate.
    const double d = options_.roll_rate_step_rad_s;
    const double w_without_roll = best_w;
    auto at = [&](double r) {
      roll_rate_ = r;
      ++arc.evaluations;
      return contrast(events, t_ref_ns, best_w, v, setup.deep_planes);
    };
    const double f0 = best_f, fm = at(-d), fp = at(d);
    double r_best = 0.0, f_best = f0;
    if (fm > f_best) r_best = -d, f_best = fm;
    if (fp > f_best) r_best = d, f_best = fp;
    const double curvature = fm - 2 * f0 + fp;
    if (curvature < 0) {
      const double r = d * std::clamp(0.5 * (fm - fp) / curvature, -2.0, 2.0);
      if (std::abs(r) > 1e-3 * d && std::abs(std::abs(r) - d) > 1e-3 * d) {
        const double fr = at(r);
        if (fr > f_best) r_best = r, f_best = fr;
      }
    }
    roll_rate_ = r_best;
    if (r_best != 0.0) {
      best_f = f_best;
      ++stats_.windows_rolled;
      double f_roll = best_f;
      const double w_roll =
          brentMaximize(f, std::max(-wmax, best_w - step), std::min(wmax, best_w + step), best_w,
                        best_f, nan, nan, options_.refine_tolerance_rad_s, 30, &f_roll);
      if (f_roll >= best_f) best_w = w_roll, best_f = f_roll;
    }
    arc.roll_rate = roll_rate_;
    arc.roll_omega_shift = best_w - w_without_roll;
    roll_rate_ = 0.0;
  }
  arc.omega = best_w;
  arc.contrast = best_f;
  arc.confidence = best_f > 0 ? std::clamp((best_f - min_f) / best_f, 0.0, 1.0) : 0.0;
  arc.status = arc.confidence < options_.min_confidence ? ArcStatus::kLost : ArcStatus::kOk;
  return arc;
}

ArcEstimate Frontend::estimateSpan(const EventVector& events, int64_t t0, int64_t t1,
                                   WindowScan setup, bool* scanned) {
  ArcEstimate arc;
  const double duration = dtSec(t1, t0);
  bool odom_standstill = false, measured = false;
  double v = speedAt(t0, t1, &odom_standstill, &measured);
  const bool cut = options_.per_camera_min_depth && measured;
  setup.roll_nuisance = measured;
  objective_.setPerCameraMinDepth(cut);
  scan_objectives_.setPerCameraMinDepth(cut);
  if (one_sided_objective_) one_sided_objective_->setPerCameraMinDepth(cut);
  if (one_sided_scan_objectives_) one_sided_scan_objectives_->setPerCameraMinDepth(cut);
  const double rate = double(events.size()) / std::max(duration, 1e-6);
  // Without odometry, slow windows (braking into a stop, starting from one) are driven at a
  // speed in proportion to their event rate; the others update the moving rate.
  double factor = 1.0;
  const bool moving = !odom_standstill && rate >= options_.standstill_event_rate_hz &&
                      events.size() >= options_.min_events;
  if (!measured && moving && options_.slow_rate_fraction > 0) {
    const double slow_below = options_.slow_rate_fraction * moving_rate_hz_;
    if (moving_rate_hz_ > 0 && rate < slow_below) {
      factor = rate / slow_below;
      v *= factor;
      ++stats_.windows_slow;
    } else {
      moving_rate_hz_ =
          moving_rate_hz_ > 0 ? moving_rate_hz_ + 0.2 * (rate - moving_rate_hz_) : rate;
    }
    speed_factors_.push_back({t0, t1, factor});
    while (speed_factors_.size() > 64) speed_factors_.pop_front();
  }
  const int64_t t_ref = events.empty()
                            ? t0 + (t1 - t0) / 2
                            : events.front().t_ns + (events.back().t_ns - events.front().t_ns) / 2;
  *scanned = false;
  if (odom_standstill || rate < options_.standstill_event_rate_hz) {
    arc.status = ArcStatus::kStandstill;
    arc.confidence = 1.0;
  } else if (events.size() < options_.min_events) {
    arc.status = ArcStatus::kLowEvents;
    arc.omega = last_omega_;
    arc.v = v;
  } else {
    size_t budget = options_.max_events_per_volume;
    if (volume_thinning_ > 1) {
      budget = std::max(
          {budget / volume_thinning_, size_t(100), size_t(10 * options_.subsample_time_slices)});
      ++stats_.windows_thinned;
    }
    EventVector off_ground;
    const EventVector& seen = offGround(events, &off_ground);
    stats_.events_ground_masked += events.size() - seen.size();
    const EventVector sub = subsampleEventsPerTimeSlice(
        seen, t0, t1, budget, options_.subsample_time_slices, options_.seed + stats_.windows);
    double center = lost_ ? 0.0 : last_omega_;
    double half = lost_ ? options_.omega_max_rad_s : options_.scan_half_range_rad_s;
    double gyro = 0.0;
    if (options_.use_gyro_prior && gyroAt(t0, t1, &gyro))
      center = gyro, half = options_.gyro_prior_half_range_rad_s;
    setup.deep_planes = false;
    if (one_sided_.oneSided(sub)) {
      // The prediction: the gyro's yaw rate where /dvs/imu gives one, else the previous arc's,
      // which is stale at the start of a turn and smears the facade's measured depth, so the
      // rule separates deep from near facades less well without a gyro.
      double predicted = lost_ ? 0.0 : last_omega_;
      gyroAt(t0, t1, &predicted);
      ++stats_.evaluations;
      setup.deep_planes = one_sided_.deepEnough(
          objective_, sub, AckermannArcModel(predicted, v, t_ref, T_base_cam_));
      stats_.windows_one_sided += setup.deep_planes;
      stats_.windows_one_sided_near += !setup.deep_planes;
    }
    arc = estimateWindow(sub, t_ref, v, center, half, setup);
    if (!measured && after_standstill_ && options_.restart_speed_scan) {
      bool slower = false;
      int evaluations = arc.evaluations;
      for (const double f : {1.0 / 16.0, 1.0 / 4.0}) {
        const ArcEstimate a = estimateWindow(sub, t_ref, v * f, center, half, setup);
        evaluations += a.evaluations;
        if (a.status == ArcStatus::kOk && a.contrast > arc.contrast)
          arc = a, arc.v = v, slower = true;
      }
      arc.evaluations = evaluations;  // all three estimates'
      stats_.windows_restart_slower += slower;
    }
    if (ground_yaw_ && measured && arc.status == ArcStatus::kOk) {
      const GroundYawEstimate road =
          ground_yaw_->estimate(events, t0, t1, t_ref, v, accelerationAt(t0, t1), arc.omega,
                                options_.seed + stats_.windows,
                                lost_ ? std::numeric_limits<double>::quiet_NaN() : last_omega_);
      stats_.ground_evaluations += size_t(road.evaluations);
      if (road.valid) {
        const double w = ground_yaw_->share(road);
        stats_.ground_shift_abs_sum_rad_s += std::abs(road.omega - arc.omega);
        arc.omega = (1 - w) * arc.omega + w * road.omega;
        arc.road_omega = road.omega, arc.road_pitch = road.pitch, arc.road_roll = road.roll;
        arc.road_pitch_rate = road.pitch_rate, arc.road_curvature = road.curvature;
        arc.road_share = w;
        ++stats_.windows_ground;
        stats_.windows_ground_alone += w == 1.0;
        stats_.windows_ground_refused += w == 0.0;
      } else {
        ++stats_.windows_ground_few;
      }
    }
    *scanned = true;
  }
  arc.t_ref_ns = t_ref;
  arc.t_start_ns = t0;
  arc.t_end_ns = t1;
  arc.window_events = events.size();
  if (!*scanned) arc.num_events = 0;
  return arc;
}

std::vector<ArcEstimate> Frontend::process(size_t max_windows) {
  std::vector<ArcEstimate> arcs;
  EventVector window;
  int64_t t0, t1;
  for (size_t n = 0; n < max_windows && nextWindow(&window, &t0, &t1); ++n) {
    const double previous_omega = last_omega_;
    const bool was_lost = lost_;
    bool scanned = false;
    ArcEstimate arc = estimateSpan(window, t0, t1, WindowScan(), &scanned);
    std::vector<ArcEstimate> parts{arc};
    // A standstill window's moving edges become arcs. So do those of a window /odom says is
    // still for most of its time (a start or a stop just above the mean standstill speed): it
    // moved a centimetre and its events' yaw rate is noise (a start of indoor_long found
    // 6.5 deg/s, 2 deg over the window).
    if (arc.status == ArcStatus::kStandstill || arc.status == ArcStatus::kOk) {
      std::vector<ArcEstimate> edges = standstillEdges(window, t0, t1);
      int64_t moving_ns = 0;
      for (const ArcEstimate& e : edges)
        if (e.status != ArcStatus::kStandstill) moving_ns += e.t_end_ns - e.t_start_ns;
      const bool still = arc.status == ArcStatus::kStandstill || 2 * moving_ns < t1 - t0;
      if (!edges.empty() && still) parts = std::move(edges), ++stats_.windows_standstill_edges;
    }
    // The yaw rate changed within reach of this window: a constant arc would average a ramp
    // badly, so the window is estimated again as two halves (not with overlapping windows).
    const bool tiles = options_.window_by_count || options_.window_stride_s <= 0 ||
                       options_.window_stride_s >= options_.window_duration_s;
    if (scanned && !was_lost && arc.status == ArcStatus::kOk && parts.size() == 1 && tiles &&
        options_.split_omega_change_rad_s > 0 &&
        std::abs(arc.omega - previous_omega) > options_.split_omega_change_rad_s) {
      const int64_t tm = t0 + (t1 - t0) / 2;
      const auto mid = std::lower_bound(window.begin(), window.end(), tm,
                                        [](const PixelEvent& e, int64_t t) { return e.t_ns < t; });
      const EventVector first(window.begin(), mid), second(mid, window.end());
      bool s1 = false, s2 = false;
      // The halves of a ramp from the previous rate through the whole window's: they rescan
      // only that far (plus the scan's half range), not the full range, where a half's spurious
      // peak can win on straight driving; fast turn onsets still need the rescan within that range.
      const double far_end = 2.0 * arc.omega - previous_omega;
      WindowScan halves;
      halves.rescan_lo_rad_s = std::min(previous_omega, far_end) - options_.scan_half_range_rad_s;
      halves.rescan_hi_rad_s = std::max(previous_omega, far_end) + options_.scan_half_range_rad_s;
      const ArcEstimate a = estimateSpan(first, t0, tm, halves, &s1);
      if (a.status == ArcStatus::kOk) last_omega_ = a.omega;
      const ArcEstimate b = estimateSpan(second, tm, t1, halves, &s2);
      if (a.status == ArcStatus::kOk && b.status == ArcStatus::kOk) {
        parts = {a, b};
        ++stats_.windows_split;
      }
    }
    for (const ArcEstimate& p : parts) {
      arcs.push_back(p);
      extendChain(p.t_start_ns, p.t_end_ns, p.omegaWithoutRoll(), p.v);
    }
    for (const ArcEstimate& p : parts)
      if (p.status == ArcStatus::kOk && p.t_end_ns - p.t_start_ns >= strideNs() / 2 &&
          std::abs(p.v) >= std::max(options_.standstill_speed_mps, 1e-3))
        last_curvature_ = p.omega / p.v;
    const ArcEstimate& last = parts.back();
    lost_ = last.status == ArcStatus::kLost;
    after_standstill_ = last.status == ArcStatus::kStandstill;
    last_omega_ = last.status == ArcStatus::kOk
                      ? last.omega
                      : (arc.status == ArcStatus::kOk ? arc.omega : previous_omega);
    ++stats_.windows;
    moveToNextWindow(t0, t1);
  }
  return arcs;
}

std::vector<ArcEstimate> Frontend::standstillEdges(const EventVector& events, int64_t t0,
                                                   int64_t t1) const {
  // The /odom samples of the window, in time order (addOdometry appends).
  std::vector<RateSample> samples;
  for (const RateSample& s : odometry_)
    if (s.t_ns >= t0 && s.t_ns <= t1) samples.push_back(s);
  if (samples.size() < 3) return {};
  auto moving = [&](const RateSample& s) { return std::abs(s.v) >= options_.standstill_speed_mps; };
  // Braking: moving from t0 until the first sample below the threshold; starting: moving from
  // the last sample below it until t1.
  size_t first_still = 0, last_still = samples.size() - 1;
  while (first_still < samples.size() && moving(samples[first_still])) ++first_still;
  while (last_still > 0 && moving(samples[last_still])) --last_still;
  if (first_still >= samples.size() || first_still > last_still) return {};
  const int64_t t_stop = first_still > 0 ? samples[first_still].t_ns : t0;
  const int64_t t_go = last_still + 1 < samples.size() ? samples[last_still].t_ns : t1;
  constexpr int64_t kMinEdge_ns = 20000000;  // shorter edges stay in the standstill
  const bool head = t_stop - t0 >= kMinEdge_ns, tail = t1 - t_go >= kMinEdge_ns;
  if ((!head && !tail) || t_go <= t_stop) return {};
  auto count = [&](int64_t a, int64_t b) {
    const auto lo = std::lower_bound(events.begin(), events.end(), a,
                                     [](const PixelEvent& e, int64_t t) { return e.t_ns < t; });
    const auto hi = std::lower_bound(events.begin(), events.end(), b,
                                     [](const PixelEvent& e, int64_t t) { return e.t_ns < t; });
    return size_t(hi - lo);
  };
  auto part = [&](int64_t a, int64_t b, bool still) {
    ArcEstimate arc;
    arc.t_start_ns = a;
    arc.t_end_ns = b;
    arc.t_ref_ns = a + (b - a) / 2;
    arc.window_events = count(a, b);
    arc.confidence = 1.0;
    if (still) {
      arc.status = ArcStatus::kStandstill;
      return arc;
    }
    double sum = 0;
    int n = 0;
    for (const RateSample& s : samples)
      if (s.t_ns >= a && s.t_ns <= b) sum += s.v, ++n;
    arc.v = n > 0 ? sum / n : options_.standstill_speed_mps;
    // A vehicle keeps its steering through a stop: the path's curvature is the one before.
    arc.omega = last_curvature_ * arc.v;
    arc.status = ArcStatus::kOk;
    return arc;
  };
  std::vector<ArcEstimate> parts;
  const int64_t still_from = head ? t_stop : t0, still_to = tail ? t_go : t1;
  if (head) parts.push_back(part(t0, t_stop, false));
  parts.push_back(part(still_from, still_to, true));
  if (tail) parts.push_back(part(t_go, t1, false));
  return parts;
}

int64_t Frontend::strideNs() const {
  return options_.window_stride_s > 0 ? secToNs(options_.window_stride_s)
                                      : secToNs(options_.window_duration_s);
}

void Frontend::extendChain(int64_t t0, int64_t t1, double omega, double v) {
  // By count the windows tile the time; by duration a window stands for its middle stride.
  const bool overlap = !options_.window_by_count && options_.window_stride_s > 0 &&
                       options_.window_stride_s < options_.window_duration_s;
  const int64_t stride = overlap ? strideNs() : t1 - t0;
  const int64_t mid = t0 + (t1 - t0) / 2;
  if (!chain_) chain_ = std::make_unique<ArcChain>(Pose3::Identity(), mid - stride / 2);
  chain_->append(omega, v, std::max(chain_->endTime(), mid + stride / 2));
}

void Frontend::moveToNextWindow(int64_t t0, int64_t t1) {
  next_window_start_ns_ = options_.window_by_count ? t1 : t0 + strideNs();
  buffer_.dropBefore(next_window_start_ns_);
}

Trajectory3 integrateArcs(const std::vector<ArcEstimate>& arcs, int64_t step_ns) {
  std::vector<TimedRates> rates;
  rates.reserve(arcs.size());
  for (const ArcEstimate& a : arcs)
    rates.push_back({a.t_start_ns, a.t_ref_ns, a.t_end_ns, {a.omegaWithoutRoll(), a.v}});
  return integrateRamps(rates, step_ns);
}

void Frontend::setNominalSpeed(double v_mps) {
  if (!(v_mps > 0) || !std::isfinite(v_mps))
    throw std::invalid_argument("Frontend::setNominalSpeed: " + std::to_string(v_mps) +
                                " m/s is not a positive speed");
  options_.nominal_speed_mps = v_mps;
}

void Frontend::setNominalSpeed(double v_mps, int64_t t_ns) {
  double factor = 1.0;
  for (const SpeedFactor& f : speed_factors_)
    if (f.t0_ns <= t_ns && t_ns <= f.t1_ns) factor = f.factor;
  // Only a window at the moving rate says what the moving speed is. In a slow window (braking,
  // starting) the refined spline's speed there is smoothed across the step to the faster
  // windows around it, and divided by the window's factor it overshot the moving speed
  // (0.52 m/s for 0.3 after indoor_drive's stops).
  if (factor < 1.0) return;
  setNominalSpeed(v_mps);
}

Pose3 Frontend::T_odom_base(int64_t t_ns) const {
  return chain_ ? chain_->T_odom_base(t_ns) : Pose3::Identity();
}

}  // namespace vwe_vo
