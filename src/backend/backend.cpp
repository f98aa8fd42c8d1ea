#include "vwe_vo/backend/backend.h"

#include <ceres/gradient_problem.h>
#include <ceres/gradient_problem_solver.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "backend_imu.h"
#include "vwe_vo/common/validated.h"
#include "vwe_vo/sensor/subsample.h"

namespace vwe_vo {

void BackendOptions::validate(const std::string& section) const {
  auto fail = [&](const std::string& m) { throw std::invalid_argument(section + "." + m); };
  volume.validate(section + ".volume");
  if (!(degree >= 1 && degree <= 5)) fail("degree must be in [1, 5]");
  if (!(knot_spacing_s >= 0.02 && knot_spacing_s <= 10))
    fail("knot_spacing_s must be in [0.02, 10] s");
  if (!(tau1_s > 0.005 && tau1_s <= 10)) fail("tau1_s must be in (0.005, 10] s");
  if (!(tau2_s > tau1_s && tau2_s <= 10)) fail("tau2_s must be in (tau1_s, 10] s");
  if (!(window_s >= tau2_s && window_s <= 60)) fail("window_s must be in [tau2_s, 60] s");
  if (!(update_interval_s > 0 && update_interval_s <= window_s))
    fail("update_interval_s must be in (0, window_s] s");
  if (max_events_per_volume < 100) fail("max_events_per_volume must be at least 100");
  if (min_events_per_volume > max_events_per_volume)
    fail("min_events_per_volume must be <= max_events_per_volume");
  if (max_iterations < 0) fail("max_iterations must be >= 0");
  if (max_line_search_steps < 1 || max_line_search_steps > 100)
    fail("max_line_search_steps must be in [1, 100]");
  if (!(function_tolerance > 0 && function_tolerance < 0.1))
    fail("function_tolerance must be in (0, 0.1)");
  if (!(step_scale_per_span > 0 && step_scale_per_span <= 10))
    fail("step_scale_per_span must be in (0, 10]");
  if (!(init_sample_interval_s > 0 && init_sample_interval_s <= knot_spacing_s))
    fail("init_sample_interval_s must be in (0, knot_spacing_s] s");
  if (!(smoothness_weight >= 0 && std::isfinite(smoothness_weight)))
    fail("smoothness_weight must be >= 0");
  if (!(speed_prior_weight >= 0 && std::isfinite(speed_prior_weight)))
    fail("speed_prior_weight must be >= 0");
  if (!(deformation_weight >= 0 && std::isfinite(deformation_weight)))
    fail("deformation_weight must be >= 0");
  if (!(arc_rate_prior_weight >= 0 && std::isfinite(arc_rate_prior_weight)))
    fail("arc_rate_prior_weight must be >= 0");
  if (!(yaw_scan_half_range_rad_s >= 0 && yaw_scan_half_range_rad_s <= 1))
    fail("yaw_scan_half_range_rad_s must be in [0, 1] rad/s (0: off)");
  if (yaw_scan_half_range_rad_s > 0 &&
      !(yaw_scan_step_rad_s > 0 && yaw_scan_step_rad_s <= yaw_scan_half_range_rad_s))
    fail("yaw_scan_step_rad_s must be in (0, yaw_scan_half_range_rad_s]");
  if (!(arc_rate_prior_scale_deg_s >= 0 && arc_rate_prior_scale_deg_s <= 100))
    fail("arc_rate_prior_scale_deg_s must be in [0, 100] deg/s (0: quadratic)");
  if (!(outlier_arc_min_rad_s >= 0 && outlier_arc_min_rad_s <= 2))
    fail("outlier_arc_min_rad_s must be in [0, 2] rad/s (0: off)");
  if (!(parallax_mask_slope >= 0 && parallax_mask_slope <= 10))
    fail("parallax_mask_slope must be in [0, 10] (0: off)");
  if (!(stop_ramp_max_s >= 0 && stop_ramp_max_s <= 10))
    fail("stop_ramp_max_s must be in [0, 10] s (0: off)");
  if (!(nominal_min_tangent_speed_mps > 0 && nominal_min_tangent_speed_mps <= 10))
    fail("nominal_min_tangent_speed_mps must be in (0, 10] m/s");
  if (!(std::abs(pitch_per_g_deg) <= 30))
    fail("pitch_per_g_deg must be in [-30, 30] deg/g (0: off)");
  if (!(std::abs(roll_per_g_deg) <= 30)) fail("roll_per_g_deg must be in [-30, 30] deg/g (0: off)");
  if (!(max_backwards_jump_s >= 0)) fail("max_backwards_jump_s must be >= 0");
  if (!(output_rate_hz > 0 && output_rate_hz <= 10000))
    fail("output_rate_hz must be in (0, 10000] Hz");
}

// ---------------------------------------------------------------------------------------------

MultiVolumeObjective::MultiVolumeObjective(std::shared_ptr<BSpline> spline, const Pose3& T_base_cam,
                                           int first_free, std::vector<BackendVolume> volumes,
                                           VweObjectivePool* objectives)
    : spline_(std::move(spline)),
      T_base_cam_(T_base_cam),
      first_free_(first_free),
      volumes_(std::move(volumes)),
      objectives_(objectives) {
  if (first_free_ < 0 || first_free_ > spline_->numControlPoints())
    throw std::invalid_argument("MultiVolumeObjective: first_free " + std::to_string(first_free_) +
                                " outside [0, " + std::to_string(spline_->numControlPoints()) +
                                "]");
}

Eigen::VectorXd MultiVolumeObjective::freeParams() const {
  Eigen::VectorXd x(numFree());
  for (int i = first_free_; i < spline_->numControlPoints(); ++i)
    x.segment<2>(2 * (i - first_free_)) = spline_->controlPoints()[i];
  return x;
}

void MultiVolumeObjective::setParams(const Eigen::VectorXd& params) {
  if (params.size() != numFree())
    throw std::invalid_argument("MultiVolumeObjective: " + std::to_string(params.size()) +
                                " parameters, expected " + std::to_string(numFree()));
  for (int i = first_free_; i < spline_->numControlPoints(); ++i)
    spline_->setControlPoint(i, params.segment<2>(2 * (i - first_free_)));
}

double MultiVolumeObjective::evaluate(const Eigen::VectorXd& params, Eigen::VectorXd* gradient) {
  constexpr size_t kKept = 4;
  setParams(params);
  for (const Kept& k : kept_) {
    if (k.params != params || (gradient && k.gradient.size() == 0)) continue;
    if (gradient) *gradient = k.gradient;
    return k.value;
  }
  ++evaluations_;
  const int n = int(volumes_.size());
  contrasts_.assign(size_t(n), 0.0);
  full_gradients_.resize(size_t(n));
  if (n > 0) {  // (the priors' tests have no volumes and no pool)
    objectives_->run(n, [&](int i, VweObjective& objective) {
      const BackendVolume& v = volumes_[size_t(i)];
      BSplineCameraModel model(spline_, T_base_cam_, v.t_ref_ns);
      if (tilt_) model.setTilt(tilt_);
      contrasts_[size_t(i)] =
          objective.evaluate(v.events, model, gradient ? &full_gradients_[size_t(i)] : nullptr)
              .contrast;
    });
  }
  if (gradient) gradient->setZero(numFree());
  double sum = 0.0;
  for (int i = 0; i < n; ++i) {
    sum += contrasts_[size_t(i)];
    if (gradient) *gradient += full_gradients_[size_t(i)].tail(numFree());
  }
  if (kept_.size() == kKept) kept_.erase(kept_.begin());
  kept_.push_back({params, gradient ? *gradient : Eigen::VectorXd(), sum});
  return sum;
}

SpeedPrior::SpeedPrior(std::shared_ptr<const BSpline> spline, int first_free,
                       const std::vector<double>& u, double weight, double min_speed_mps,
                       const std::vector<double>& u_scale)
    : spline_(std::move(spline)), first_free_(first_free), weight_(weight) {
  u_ = usable(u, min_speed_mps);
  for (double uk : u_) v_.push_back(spline_->velocity(uk).norm());
  u_scale_ = usable(u_scale, min_speed_mps);
  for (double uk : u_scale_)
    scale_target_ += spline_->velocity(uk).norm() / double(u_scale_.size());
}

std::vector<double> SpeedPrior::usable(const std::vector<double>& u, double min_speed_mps) const {
  std::vector<double> out;
  for (double uk : u) {
    const bool still = spline_->standstillAt(uk) != nullptr;
    const double v = spline_->velocity(uk).norm();
    if (still || !(v >= min_speed_mps)) continue;
    // Only samples the free control points move.
    if (spline_->basis(uk, 0).first + spline_->degree() < first_free_) continue;
    out.push_back(uk);
  }
  return out;
}

double SpeedPrior::speed(double u, double factor, Eigen::VectorXd* gradient) const {
  const BasisDerivatives b = spline_->basis(u, 1);
  Vec2 c1 = Vec2::Zero();
  for (int j = 0; j <= spline_->degree(); ++j)
    c1 += b.values(1, j) * spline_->controlPoints()[b.first + j];
  const double s = c1.norm();
  if (!gradient || !(s > 0) || factor == 0.0) return s;
  const Vec2 ds_dc1 = c1 / s;
  for (int j = 0; j <= spline_->degree(); ++j) {
    const int i = b.first + j;
    if (i < first_free_) continue;
    gradient->segment<2>(2 * (i - first_free_)) += (factor * b.values(1, j)) * ds_dc1;
  }
  return s;
}

double SpeedPrior::evaluate(Eigen::VectorXd* gradient) const {
  const int num_free = 2 * (spline_->numControlPoints() - first_free_);
  if (gradient) gradient->setZero(num_free);
  if (weight_ == 0.0) return 0.0;
  double f = 0.0;
  if (!u_.empty()) {
    const double w = weight_ / double(u_.size());
    for (size_t k = 0; k < u_.size(); ++k) {
      // The residual needs the speed first: evaluated without, then with the gradient.
      const double r = (speed(u_[k], 0.0, nullptr) - v_[k]) / v_[k];
      f += w * r * r;
      if (gradient) speed(u_[k], 2 * w * r / v_[k], gradient);
    }
  }
  if (!u_scale_.empty() && scale_target_ > 0) {
    const double n = double(u_scale_.size());
    double s = 0.0;
    for (double uk : u_scale_) s += speed(uk, 0.0, nullptr) / n;
    const double r = (s - scale_target_) / scale_target_;
    f += weight_ * r * r;
    if (gradient)
      for (double uk : u_scale_) speed(uk, 2 * weight_ * r / (scale_target_ * n), gradient);
  }
  return f;
}

ArcRatePrior::ArcRatePrior(std::shared_ptr<const BSpline> spline, int first_free,
                           const std::vector<Arc>& arcs, double weight, double scale_deg_s)
    : spline_(std::move(spline)), first_free_(first_free), weight_(weight), scale_(scale_deg_s) {
  for (const Arc& a : arcs) {
    if (!(a.u_end - a.u_start >= 1e-3) || !std::isfinite(a.omega)) continue;
    // The headings at both ends depend on the control points active there (or, in a
    // standstill or at a slow tangent, where the heading is taken from): the end is the later.
    if (spline_->basis(a.u_end, 0).first + spline_->degree() < first_free_) continue;
    arcs_.push_back(a);
  }
}

double ArcRatePrior::evaluate(Eigen::VectorXd* gradient) const {
  const int num_free = 2 * (spline_->numControlPoints() - first_free_);
  if (gradient) gradient->setZero(num_free);
  if (arcs_.empty() || weight_ == 0.0) return 0.0;
  const double w = weight_ / double(arcs_.size());
  double f = 0.0;
  PlanarPoseJacobian ja, jb;
  Vec2 c;
  for (const Arc& a : arcs_) {
    const double psi_a = spline_->planarPose(a.u_start, &c, gradient ? &ja : nullptr);
    const double psi_b = spline_->planarPose(a.u_end, &c, gradient ? &jb : nullptr);
    const double dt = a.u_end - a.u_start;
    const double r = kDegPerRad * (wrapAngle(psi_b - psi_a) / dt - a.omega);
    // Cauchy: s^2 ln(1 + r^2 / s^2), r^2 for |r| << s, a bounded pull of an outlying arc.
    const double q = scale_ > 0 ? 1.0 + r * r / (scale_ * scale_) : 1.0;
    f += w * (scale_ > 0 ? scale_ * scale_ * std::log(q) : r * r);
    if (!gradient) continue;
    const double g = 2 * w * r / q * kDegPerRad / dt;
    auto add = [&](const PlanarPoseJacobian& j, double sign) {
      for (int k = 0; k < j.size; ++k) {
        const int i = j.index[k] - 2 * first_free_;
        if (i >= 0) (*gradient)[i] += sign * g * j.dpsi[k];
      }
    };
    add(jb, 1.0);
    add(ja, -1.0);
  }
  return f;
}

MultiVolumeCost::MultiVolumeCost(MultiVolumeObjective* objective, Eigen::VectorXd params0,
                                 double step_scale, double normaliser,
                                 std::vector<const SplinePrior*> priors, double deformation_weight)
    : objective_(objective),
      params0_(std::move(params0)),
      step_scale_(step_scale),
      normaliser_(normaliser),
      priors_(std::move(priors)),
      deformation_weight_(deformation_weight) {}

Eigen::VectorXd MultiVolumeCost::params(const double* x) const {
  return params0_ + step_scale_ * Eigen::Map<const Eigen::VectorXd>(x, params0_.size());
}

bool MultiVolumeCost::Evaluate(const double* x, double* cost, double* gradient) const {
  return evaluate(x, cost, gradient, true);
}

bool MultiVolumeCost::startCost(const double* x, double* cost) const {
  return evaluate(x, cost, nullptr, false);
}

bool MultiVolumeCost::evaluate(const double* x, double* cost, double* gradient,
                               bool deformation) const {
  Eigen::VectorXd g;
  const double f = objective_->evaluate(params(x), gradient ? &g : nullptr);
  if (!std::isfinite(f)) return false;
  *cost = -f / normaliser_;
  if (gradient) {
    if (!g.allFinite()) return false;
    Eigen::Map<Eigen::VectorXd>(gradient, params0_.size()) = (-step_scale_ / normaliser_) * g;
  }
  for (const SplinePrior* prior : priors_) {
    Eigen::VectorXd gp;
    *cost += prior->evaluate(gradient ? &gp : nullptr);  // the objective has set the control points
    if (gradient) Eigen::Map<Eigen::VectorXd>(gradient, params0_.size()) += step_scale_ * gp;
  }
  if (deformation && deformation_weight_ > 0) {
    // Control point k (of m free) moves by x[2k..2k+1]; three fixed (zero) moves precede them.
    const int m = NumParameters() / 2;
    auto move = [&](int k) { return k < 0 ? Vec2(Vec2::Zero()) : Vec2(x[2 * k], x[2 * k + 1]); };
    for (int i = -3; i + 3 < m; ++i) {
      const Vec2 d3 = move(i) - 3 * move(i + 1) + 3 * move(i + 2) - move(i + 3);
      *cost += deformation_weight_ * d3.squaredNorm();
      if (!gradient) continue;
      const double c[4] = {1, -3, 3, -1};
      for (int j = 0; j < 4; ++j) {
        const int k = i + j;
        if (k < 0) continue;
        gradient[2 * k] += 2 * deformation_weight_ * c[j] * d3.x();
        gradient[2 * k + 1] += 2 * deformation_weight_ * c[j] * d3.y();
      }
    }
  }
  return std::isfinite(*cost);
}

// ---------------------------------------------------------------------------------------------

int closeStandstillGaps(BSpline* spline, int first) {
  // At walking speed a sideways gap of a millimetre turns the direction of the first
  // centimetres after a restart by degrees (indoor_drive without /odom: 1-3 deg over 1 s).
  const int p = spline->degree(), n = spline->numControlPoints();
  const std::vector<double>& k = spline->knots();
  int closed = 0;
  for (const BSpline::Interval& s : spline->standstills()) {
    if (!(s.to_s < spline->validTo())) continue;  // still standing: no restart yet
    int j = std::max(first, 0);
    while (j < n && k[size_t(j)] < s.from_s) ++j;
    if (j >= n || k[size_t(j + p)] > s.to_s) continue;
    const Vec2 delta = spline->position(s.from_s) - spline->position(s.to_s);
    if (!(delta.norm() > 1e-9)) continue;  // closed to a nanometre
    std::vector<Vec2> P = spline->controlPoints();
    for (int i = j; i < n; ++i) P[size_t(i)] += delta;
    spline->setControlPoints(P);
    ++closed;
  }
  return closed;
}

void fitControlPoints(BSpline* spline, int first, const std::vector<double>& u,
                      const std::vector<Vec2>& p_odom, double smoothness_weight) {
  const int n = spline->numControlPoints();
  if (u.size() != p_odom.size())
    throw std::invalid_argument("fitControlPoints: " + std::to_string(u.size()) + " times but " +
                                std::to_string(p_odom.size()) + " positions");
  if (first < 0 || first >= n)
    throw std::invalid_argument("fitControlPoints: first " + std::to_string(first) +
                                " outside [0, " + std::to_string(n) + ")");
  const int m = n - first;
  const std::vector<Vec2>& P = spline->controlPoints();
  Eigen::MatrixXd AtA = Eigen::MatrixXd::Zero(m, m);
  Eigen::MatrixXd Atb = Eigen::MatrixXd::Zero(m, 2);
  // One row: sum_j a_j P_{idx_j} = b.
  auto addRow = [&](const std::vector<std::pair<int, double>>& row, Vec2 b) {
    for (const auto& c : row)
      if (c.first < first) b -= c.second * P[c.first];
    for (const auto& ci : row) {
      if (ci.first < first) continue;
      Atb.row(ci.first - first) += ci.second * b.transpose();
      for (const auto& cj : row)
        if (cj.first >= first) AtA(ci.first - first, cj.first - first) += ci.second * cj.second;
    }
  };
  std::vector<std::pair<int, double>> row;
  for (size_t k = 0; k < u.size(); ++k) {
    const BasisDerivatives b = spline->basis(u[k], 0);
    row.clear();
    for (int j = 0; j <= spline->degree(); ++j) row.emplace_back(b.first + j, b.values(0, j));
    addRow(row, p_odom[k]);
  }
  for (int i = std::max(1, first - 1); i + 1 < n; ++i) {
    row = {{i - 1, smoothness_weight}, {i, -2 * smoothness_weight}, {i + 1, smoothness_weight}};
    addRow(row, Vec2::Zero());
  }
  AtA.diagonal().array() += 1e-9 * (1.0 + AtA.diagonal().maxCoeff());
  const Eigen::MatrixXd X = AtA.ldlt().solve(Atb);
  for (int i = 0; i < m; ++i) spline->setControlPoint(first + i, X.row(i).transpose());
}

// ---------------------------------------------------------------------------------------------

Backend::Backend(const BackendOptions& options, const CameraModel& camera, const Pose3& T_base_cam)
    : options_(options),
      camera_(camera),
      T_base_cam_(T_base_cam),
      objectives_(camera_, validated(options).volume) {
  if (options_.parallax_mask_slope > 0)
    mask_ = GroundMask(camera_, T_base_cam_, 0.0, options_.parallax_mask_slope);
}

Backend::~Backend() = default;

void Backend::reset() {
  buffer_.clear();
  standstills_ns_.clear();
  dead_reckoning_.reset();
  has_good_rates_ = false;
  arcs_.clear();
  newest_arc_ns_ = processed_ns_ = spline_final_ns_ = -1;
  first_free_ = 0;
  spline_.reset();
  fit_u_.clear();
  overruled_until_ns_ = -1;
  ramp_from_u_ = std::numeric_limits<double>::infinity();
  counted_stop_edge_ns_ = counted_start_edge_ns_ = std::numeric_limits<int64_t>::min();
  if (imu_) imu_->reset();
  ++stats_.resets;
}

void Backend::addEvents(const EventVector& events) {
  if (events.empty()) return;
  stats_.events_in += events.size();
  if (!buffer_.empty() &&
      events.front().t_ns < buffer_.newestTime() - secToNs(options_.max_backwards_jump_s))
    reset();
  for (const PixelEvent& e : events) {
    if (!camera_.inside(e.x, e.y))
      ++stats_.events_outside;
    else if (!mask_.keeps(e))
      ++stats_.events_masked;
    else if (!buffer_.push(e))
      ++stats_.events_out_of_order;
  }
  // Bounded memory also when no arcs arrive: the next refinement never looks further back.
  const int64_t keep_ns = secToNs(options_.window_s + options_.tau2_s + options_.update_interval_s);
  if (!buffer_.empty() && buffer_.newestTime() - buffer_.oldestTime() > keep_ns + keep_ns / 4)
    buffer_.dropBefore(buffer_.newestTime() - keep_ns);
}

bool Backend::addArc(const ArcEstimate& arc) {
  ++stats_.arcs_in;
  bool was_reset = false;
  if (dead_reckoning_ && arc.t_end_ns < newest_arc_ns_ - secToNs(options_.max_backwards_jump_s)) {
    reset();
    was_reset = true;
  }
  if (!dead_reckoning_)
    dead_reckoning_ =
        std::make_unique<ArcDeadReckoning>(arc.t_start_ns, options_.interpolate_arc_rates);
  if (newest_arc_ns_ >= 0 && arc.t_end_ns <= newest_arc_ns_) return was_reset;
  const bool still = arc.status == ArcStatus::kStandstill;
  const bool measured =
      arc.status == ArcStatus::kOk && std::isfinite(arc.omega) && std::isfinite(arc.v);
  if (measured) {
    good_omega_ = arc.omega;
    good_v_ = arc.v;
    has_good_rates_ = true;
  } else if (!still) {
    ++stats_.arcs_held;  // no motion estimate: the last measured rates are held through it
  }
  double omega = still ? 0.0 : measured ? arc.omega : has_good_rates_ ? good_omega_ : 0.0;
  // With the IMU the first fit turns at the gyro's yaw rate (less the bias estimate): the solver
  // starts where the gyro says, and the volumes see the rest. From the events' arcs it stayed
  // near them (street_drive: yaw RPE 0.39 -> 0.12 deg/s, 0.54 -> 0.23 started at 2.3 s).
  double gyro_omega = 0.0;
  if (imu_ && !still && gyroMeanYawRate(arc.t_start_ns, arc.t_end_ns, &gyro_omega))
    omega = gyro_omega;
  const double v = still ? 0.0 : measured ? arc.v : has_good_rates_ ? good_v_ : 0.0;
  const int64_t from = newest_arc_ns_ >= 0 ? newest_arc_ns_ : arc.t_start_ns;
  dead_reckoning_->append({omega, v}, still, from, arc.t_ref_ns, arc.t_end_ns);
  if (measured) {
    arcs_.push_back(arc);
    // Bounded: the next refinement's window starts at most window_s before its newest arc.
    const int64_t keep_ns = secToNs(options_.window_s + options_.update_interval_s);
    while (!arcs_.empty() && arcs_.front().t_end_ns < arc.t_end_ns - keep_ns) arcs_.pop_front();
  }
  if (still) {
    if (!standstills_ns_.empty() && standstills_ns_.back().second >= from)
      standstills_ns_.back().second = arc.t_end_ns;
    else
      standstills_ns_.emplace_back(from, arc.t_end_ns);
  }
  newest_arc_ns_ = arc.t_end_ns;
  if (imu_) advanceImu();
  return was_reset;
}

bool Backend::process() {
  if (!dead_reckoning_) return false;
  const int64_t from = processed_ns_ < 0 ? dead_reckoning_->startTime() : processed_ns_;
  if (dtSec(newest_arc_ns_, from) < options_.update_interval_s) return false;
  update(newest_arc_ns_);
  return true;
}

void Backend::finish() {
  if (imu_ && dead_reckoning_) advanceImu(true);
  if (!dead_reckoning_ || newest_arc_ns_ <= processed_ns_) return;
  if (dtSec(newest_arc_ns_, dead_reckoning_->startTime()) < 2 * options_.init_sample_interval_s)
    return;
  update(newest_arc_ns_);
}

void Backend::update(int64_t t_new_ns) {
  extendSpline(t_new_ns);
  refine(t_new_ns);
  processed_ns_ = t_new_ns;
  spline_final_ns_ = finalUntil();
  ++stats_.updates;
  // Bounded memory: events before the next window cannot be used again.
  const int64_t keep_from = t_new_ns - secToNs(options_.window_s + options_.tau2_s);
  if (!buffer_.empty() && buffer_.oldestTime() < keep_from) buffer_.dropBefore(keep_from);
}

std::vector<BSpline::Interval> Backend::standstillIntervals(int64_t epoch_ns) const {
  std::vector<BSpline::Interval> out;
  for (const auto& s : standstills_ns_)
    out.push_back({dtSec(s.first, epoch_ns), dtSec(s.second, epoch_ns)});
  return out;
}

struct Backend::SpeedRamp {
  int64_t edge_ns = 0;          // the standstill's start (a stop) or end (a start)
  int64_t peak_ns = 0;          // the middle of the bin where the event rate peaked beyond it
  int64_t bin_ns = 0;           // length of the rate bins, away from the edge
  int direction = -1;           // -1: bins back from the edge (a stop); +1: ahead (a start)
  std::vector<double> factors;  // the speed over the cruise speed per bin, the edge's first
  /// The earliest time the ramp covers.
  int64_t from() const { return std::min(edge_ns, peak_ns); }
  /// The speed factor at t: 1 outside [edge, peak], linear between the bins' middles inside.
  double factorAt(int64_t t_ns) const {
    const double x = double(direction * (t_ns - edge_ns)) / double(bin_ns) - 0.5;
    if (x < -0.5 || x >= double(factors.size()) - 0.5) return 1.0;
    if (x <= 0) return factors.front();
    const size_t i = size_t(x);
    const double w = x - double(i);
    return (1 - w) * factors[i] + w * (i + 1 < factors.size() ? factors[i + 1] : 1.0);
  }
};

std::vector<Backend::SpeedRamp> Backend::speedRamps(int64_t from_ns, int64_t to_ns) const {
  std::vector<SpeedRamp> ramps;
  if (options_.stop_ramp_max_s <= 0 || buffer_.empty()) return ramps;
  constexpr int64_t kBin_ns = 100000000;  // 0.1 s: ~1e5 events at a moving rate of 1 Mev/s
  const int max_bins = int(options_.stop_ramp_max_s / 0.1 + 1e-9);
  const int64_t oldest = buffer_.oldestTime(), newest = std::min(buffer_.newestTime(), to_ns);
  auto rate = [&](int64_t t0) {  // events per second in [t0, t0 + bin)
    return double(buffer_.lowerBound(t0 + kBin_ns) - buffer_.lowerBound(t0)) / nsToSec(kBin_ns);
  };
  for (const auto& [a, b] : standstills_ns_) {
    // The noise floor: the quietest bin of the standstill (0 if none is buffered).
    double floor = std::numeric_limits<double>::infinity();
    for (int64_t t = std::max(a, oldest); t + kBin_ns <= std::min(b, newest); t += kBin_ns)
      floor = std::min(floor, rate(t));
    if (!std::isfinite(floor)) floor = 0.0;
    // The rates walking away from the edge, up to where they peaked: braking, the rate falls
    // steadily towards the stop; a cruising vehicle's rate varies with its yaw rate and the
    // scene, so the walk ends where the rate falls clearly (10 %) below its peak.
    auto ramp = [&](int64_t edge, int direction) {
      std::vector<double> rates;
      double peak = 0.0;
      size_t peak_bin = 0;
      bool ended = false;
      for (int j = 0; j < max_bins; ++j) {
        const int64_t t0 = direction < 0 ? edge - (j + 1) * kBin_ns : edge + j * kBin_ns;
        if (t0 < oldest || t0 + kBin_ns > newest) break;
        const double r = rate(t0) - floor;
        if (r < 0.9 * peak) {
          ended = true;
          break;
        }
        rates.push_back(r);
        if (r > peak) peak = r, peak_bin = size_t(j);
      }
      if (peak_bin == 0 || !(peak > 0)) return;
      // A start is ramped once its rate stopped rising (the cruise speed is the fit's there),
      // while its end is inside the window.
      if (direction > 0 && !ended && rates.size() < size_t(max_bins)) return;
      SpeedRamp r;
      r.edge_ns = edge;
      r.bin_ns = kBin_ns;
      r.direction = direction;
      r.peak_ns = edge + direction * (int64_t(peak_bin) * kBin_ns + kBin_ns / 2);
      if (direction > 0 && r.peak_ns <= from_ns) return;
      for (size_t j = 0; j < peak_bin; ++j)
        r.factors.push_back(std::clamp(rates[j] / peak, 0.0, 1.0));
      ramps.push_back(std::move(r));
    };
    if (a > from_ns && a - secToNs(options_.stop_ramp_max_s) < to_ns) ramp(a, -1);
    if (options_.start_ramps && b < newest_arc_ns_ && b < to_ns) ramp(b, +1);
  }
  return ramps;
}

void Backend::extendSpline(int64_t t_new_ns) {
  const int p = options_.degree;
  const double dk = options_.knot_spacing_s;
  const ArcChain& chain = dead_reckoning_->ramped();
  const int64_t epoch = spline_ ? spline_->epochNs() : chain.startTime();
  const double u_new = dtSec(t_new_ns, epoch);
  // Uniform knots (k - p) dk, unclamped: extending appends knots and control points and leaves
  // the existing curve on the old domain untouched.
  const int spans = std::max(1, int(std::ceil(u_new / dk - 1e-9)));
  const int n = spans + p;
  std::vector<double> knots(n + p + 1);
  for (int k = 0; k <= n + p; ++k) knots[k] = (k - p) * dk;

  std::vector<Vec2> P(n, Vec2::Zero());
  int first = 0;
  Pose3 T_anchor = Pose3::Identity();  // maps the front-end's odom into the spline's odom
  double u_old = 0.0;
  if (spline_) {
    u_old = spline_->toSplineTime(processed_ns_);
    const int n_old = spline_->numControlPoints();
    for (int i = 0; i < std::min(n, n_old); ++i) P[i] = spline_->controlPoints()[i];
    // Refit every control point whose support reaches past u_old (the unrefined part).
    while (first < n_old && knots[first + p + 1] <= u_old) ++first;
    first = std::min(first, n - 1);
    // Fit over the last half window, but not across arcs a refinement overruled.
    double span_s = options_.window_s / 2;
    if (overruled_until_ns_ > processed_ns_ - secToNs(span_s))
      span_s = std::max(0.0, dtSec(processed_ns_, overruled_until_ns_));
    T_anchor = fitAnchorOnSpline(*spline_, chain, processed_ns_, span_s);
  }
  // Without /odom, the braking ramps into stops (stop_ramp_max_s) and out of them
  // (start_ramps), also where the previous refinement drove one at the cruise speed before the
  // standstill was known: refit from the ramp's start.
  std::vector<SpeedRamp> ramps;
  ramp_from_u_ = std::numeric_limits<double>::infinity();
  if (!speeds_measured_ && options_.stop_ramp_max_s > 0) {
    const double u_window = u_new - options_.window_s;
    ramps = speedRamps(epoch + secToNs(u_window), t_new_ns);
    // A standstill is known once its still arcs arrive, up to update_interval_s after it began:
    // the ramp before it may reach behind the window, whose points the previous refinement drove
    // at the cruise speed. This refinement's window then reaches back to the ramp's start, as far
    // as the buffered events allow its volumes.
    const double u_events =
        dtSec(buffer_.empty() ? t_new_ns : buffer_.oldestTime(), epoch) + 0.5 * options_.tau2_s;
    for (const SpeedRamp& r : ramps) {
      ramp_from_u_ = std::min(ramp_from_u_, std::max(dtSec(r.from(), epoch), u_events));
      // Each refit of a ramp counts once (edges come in time order).
      int64_t& counted = r.direction < 0 ? counted_stop_edge_ns_ : counted_start_edge_ns_;
      if (r.edge_ns > counted) {
        counted = r.edge_ns;
        ++(r.direction < 0 ? stats_.stop_ramps : stats_.start_ramps);
      }
    }
    if (spline_) {
      int min_first = p + 1;
      while (min_first < n && knots[min_first + p + 1] <= std::min(u_window, ramp_from_u_))
        ++min_first;
      for (const SpeedRamp& r : ramps) {
        const double u_r = dtSec(r.from(), epoch);
        while (first > min_first && knots[first + p] > u_r) --first;
      }
    }
  }
  auto next = std::make_shared<BSpline>(p, knots, P, epoch);
  next->setStandstills(standstillIntervals(epoch));
  if (!speeds_measured_) next->setMinSpeed(options_.nominal_min_tangent_speed_mps);

  std::vector<double> u;
  std::vector<Vec2> pos;
  // The first fit also samples the dead reckoning (extrapolated) one knot span before the
  // domain, so that the start pose is not an end effect of the least squares.
  const double u_from = spline_ ? std::max(0.0, knots[first]) : -dk, u_to = next->validTo();
  const int samples =
      std::max(2, int(std::ceil((u_to - u_from) / options_.init_sample_interval_s)) + 1);
  for (int k = 0; k < samples; ++k) {
    const double uk = u_from + (u_to - u_from) * k / (samples - 1);
    u.push_back(uk);
    if (spline_ && uk <= u_old)
      pos.push_back(spline_->position(uk));
    else
      pos.push_back((T_anchor * chain.T_odom_base(epoch + secToNs(uk))).translation().head<2>());
  }
  if (!ramps.empty()) applySpeedRamps(ramps, epoch, u, &pos);
  fitControlPoints(next.get(), first, u, pos, options_.smoothness_weight);
  spline_ = next;
  fit_first_ = first;
  fit_u_ = std::move(u);
}

void Backend::applySpeedRamps(const std::vector<SpeedRamp>& ramps, int64_t epoch,
                              const std::vector<double>& u, std::vector<Vec2>* pos) const {
  const std::vector<Vec2> p = *pos;
  // The cruise speed of each ramp: the fit's (or the refined spline's) speed at its peak.
  std::vector<double> cruise;
  for (const SpeedRamp& r : ramps) {
    const double u_peak = dtSec(r.peak_ns, epoch);
    double v = std::numeric_limits<double>::quiet_NaN();
    for (size_t k = 1; k < u.size(); ++k)
      if (u[k - 1] <= u_peak && u_peak <= u[k]) v = (p[k] - p[k - 1]).norm() / (u[k] - u[k - 1]);
    if (!std::isfinite(v) && spline_ && u_peak >= spline_->validFrom() &&
        u_peak <= spline_->validTo())
      v = spline_->velocity(u_peak).norm();
    cruise.push_back(v);
  }
  for (size_t k = 1; k < u.size(); ++k) {
    const int64_t t_mid = epoch + secToNs(0.5 * (u[k - 1] + u[k]));
    Vec2 step = p[k] - p[k - 1];
    const double len = step.norm();
    for (size_t i = 0; i < ramps.size(); ++i) {
      const double f = ramps[i].factorAt(t_mid);
      if (f >= 1.0 || !(cruise[i] > 0) || !(len > 1e-9)) continue;
      step *= cruise[i] * f * (u[k] - u[k - 1]) / len;
      break;
    }
    (*pos)[k] = (*pos)[k - 1] + step;
  }
}

void Backend::refine(int64_t t_new_ns) {
  const int p = options_.degree;
  const double u_new = spline_->toSplineTime(t_new_ns);
  // The window, reaching back to the start of a speed ramp the extension refit (extendSpline).
  const double u_window =
      std::max(spline_->validFrom(), std::min(u_new - options_.window_s, ramp_from_u_));
  // Control points whose support ends before the window are fixed, and so are the first p + 1
  // (the first segment from the front-end: origin, heading and scale).
  int first_free = p + 1;
  while (first_free < spline_->numControlPoints() &&
         spline_->knots()[first_free + p + 1] <= u_window)
    ++first_free;
  first_free_ = first_free;
  if (first_free >= spline_->numControlPoints() || options_.max_iterations == 0) return;
  // The solver starts (and below, ends) with the path leaving each standstill where it stood.
  stats_.standstill_gaps_closed += size_t(closeStandstillGaps(spline_.get(), first_free));

  std::vector<BackendVolume> volumes;
  const double half = 0.5 * options_.tau2_s;
  for (double ur = u_new - half; ur - half >= u_window - 1e-9; ur -= options_.tau1_s) {
    if (spline_->standstillAt(ur)) {
      ++stats_.volumes_skipped;
      continue;
    }
    const int64_t t_ref = spline_->epochNs() + secToNs(ur);
    // Only the events the volume votes are copied out of the buffer (1-2 M in a second of a
    // street at 2 Mev/s, of which it votes max_events_per_volume).
    const size_t i0 = buffer_.lowerBound(t_ref - secToNs(half));
    const size_t i1 = buffer_.lowerBound(t_ref + secToNs(half));
    if (i1 < i0 + options_.min_events_per_volume) {
      ++stats_.volumes_skipped;
      continue;
    }
    volumes.push_back({t_ref, subsampleRange(buffer_, i0, i1, options_.max_events_per_volume,
                                             options_.seed + volumes.size())});
  }
  if (volumes.empty()) return;
  stats_.volumes += volumes.size();

  // With the tilt from the accelerations in the pose, the volumes see the camera tilted as well
  // (the IMU's tilt stays out of them).
  const int64_t tilt_from = volumes.front().t_ref_ns - secToNs(options_.tau2_s),
                tilt_to = volumes.back().t_ref_ns + secToNs(options_.tau2_s);
  MultiVolumeObjective objective(spline_, T_base_cam_, first_free, std::move(volumes),
                                 &objectives_);
  if (tiltInPose() && !imu_) objective.setTilt(tiltTable(tilt_from, tilt_to));
  const Eigen::VectorXd params0 = objective.freeParams();
  // With the gradient: the solver's first evaluation, at params0, is then already done.
  Eigen::VectorXd g0;
  const double f0 = objective.evaluate(params0, &g0);
  if (!(f0 > 0) || !std::isfinite(f0)) return;

  const auto t0 = std::chrono::steady_clock::now();
  std::vector<double> u_prior;
  for (double u = u_window; u <= u_new; u += options_.init_sample_interval_s) u_prior.push_back(u);
  // Measured speeds: every sample. A nominal speed: the refined past's speeds where the window
  // has any (processed_ns_ is still the previous refinement's end), else the new part's mean.
  std::vector<double> u_speeds, u_scale;
  if (speeds_measured_) {
    u_speeds = u_prior;
  } else {
    const double u_refined = processed_ns_ >= 0 ? spline_->toSplineTime(processed_ns_) : -1.0;
    for (double u : u_prior) (u <= u_refined ? u_speeds : u_scale).push_back(u);
  }
  SpeedPrior speed_prior(spline_, first_free, u_speeds, options_.speed_prior_weight, 0.05);
  if (speed_prior.numSamples() == 0)
    speed_prior = SpeedPrior(spline_, first_free, {}, options_.speed_prior_weight, 0.05, u_scale);
  std::vector<ArcRatePrior::Arc> arcs;
  for (const ArcEstimate& a : arcs_) {
    const double ua = spline_->toSplineTime(a.t_start_ns), ub = spline_->toSplineTime(a.t_end_ns);
    if (ub > u_window && ub <= u_new + 1e-9) arcs.push_back({ua, ub, a.omega});
  }
  const ArcRatePrior arc_prior(spline_, first_free, arcs, options_.arc_rate_prior_weight,
                               options_.arc_rate_prior_scale_deg_s);
  std::vector<const SplinePrior*> priors;
  if (options_.speed_prior_weight > 0) priors.push_back(&speed_prior);
  if (options_.arc_rate_prior_weight > 0) priors.push_back(&arc_prior);
  const std::unique_ptr<SplinePrior> gyro_prior =
      imu_ ? makeGyroPrior(u_window, u_new, first_free) : nullptr;
  if (gyro_prior) priors.push_back(gyro_prior.get());
  // The solver's unit follows the vehicle's scale: control points of a car moving 1.2 m per knot
  // span need moves of centimetres, a robot's of millimetres (LBFGS stopped after 2-5 iterations
  // on the street with a fixed 2 cm unit).
  double mean_speed = 0.0;
  for (double u : u_prior) mean_speed += spline_->velocity(u).norm() / double(u_prior.size());
  const double step_m =
      std::max(1e-3, options_.step_scale_per_span * mean_speed * options_.knot_spacing_s);
  // The solver starts from the best of the scanned starts (scanStart): the deformation prior then
  // measures the solver's moves from there.
  Eigen::VectorXd start = params0;
  {
    const MultiVolumeCost probe(&objective, params0, step_m, f0, priors, 0.0);
    const Eigen::VectorXd x_start = scanStart(probe, params0, first_free, step_m);
    if (!x_start.isZero()) start = probe.params(x_start.data());
  }
  auto* cost =
      new MultiVolumeCost(&objective, start, step_m, f0, priors, options_.deformation_weight);
  ceres::GradientProblem problem(cost);  // takes ownership
  ceres::GradientProblemSolver::Options so;
  so.line_search_direction_type = ceres::LBFGS;
  so.max_num_iterations = options_.max_iterations;
  so.function_tolerance = options_.function_tolerance;
  so.max_num_line_search_step_size_iterations = options_.max_line_search_steps;
  so.gradient_tolerance = 1e-8;
  so.parameter_tolerance = 1e-6;
  so.logging_type = ceres::SILENT;
  ceres::GradientProblemSolver::Summary summary;
  Eigen::VectorXd x = Eigen::VectorXd::Zero(start.size());
  ceres::Solve(so, problem, x.data(), &summary);
  const Eigen::VectorXd params = cost->params(x.data());
  const double f1 = objective.evaluate(params, nullptr);  // the solver's last point: kept
  stats_.solver_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  stats_.evaluations += objective.evaluations();
  stats_.solver_iterations += summary.iterations.empty() ? 0 : summary.iterations.size() - 1;
  if (summary.termination_type == ceres::NO_CONVERGENCE) ++stats_.max_iteration_stops;
  // Accept what lowered the total cost (VWE and speed prior); anything else is reverted.
  if (!(summary.final_cost <= summary.initial_cost) || !std::isfinite(f1) || !params.allFinite()) {
    ++stats_.rejected;
    objective.setParams(start);  // restores the start
    stats_.last_gain = 1.0;
  } else {
    stats_.last_gain = f1 / f0;
    stats_.gain_sum += f1 / f0 - 1.0;
    ++stats_.accepted;
  }
  if (gyro_prior) {
    const auto& gyro = static_cast<const GyroRatePrior&>(*gyro_prior);
    updateGyroBias(
        gyro, t_new_ns,
        gyro.measuresStandstill() ? 0.0 : preferredYawRateOffset(&objective, first_free, step_m));
  }
  stats_.standstill_gaps_closed += size_t(closeStandstillGaps(spline_.get(), first_free));
}

/// The solver's start turned: the spline at the sample times of its extension's fit, its steps
/// past u_old rotated by a heading offset h(u), refit the same way (the same free points and
/// smoothness), as x of the cost (control-point moves in solver units). The fit is turned, not
/// the dead reckoning it was fit to: the smoothed start moves less where h steps (measured on
/// the street: turning the dead reckoning exactly replaced turn onsets by ramps more often).
class Backend::TurnedStart {
 public:
  TurnedStart(const Backend& b, const Eigen::VectorXd& params0, int first_free, double step_m)
      : b_(b), params0_(params0), first_free_(first_free), step_m_(step_m), trial_(*b.spline_) {
    // The new part: past the previous refinement (the whole spline at the first).
    u_old_ =
        b.processed_ns_ >= 0 ? b.spline_->toSplineTime(b.processed_ns_) : b.spline_->validFrom();
    // Only the free points move (at the first refinement the fit also placed the fixed first ones).
    first_refit_ = std::max(b.fit_first_, first_free);
    valid_ = b.fit_u_.size() >= 2 && first_refit_ < b.spline_->numControlPoints() &&
             b.fit_u_.back() > u_old_;
    for (double u : b.fit_u_) p_.push_back(b.spline_->position(u));
  }
  bool valid() const { return valid_; }
  double uOld() const { return u_old_; }
  /// x of the start whose heading past u_old is turned by heading(u) [rad].
  template <typename Heading>
  Eigen::VectorXd operator()(Heading&& heading) {
    const std::vector<double>& u = b_.fit_u_;
    const std::vector<Vec2>& p = p_;
    std::vector<Vec2> q(p.size());
    q[0] = p[0];
    for (size_t k = 1; k < q.size(); ++k) {
      const double um = 0.5 * (u[k - 1] + u[k]);
      const Vec2 step = p[k] - p[k - 1];
      q[k] = q[k - 1] + (um <= u_old_ ? step : Eigen::Rotation2Dd(heading(um)) * step);
    }
    fitControlPoints(&trial_, first_refit_, u, q, b_.options_.smoothness_weight);
    Eigen::VectorXd x(params0_.size());
    for (int i = first_free_; i < trial_.numControlPoints(); ++i)
      x.segment<2>(2 * (i - first_free_)) =
          (trial_.controlPoints()[size_t(i)] - params0_.segment<2>(2 * (i - first_free_))) /
          step_m_;
    return x;
  }

 private:
  const Backend& b_;
  const Eigen::VectorXd& params0_;
  int first_free_;
  double step_m_;
  BSpline trial_;
  bool valid_ = false;
  double u_old_ = 0.0;
  int first_refit_ = 0;
  std::vector<Vec2> p_;  // the spline at the fit's sample times
};

double Backend::preferredYawRateOffset(MultiVolumeObjective* objective, int first_free,
                                       double step_m) {
  const Eigen::VectorXd p1 = objective->freeParams();
  TurnedStart turned(*this, p1, first_free, step_m);
  if (!turned.valid()) return std::numeric_limits<double>::quiet_NaN();
  const double u_old = turned.uOld();
  const double s = imu_->options.bias_window_sigma_deg_s / kDegPerRad;
  // Least-squares parabola f = a d^2 + b d + c through the five symmetric offsets.
  constexpr int kHalf = 2;
  double sum_df = 0.0, sum_dd = 0.0, sum_qf = 0.0, sum_qq = 0.0, best_f = -1.0, best_d = 0.0;
  constexpr double kMeanSquare = 2.0;  // mean of k^2 over k = -2..2
  for (int k = -kHalf; k <= kHalf; ++k) {
    const double d = k * s;
    const double f = objective->evaluate(
        k == 0 ? p1
               : Eigen::VectorXd(p1 + step_m * turned([&](double u) { return d * (u - u_old); })),
        nullptr);
    sum_df += k * f, sum_dd += double(k * k);
    const double q = double(k * k) - kMeanSquare;
    sum_qf += q * f, sum_qq += q * q;
    if (f > best_f) best_f = f, best_d = d;
  }
  objective->setParams(p1);
  const double a = sum_qf / sum_qq / (s * s), b = sum_df / sum_dd / s;
  if (!(a < 0)) return best_d;  // no peak inside: the best of the five
  return std::clamp(-b / (2 * a), -kHalf * s, kHalf * s);
}

Eigen::VectorXd Backend::scanStart(const MultiVolumeCost& cost, const Eigen::VectorXd& params0,
                                   int first_free, double step_m) {
  Eigen::VectorXd best = Eigen::VectorXd::Zero(params0.size());
  const double range = options_.yaw_scan_half_range_rad_s;
  const double outlier = options_.outlier_arc_min_rad_s;
  if (!(range > 0) && !(outlier > 0)) return best;
  TurnedStart turned(*this, params0, first_free, step_m);
  double best_cost = 0.0;
  if (!turned.valid() || !cost.startCost(best.data(), &best_cost)) return best;
  const double u_old = turned.uOld();
  auto consider = [&](const Eigen::VectorXd& x) {
    double c = 0.0;
    const bool better = cost.startCost(x.data(), &c) && c < best_cost;
    if (better) best_cost = c, best = x;
    return better;
  };
  if (range > 0) {
    double best_offset = 0.0;
    const int steps = int(std::floor(range / options_.yaw_scan_step_rad_s + 1e-9));
    for (int k = -steps; k <= steps; ++k) {
      if (k == 0) continue;
      const double offset = k * options_.yaw_scan_step_rad_s;
      if (consider(turned([&](double u) { return offset * (u - u_old); }))) best_offset = offset;
    }
    ++stats_.yaw_scans;
    if (best_offset != 0.0) ++stats_.yaw_scans_moved;
    stats_.yaw_scan_abs_sum_rad_s += std::abs(best_offset);
  }
  if (outlier > 0) {
    // A front-end arc (or the two halves of a split window) whose yaw rate stands out from the
    // arcs around it is either a real change of the steering or a window whose scan found the
    // wrong maximum (a flat, ambiguous scan). Its 0.3 s cannot tell; the back-end's volumes, with
    // a second of parallax, can: each such run of new arcs is tried at the rates interpolated
    // between its neighbouring arcs' (not the fit's: its smoothing spreads the outlier onto them),
    // and the start of least cost kept (compared without the deformation prior, which measures
    // the solver's moves from the start it is given). The solver alone stays in the basin of the
    // arcs' rates.
    struct Span {
      double a, b, rate;
      double middle() const { return 0.5 * (a + b); }
    };
    std::vector<Span> spans;
    for (const ArcEstimate& arc : arcs_) {
      const double a = spline_->toSplineTime(arc.t_start_ns);
      const double b = spline_->toSplineTime(arc.t_end_ns);
      if (!(b - a >= 1e-3) || b > spline_->validTo() + 1e-9 || a < spline_->validFrom()) continue;
      if (!spans.empty() && a < spans.back().b - 1e-6) continue;  // overlapping (not expected)
      spans.push_back({a, b, arc.omega});
    }
    // The heading the dead reckoning gains past u_old when the rates of arcs [j, k] change by
    // delta: steps over the arcs' windows, or (interpolate_arc_rates) ramps between the middles,
    // from zero at the neighbours' middles.
    auto headingOffset = [&](size_t j, size_t k, const std::vector<double>& delta, double u) {
      double h = 0.0;
      if (!options_.interpolate_arc_rates) {
        for (size_t i = j; i <= k; ++i) {
          const double a = std::max(spans[i].a, u_old);
          h += delta[i - j] * std::clamp(u - a, 0.0, std::max(0.0, spans[i].b - a));
        }
        return h;
      }
      // Piecewise-linear rate offset through (middle, delta): integral over [u_old, u].
      std::vector<std::pair<double, double>> r{{spans[j - 1].middle(), 0.0}};
      for (size_t i = j; i <= k; ++i) r.push_back({spans[i].middle(), delta[i - j]});
      r.push_back({spans[k + 1].middle(), 0.0});
      for (size_t i = 0; i + 1 < r.size(); ++i) {
        const double x0 = std::max(r[i].first, u_old), x1 = std::min(r[i + 1].first, u);
        if (!(x1 > x0)) continue;
        const double slope = (r[i + 1].second - r[i].second) / (r[i + 1].first - r[i].first);
        const double y0 = r[i].second + slope * (x0 - r[i].first);
        const double y1 = r[i].second + slope * (x1 - r[i].first);
        h += 0.5 * (y0 + y1) * (x1 - x0);
      }
      return h;
    };
    constexpr int kMaxRun = 2;  // a window and the two halves of a split window
    size_t tried = 0;
    bool replaced = false;
    double best_run_end = 0.0;  // spline time of the end of the run that won
    for (size_t j = 1; j < spans.size(); ++j) {
      if (spans[j].b <= u_old) continue;  // only the new part's arcs
      // A run between two arcs (at the newest end a bump cannot be told from a turn's onset or
      // end); the rates it is tried at: linear between the middles of the arcs around it.
      for (size_t k = j; k + 1 < std::min(spans.size(), j + kMaxRun + 1); ++k) {
        const Span &prev = spans[j - 1], &next = spans[k + 1];
        // It stands out if each of its arcs lies beyond the range of the arcs around it by the
        // threshold: a bump. A step between them (a turn's onset or end) is what the steering
        // does, and the volumes' cost is no judge there: it prefers the ramp that starts a turn
        // early (measured in process on street_long: ATE 0.07 -> 0.30 % when steps were tried).
        const double lo = std::min(prev.rate, next.rate), hi = std::max(prev.rate, next.rate);
        std::vector<double> delta;
        double least_beyond = std::numeric_limits<double>::infinity();
        for (size_t i = j; i <= k; ++i) {
          const double r = spans[i].rate;
          least_beyond = std::min(least_beyond, std::max(lo - r, r - hi));
          const double s = (spans[i].middle() - prev.middle()) / (next.middle() - prev.middle());
          delta.push_back(prev.rate + (next.rate - prev.rate) * s - r);
        }
        if (least_beyond < outlier) continue;
        ++tried;
        if (consider(turned([&](double u) { return headingOffset(j, k, delta, u); })))
          replaced = true, best_run_end = spans[k].b;
      }
    }
    stats_.outlier_runs_tried += tried;
    if (replaced) {
      ++stats_.outlier_runs_replaced;
      // The dead reckoning keeps the replaced rates: the next extension anchors it on the spline
      // after them only (fitAnchorOnSpline would fit its kink).
      overruled_until_ns_ = spline_->epochNs() + secToNs(best_run_end);
    }
  }
  return best;
}

int64_t Backend::finalUntil() const {
  if (!dead_reckoning_) return -1;
  return std::min(newest_arc_ns_, dead_reckoning_->ramped().endTime());
}

int64_t Backend::oldestArcTime() const {
  return dead_reckoning_ ? dead_reckoning_->startTime() : -1;
}

bool Backend::poseAt(int64_t t_ns, Pose3* T_odom_base, double* v, double* omega) const {
  if (!planarPoseAt(t_ns, T_odom_base, v, omega)) return false;
  if (tiltInPose()) *T_odom_base = withTilt(t_ns, *T_odom_base);
  return true;
}

bool Backend::planarPoseAt(int64_t t_ns, Pose3* T_odom_base, double* v, double* omega) const {
  if (!dead_reckoning_ || t_ns < dead_reckoning_->startTime() || t_ns > newest_arc_ns_)
    return false;
  constexpr int64_t kRateStep_ns = 20000000;  // central differences for the rates [ns]
  // Beyond spline_final_ns_, the dead reckoning anchored on the spline there; anchored at each
  // call, because a ramp's pose there changes until the next arc's middle has arrived.
  const ArcChain& chain = dead_reckoning_->ramped();
  Pose3 T_anchor = Pose3::Identity();
  if (spline_)
    T_anchor = anchorOnSplinePose(*spline_, spline_->toSplineTime(spline_final_ns_),
                                  chain.T_odom_base(spline_final_ns_));
  auto pose = [&](int64_t t) {
    if (spline_ && t <= spline_final_ns_) return spline_->T_odom_base(spline_->toSplineTime(t));
    return Pose3(T_anchor * chain.T_odom_base(t));
  };
  *T_odom_base = pose(t_ns);
  if (v || omega) {
    const int64_t a = std::max(dead_reckoning_->startTime(), t_ns - kRateStep_ns);
    const int64_t b = std::min(newest_arc_ns_, t_ns + kRateStep_ns);
    const double dt = dtSec(b, a);
    const Pose3 Ta = pose(a), Tb = pose(b);
    const Pose3 rel = Ta.inverse() * Tb;
    if (v) *v = dt > 0 ? rel.translation().head<2>().norm() / dt : 0.0;
    if (v && rel.translation().x() < 0) *v = -*v;
    if (omega) *omega = dt > 0 ? std::atan2(rel.linear()(1, 0), rel.linear()(0, 0)) / dt : 0.0;
  }
  return true;
}

Trajectory3 Backend::sampleTrajectory(double rate_hz) const {
  Trajectory3 out;
  if (!spline_ || !(rate_hz > 0)) return out;
  const int64_t t0 = spline_->epochNs(), t1 = processed_ns_;
  const int64_t step = std::max<int64_t>(1, secToNs(1.0 / rate_hz));
  for (int64_t t = t0; t <= t1; t += step)
    out.push_back({t, spline_->T_odom_base(spline_->toSplineTime(t))});
  if (out.empty() || out.back().t_ns < t1)
    out.push_back({t1, spline_->T_odom_base(spline_->toSplineTime(t1))});
  if (tiltInPose())
    for (auto& s : out) s.T = withTilt(s.t_ns, s.T);
  return out;
}

bool ContinuousOdometry::next(const Backend& backend, int64_t t_ns, Pose3* T_odom_base, double* v,
                              double* omega) {
  // Composed on the planar poses; the tilt (IMU) is the estimate at t_ns.
  Pose3 T_best;
  if (!backend.planarPoseAt(t_ns, &T_best, v, omega)) return false;
  Pose3 T_was;
  if (has_previous_ && t_ns > t_previous_ns_ &&
      backend.planarPoseAt(t_previous_ns_, &T_was, nullptr, nullptr)) {
    // The motion since the previous output as the back-end sees it now, on the output so far.
    *T_odom_base = Pose3(T_previous_ * (T_was.inverse() * T_best));
  } else {
    *T_odom_base = T_best;  // the first pose, or the previous one left the back-end's span
  }
  has_previous_ = true;
  t_previous_ns_ = t_ns;
  T_previous_ = *T_odom_base;
  if (backend.tiltInPose())
    T_odom_base->linear() = T_odom_base->linear() * backend.tiltAt(t_ns).rotation();
  return true;
}

}  // namespace vwe_vo
