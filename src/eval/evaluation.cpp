#include "vwe_vo/eval/evaluation.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <sstream>
#include <stdexcept>

namespace vwe_vo {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), format, v);
  return buf;
}

std::string rangeText(int64_t t0_ns, int64_t t1_ns) {
  return "[" + fmt("%.3f", nsToSec(t0_ns)) + ", " + fmt("%.3f", nsToSec(t1_ns)) + "] s";
}

/// Root mean square and median of the finite values; NaN if there are none.
double rmseOf(const std::vector<double>& v) {
  double sum = 0;
  int n = 0;
  for (double x : v)
    if (std::isfinite(x)) sum += x * x, ++n;
  return n > 0 ? std::sqrt(sum / n) : kNaN;
}

double medianOf(const std::vector<double>& v) {
  std::vector<double> f;
  for (double x : v)
    if (std::isfinite(x)) f.push_back(x);
  if (f.empty()) return kNaN;
  const size_t mid = f.size() / 2;
  std::nth_element(f.begin(), f.begin() + mid, f.end());
  const double upper = f[mid];
  if (f.size() % 2 == 1) return upper;
  return 0.5 * (*std::max_element(f.begin(), f.begin() + mid) + upper);
}

/// The time span both trajectories cover and the estimate's gaps (consecutive samples further
/// apart than max_gap_s): the estimate counts as untracked strictly inside a gap.
class Coverage {
 public:
  Coverage(const Trajectory3& gt, const Trajectory3& est, const EvaluationOptions& options) {
    if (gt.size() < 2)
      throw std::runtime_error("ground truth has " + std::to_string(gt.size()) +
                               " poses, need at least 2");
    if (est.size() < 2)
      throw std::runtime_error("estimate has " + std::to_string(est.size()) +
                               " poses, need at least 2");
    t0_ns_ = std::max(gt.front().t_ns, est.front().t_ns);
    t1_ns_ = std::min(gt.back().t_ns, est.back().t_ns);
    if (t1_ns_ <= t0_ns_)
      throw std::runtime_error("trajectories do not overlap: ground truth covers " +
                               rangeText(gt.front().t_ns, gt.back().t_ns) + ", estimate covers " +
                               rangeText(est.front().t_ns, est.back().t_ns));
    const int64_t max_gap_ns = secToNs(options.max_gap_s);
    for (size_t i = 1; i < est.size(); ++i)
      if (est[i].t_ns - est[i - 1].t_ns > max_gap_ns)
        gaps_.emplace_back(est[i - 1].t_ns, est[i].t_ns);
  }

  int64_t start() const { return t0_ns_; }
  int64_t end() const { return t1_ns_; }
  double durationSec() const { return dtSec(t1_ns_, t0_ns_); }

  /// True if [a_ns, b_ns] reaches strictly into a gap (a == b asks about one time).
  bool spansGap(int64_t a_ns, int64_t b_ns) const {
    for (const auto& g : gaps_)
      if (g.first < b_ns && g.second > a_ns) return true;
    return false;
  }

  void requireAtLeast(double delta_s) const {
    if (durationSec() < delta_s)
      throw std::runtime_error("trajectories overlap only over " + rangeText(t0_ns_, t1_ns_) +
                               " (" + fmt("%.3f", durationSec()) + " s), shorter than delta " +
                               fmt("%g", delta_s) + " s");
  }

 private:
  int64_t t0_ns_ = 0, t1_ns_ = 0;
  std::vector<std::pair<int64_t, int64_t>> gaps_;
};

Pose3 poseAt(const Trajectory3& traj, int64_t t_ns, const char* which) {
  Pose3 T;
  if (!interpolateTrajectory(traj, t_ns, &T))
    throw std::logic_error(std::string("evaluation: ") + which + " has no pose at " +
                           fmt("%.9f", nsToSec(t_ns)));
  return T;
}

/// Pair start times (and ATE sample times): t0 + k * step.
std::vector<int64_t> sampleTimes(int64_t t0_ns, int64_t last_ns, double step_s) {
  const int64_t step_ns = std::max<int64_t>(1, secToNs(step_s));
  std::vector<int64_t> times;
  for (int64_t t = t0_ns; t <= last_ns; t += step_ns) times.push_back(t);
  return times;
}

/// Swing-twist decomposition of R about z: R = swing * twist, twist about z by |yaw| and the
/// swing about a horizontal axis by tilt (the angle between R e_z and e_z).
void swingTwist(const Mat3& R, double* yaw_rad, double* tilt_rad) {
  const Quat q(R);
  *yaw_rad = std::abs(wrapAngle(2.0 * std::atan2(q.z(), q.w())));
  const double c = std::sqrt(q.w() * q.w() + q.z() * q.z());
  *tilt_rad = 2.0 * std::acos(std::min(1.0, c));
}

RpeResult rpeOver(const Trajectory3& gt, const Trajectory3& est, double delta_s,
                  const EvaluationOptions& options, const Coverage& cov) {
  cov.requireAtLeast(delta_s);
  RpeResult r;
  r.delta_s = delta_s;
  const int64_t delta_ns = secToNs(delta_s);
  std::vector<double> rot, trans, yaw, tilt;
  for (int64_t t : sampleTimes(cov.start(), cov.end() - delta_ns, options.pair_step_s)) {
    if (cov.spansGap(t, t + delta_ns)) {
      ++r.untracked_pairs;
      continue;
    }
    // Relative motion in the first pose's frame: T_rel = T(t)^-1 T(t + Delta).
    const Pose3 gt_rel =
        poseAt(gt, t, "ground truth").inverse() * poseAt(gt, t + delta_ns, "ground truth");
    const Pose3 est_rel =
        poseAt(est, t, "estimate").inverse() * poseAt(est, t + delta_ns, "estimate");
    RpePair p;
    p.t_ns = t;
    const Mat3 E = gt_rel.linear().transpose() * est_rel.linear();
    p.rot_err_deg_s = rotationAngle(E) * kDegPerRad / delta_s;
    swingTwist(E, &p.yaw_err_deg_s, &p.tilt_err_deg_s);
    p.yaw_err_deg_s *= kDegPerRad / delta_s;
    p.tilt_err_deg_s *= kDegPerRad / delta_s;
    if (gt_rel.translation().norm() < options.standstill_threshold_m) {
      ++r.standstill_pairs;
      p.trans_dir_err_deg_s = kNaN;
    } else if (est_rel.translation().norm() == 0.0) {
      // No direction to compare with: count it as the expected angle to a random direction.
      ++r.est_still_pairs;
      p.trans_dir_err_deg_s = 90.0 / delta_s;
    } else {
      p.trans_dir_err_deg_s =
          angleBetween(gt_rel.translation(), est_rel.translation()) * kDegPerRad / delta_s;
    }
    rot.push_back(p.rot_err_deg_s);
    yaw.push_back(p.yaw_err_deg_s);
    tilt.push_back(p.tilt_err_deg_s);
    trans.push_back(p.trans_dir_err_deg_s);
    r.series.push_back(p);
  }
  r.pairs = static_cast<int>(r.series.size());
  if (r.pairs == 0)
    throw std::runtime_error(
        "no RPE pair of " + fmt("%g", delta_s) + " s is tracked in the overlap " +
        rangeText(cov.start(), cov.end()) + " (" + std::to_string(r.untracked_pairs) +
        " pairs span estimate gaps longer than " + fmt("%g", options.max_gap_s) + " s)");
  r.rot_rmse_deg_s = rmseOf(rot);
  r.rot_median_deg_s = medianOf(rot);
  r.yaw_rmse_deg_s = rmseOf(yaw);
  r.yaw_median_deg_s = medianOf(yaw);
  r.tilt_rmse_deg_s = rmseOf(tilt);
  r.tilt_median_deg_s = medianOf(tilt);
  r.trans_dir_rmse_deg_s = rmseOf(trans);
  r.trans_dir_median_deg_s = medianOf(trans);
  return r;
}

/// Yaw of the body-frame rotation from t to t + h, over h: a finite-difference yaw rate [rad/s].
/// atan2 in yawOf wraps it, so it is right as long as |yaw rate| * h < pi.
double yawRate(const Trajectory3& traj, int64_t t_ns, int64_t h_ns, const char* which) {
  const Mat3 R_rel =
      poseAt(traj, t_ns, which).linear().transpose() * poseAt(traj, t_ns + h_ns, which).linear();
  return yawOf(R_rel) / nsToSec(h_ns);
}

double pathLength(const std::vector<Vec3>& p) {
  double d = 0;
  for (size_t i = 1; i < p.size(); ++i) d += (p[i] - p[i - 1]).norm();
  return d;
}

/// Estimate-covered time inside the ground truth's span (gaps > max_gap_s left out) / its duration.
double trackedFraction(const Trajectory3& gt, const Trajectory3& est, double max_gap_s) {
  const int64_t max_gap_ns = secToNs(max_gap_s);
  const int64_t g0 = gt.front().t_ns, g1 = gt.back().t_ns;
  int64_t covered_ns = 0;
  for (size_t i = 1; i < est.size(); ++i) {
    if (est[i].t_ns - est[i - 1].t_ns > max_gap_ns) continue;
    const int64_t a = std::max(est[i - 1].t_ns, g0), b = std::min(est[i].t_ns, g1);
    if (b > a) covered_ns += b - a;
  }
  return static_cast<double>(covered_ns) / static_cast<double>(g1 - g0);
}

nlohmann::json num(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

nlohmann::json rpeJson(const RpeResult& r) {
  nlohmann::json j = {{"delta_s", r.delta_s},
                      {"pairs", r.pairs},
                      {"standstill_pairs", r.standstill_pairs},
                      {"untracked_pairs", r.untracked_pairs},
                      {"est_still_pairs", r.est_still_pairs},
                      {"rot_rmse_deg_s", num(r.rot_rmse_deg_s)},
                      {"rot_median_deg_s", num(r.rot_median_deg_s)},
                      {"yaw_rmse_deg_s", num(r.yaw_rmse_deg_s)},
                      {"yaw_median_deg_s", num(r.yaw_median_deg_s)},
                      {"tilt_rmse_deg_s", num(r.tilt_rmse_deg_s)},
                      {"tilt_median_deg_s", num(r.tilt_median_deg_s)},
                      {"trans_dir_rmse_deg_s", num(r.trans_dir_rmse_deg_s)},
                      {"trans_dir_median_deg_s", num(r.trans_dir_median_deg_s)}};
  if (!r.error.empty()) j["error"] = r.error;
  return j;
}

std::string rpeKey(double delta_s) {
  return "rpe_" + fmt("%g", delta_s);
}

}  // namespace

void EvaluationOptions::validate() const {
  auto positive = [](double v, const char* name) {
    if (!std::isfinite(v) || v <= 0)
      throw std::invalid_argument(std::string("EvaluationOptions.") + name +
                                  " must be a positive number, got " + fmt("%g", v));
  };
  positive(delta_s, "delta_s");
  positive(pair_step_s, "pair_step_s");
  if (!std::isfinite(standstill_threshold_m) || standstill_threshold_m < 0)
    throw std::invalid_argument("EvaluationOptions.standstill_threshold_m must be >= 0, got " +
                                fmt("%g", standstill_threshold_m));
  positive(max_gap_s, "max_gap_s");
  positive(yaw_rate_dt_s, "yaw_rate_dt_s");
  positive(segment_m, "segment_m");
  positive(lag_max_s, "lag_max_s");
  positive(lag_resolution_s, "lag_resolution_s");
  positive(lag_sample_step_s, "lag_sample_step_s");
  if (lag_resolution_s > lag_max_s)
    throw std::invalid_argument("EvaluationOptions.lag_resolution_s must not exceed lag_max_s");
  for (double d : extra_deltas_s) positive(d, "extra_deltas_s[]");
}

Sim3 alignUmeyama(const std::vector<Vec3>& src, const std::vector<Vec3>& dst, bool with_scale) {
  if (src.size() != dst.size())
    throw std::invalid_argument("alignUmeyama: " + std::to_string(src.size()) + " source and " +
                                std::to_string(dst.size()) + " target points");
  if (src.size() < 3)
    throw std::invalid_argument("alignUmeyama: need at least 3 points, got " +
                                std::to_string(src.size()));
  const double n = static_cast<double>(src.size());
  Vec3 mu_src = Vec3::Zero(), mu_dst = Vec3::Zero();
  for (size_t i = 0; i < src.size(); ++i) mu_src += src[i], mu_dst += dst[i];
  mu_src /= n;
  mu_dst /= n;
  double var_src = 0;
  Mat3 cov = Mat3::Zero();  // (1/n) sum (dst - mu_dst)(src - mu_src)^T
  for (size_t i = 0; i < src.size(); ++i) {
    const Vec3 a = src[i] - mu_src;
    var_src += a.squaredNorm();
    cov += (dst[i] - mu_dst) * a.transpose();
  }
  var_src /= n;
  cov /= n;
  if (!(var_src > 0))
    throw std::runtime_error("alignUmeyama: source points have no spread (all equal)");

  const Eigen::JacobiSVD<Mat3> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  // Reflection fix: if U V^T would be a reflection, flip the axis of the smallest singular value.
  Vec3 s(1, 1, 1);
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0) s(2) = -1;
  Sim3 out;
  out.R = svd.matrixU() * s.asDiagonal() * svd.matrixV().transpose();
  out.scale = with_scale ? svd.singularValues().dot(s) / var_src : 1.0;
  out.t = mu_dst - out.scale * (out.R * mu_src);
  return out;
}

RpeResult computeRpe(const Trajectory3& gt, const Trajectory3& est, double delta_s,
                     const EvaluationOptions& options) {
  options.validate();
  if (!std::isfinite(delta_s) || delta_s <= 0)
    throw std::invalid_argument("computeRpe: delta_s must be positive");
  return rpeOver(gt, est, delta_s, options, Coverage(gt, est, options));
}

double yawRateLag(const Trajectory3& gt, const Trajectory3& est, const EvaluationOptions& options,
                  int* samples) {
  options.validate();
  const Coverage cov(gt, est, options);
  if (samples) *samples = 0;
  const int64_t h_ns = secToNs(options.yaw_rate_dt_s);
  const int64_t res_ns = std::max<int64_t>(1, secToNs(options.lag_resolution_s));
  const int n_lag = static_cast<int>(std::llround(options.lag_max_s / options.lag_resolution_s));
  const int64_t max_ns = n_lag * res_ns;
  // The truth's yaw rate on the lag grid, from the ground truth's start.
  const int64_t g0 = gt.front().t_ns, g_last = gt.back().t_ns - h_ns;
  if (g_last <= g0) return kNaN;
  std::vector<double> w_gt(static_cast<size_t>((g_last - g0) / res_ns) + 1);
  for (size_t k = 0; k < w_gt.size(); ++k)
    w_gt[k] = yawRate(gt, g0 + static_cast<int64_t>(k) * res_ns, h_ns, "ground truth");
  // Estimate samples on the same grid whose truth is available at every shift.
  const int64_t step_ns =
      std::max<int64_t>(res_ns, secToNs(options.lag_sample_step_s) / res_ns * res_ns);
  std::vector<double> w_est;
  std::vector<size_t> index;
  const int64_t first =
      g0 + ((std::max(cov.start(), g0 + max_ns) - g0 + res_ns - 1) / res_ns) * res_ns;
  for (int64_t t = first; t + h_ns <= cov.end() && t + max_ns <= g_last; t += step_ns) {
    if (cov.spansGap(t, t + h_ns)) continue;
    w_est.push_back(yawRate(est, t, h_ns, "estimate"));
    index.push_back(static_cast<size_t>((t - g0) / res_ns));
  }
  if (samples) *samples = static_cast<int>(w_est.size());
  if (w_est.size() < 10) return kNaN;
  // A truth without yaw-rate variation has no lag.
  double mean = 0, var = 0;
  for (size_t i : index) mean += w_gt[i];
  mean /= index.size();
  for (size_t i : index) var += (w_gt[i] - mean) * (w_gt[i] - mean);
  if (!(var / index.size() > 1e-8)) return kNaN;
  // Squared error of the estimate to the truth shifted by tau = j * res: w_gt(t - tau).
  std::vector<double> cost(2 * n_lag + 1);
  for (int j = -n_lag; j <= n_lag; ++j) {
    double c = 0;
    for (size_t i = 0; i < index.size(); ++i) {
      const double d = w_est[i] - w_gt[static_cast<size_t>(static_cast<int64_t>(index[i]) - j)];
      c += d * d;
    }
    cost[static_cast<size_t>(j + n_lag)] = c;
  }
  const size_t best =
      static_cast<size_t>(std::min_element(cost.begin(), cost.end()) - cost.begin());
  double shift = static_cast<double>(best);
  if (best > 0 && best + 1 < cost.size()) {
    const double a = cost[best - 1], b = cost[best], c = cost[best + 1], curv = a - 2 * b + c;
    if (curv > 0) shift += 0.5 * (a - c) / curv;
  }
  return (shift - n_lag) * nsToSec(res_ns);
}

Trajectory3 planarProjection(const Trajectory3& trajectory) {
  Trajectory3 out;
  out.reserve(trajectory.size());
  for (const StampedPose& p : trajectory) {
    const Vec3& t = p.T.translation();
    out.push_back({p.t_ns, planarPose(t.x(), t.y(), yawOf(p.T.linear()))});
  }
  return out;
}

EvaluationResult evaluate(const Trajectory3& gt, const Trajectory3& est,
                          const EvaluationOptions& options) {
  options.validate();
  const Coverage cov(gt, est, options);
  EvaluationResult res;
  res.gt_start_ns = gt.front().t_ns;
  res.gt_end_ns = gt.back().t_ns;
  res.est_start_ns = est.front().t_ns;
  res.est_end_ns = est.back().t_ns;

  res.rpe = rpeOver(gt, est, options.delta_s, options, cov);
  const RpeResult floor = rpeOver(gt, planarProjection(gt), options.delta_s, options, cov);
  res.planar_floor_rot_rmse_deg_s = floor.rot_rmse_deg_s;
  res.planar_floor_tilt_rmse_deg_s = floor.tilt_rmse_deg_s;
  res.planar_floor_trans_dir_rmse_deg_s = floor.trans_dir_rmse_deg_s;
  for (double d : options.extra_deltas_s) {
    try {
      res.rpe_extra.push_back(rpeOver(gt, est, d, options, cov));
    } catch (const std::runtime_error& e) {
      RpeResult r;
      r.delta_s = d;
      r.rot_rmse_deg_s = r.rot_median_deg_s = r.trans_dir_rmse_deg_s = r.trans_dir_median_deg_s =
          r.yaw_rmse_deg_s = r.yaw_median_deg_s = r.tilt_rmse_deg_s = r.tilt_median_deg_s = kNaN;
      r.error = e.what();
      res.rpe_extra.push_back(r);
    }
  }

  // Yaw rate at the pair times, over yaw_rate_dt_s.
  const int64_t h_ns = secToNs(options.yaw_rate_dt_s);
  for (const RpePair& p : res.rpe.series) {
    double err = kNaN;
    if (p.t_ns + h_ns <= cov.end() && !cov.spansGap(p.t_ns, p.t_ns + h_ns)) {
      const double d =
          yawRate(est, p.t_ns, h_ns, "estimate") - yawRate(gt, p.t_ns, h_ns, "ground truth");
      err = d * kDegPerRad;
      ++res.yaw_rate_samples;
    }
    res.yaw_rate_err_deg_s.push_back(err);
  }
  res.yaw_rate_rmse_deg_s = rmseOf(res.yaw_rate_err_deg_s);
  res.yaw_rate_lag_s = yawRateLag(gt, est, options, &res.yaw_rate_lag_samples);

  // ATE at tracked grid times over the overlap.
  std::vector<int64_t> times;
  std::vector<Vec3> p_gt, p_est;
  for (int64_t t : sampleTimes(cov.start(), cov.end(), options.pair_step_s)) {
    if (cov.spansGap(t, t)) continue;
    times.push_back(t);
    p_gt.push_back(poseAt(gt, t, "ground truth").translation());
    p_est.push_back(poseAt(est, t, "estimate").translation());
  }
  res.ate_samples = static_cast<int>(times.size());
  if (times.size() < 3)
    throw std::runtime_error("only " + std::to_string(times.size()) +
                             " tracked samples in the overlap " +
                             rangeText(cov.start(), cov.end()) + ", need 3 for the alignment");
  res.alignment = alignUmeyama(p_est, p_gt, true);
  res.ate_scale = res.alignment.scale;
  const Sim3 rigid = alignUmeyama(p_est, p_gt, false);
  std::vector<Vec3> p_aligned(p_est.size());
  double se_sim = 0, se_rigid = 0;
  for (size_t i = 0; i < p_est.size(); ++i) {
    p_aligned[i] = res.alignment.apply(p_est[i]);
    se_sim += (p_aligned[i] - p_gt[i]).squaredNorm();
    se_rigid += (rigid.apply(p_est[i]) - p_gt[i]).squaredNorm();
  }
  res.ate_rmse_m = std::sqrt(se_sim / p_est.size());
  res.ate_se3_rmse_m = std::sqrt(se_rigid / p_est.size());

  // Ground-truth path length over the overlap, from its own samples (not the grid).
  std::vector<Vec3> path{poseAt(gt, cov.start(), "ground truth").translation()};
  for (const StampedPose& sp : gt)
    if (sp.t_ns > cov.start() && sp.t_ns < cov.end()) path.push_back(sp.T.translation());
  path.push_back(poseAt(gt, cov.end(), "ground truth").translation());
  res.path_length_m = pathLength(path);
  res.ate_percent_of_path =
      res.path_length_m > 0 ? 100.0 * res.ate_rmse_m / res.path_length_m : kNaN;
  res.tracked_fraction = trackedFraction(gt, est, options.max_gap_s);

  // Scale drift: segments of segment_m of ground-truth distance; a gap ends a segment unfinished.
  ScaleDrift& sd = res.scale_drift;
  sd.segment_m = options.segment_m;
  double d_gt = 0, d_est = 0;
  for (size_t i = 1; i < times.size(); ++i) {
    if (cov.spansGap(times[i - 1], times[i])) {
      d_gt = d_est = 0;
      continue;
    }
    d_gt += (p_gt[i] - p_gt[i - 1]).norm();
    d_est += (p_aligned[i] - p_aligned[i - 1]).norm();
    if (d_gt >= options.segment_m) {
      sd.ratios.push_back(d_est / d_gt);
      d_gt = d_est = 0;
    }
  }
  sd.min_ratio = sd.max_ratio = sd.max_abs_deviation = kNaN;
  if (!sd.ratios.empty()) {
    sd.min_ratio = *std::min_element(sd.ratios.begin(), sd.ratios.end());
    sd.max_ratio = *std::max_element(sd.ratios.begin(), sd.ratios.end());
    sd.max_abs_deviation = std::max(std::abs(sd.min_ratio - 1.0), std::abs(sd.max_ratio - 1.0));
  }
  return res;
}

nlohmann::json toJson(const EvaluationResult& r, bool with_series) {
  nlohmann::json j;
  j["rpe"] = rpeJson(r.rpe);
  for (const RpeResult& e : r.rpe_extra) j[rpeKey(e.delta_s)] = rpeJson(e);
  j["yaw_rate_rmse_deg_s"] = num(r.yaw_rate_rmse_deg_s);
  j["yaw_rate_samples"] = r.yaw_rate_samples;
  j["yaw_rpe_rmse_deg_s"] = num(r.rpe.yaw_rmse_deg_s);
  j["yaw_rpe_median_deg_s"] = num(r.rpe.yaw_median_deg_s);
  j["tilt_rpe_rmse_deg_s"] = num(r.rpe.tilt_rmse_deg_s);
  j["yaw_rate_lag_s"] = num(r.yaw_rate_lag_s);
  j["planar_floor"] = {{"rot_rmse_deg_s", num(r.planar_floor_rot_rmse_deg_s)},
                       {"tilt_rmse_deg_s", num(r.planar_floor_tilt_rmse_deg_s)},
                       {"trans_dir_rmse_deg_s", num(r.planar_floor_trans_dir_rmse_deg_s)}};
  j["yaw_rate_lag_samples"] = r.yaw_rate_lag_samples;
  j["ate"] = {{"rmse_m", num(r.ate_rmse_m)},
              {"percent_of_path", num(r.ate_percent_of_path)},
              {"scale", num(r.ate_scale)},
              {"se3_rmse_m", num(r.ate_se3_rmse_m)},
              {"samples", r.ate_samples}};
  j["path_length_m"] = r.path_length_m;
  j["tracked_fraction"] = r.tracked_fraction;
  j["time_range_s"] = {{"ground_truth", {nsToSec(r.gt_start_ns), nsToSec(r.gt_end_ns)}},
                       {"estimate", {nsToSec(r.est_start_ns), nsToSec(r.est_end_ns)}}};
  nlohmann::json ratios = nlohmann::json::array();
  for (double x : r.scale_drift.ratios) ratios.push_back(num(x));
  j["scale_drift"] = {{"segment_m", r.scale_drift.segment_m},
                      {"segments", r.scale_drift.ratios.size()},
                      {"min_ratio", num(r.scale_drift.min_ratio)},
                      {"max_ratio", num(r.scale_drift.max_ratio)},
                      {"max_abs_deviation", num(r.scale_drift.max_abs_deviation)},
                      {"ratios", ratios}};
  if (with_series) {
    nlohmann::json t = nlohmann::json::array(), rot = nlohmann::json::array(),
                   trans = nlohmann::json::array(), yaw = nlohmann::json::array();
    for (size_t i = 0; i < r.rpe.series.size(); ++i) {
      const RpePair& p = r.rpe.series[i];
      t.push_back(dtSec(p.t_ns, r.gt_start_ns));
      rot.push_back(num(p.rot_err_deg_s));
      trans.push_back(num(p.trans_dir_err_deg_s));
      yaw.push_back(i < r.yaw_rate_err_deg_s.size() ? num(r.yaw_rate_err_deg_s[i])
                                                    : nlohmann::json(nullptr));
    }
    j["series"] = {{"t_s", t},
                   {"rot_err_deg_s", rot},
                   {"trans_dir_err_deg_s", trans},
                   {"yaw_rate_err_deg_s", yaw}};
  }
  return j;
}

void writeSeriesCsv(const std::string& path, const EvaluationResult& r) {
  std::unique_ptr<FILE, int (*)(FILE*)> f(std::fopen(path.c_str(), "w"), &std::fclose);
  if (!f) throw std::runtime_error("cannot write " + path + ": " + std::strerror(errno));
  std::fprintf(
      f.get(),
      "t_s,rot_err_deg_s,trans_dir_err_deg_s,yaw_rate_err_deg_s,yaw_err_deg_s,tilt_err_deg_s\n");
  for (size_t i = 0; i < r.rpe.series.size(); ++i) {
    const RpePair& p = r.rpe.series[i];
    const double yaw = i < r.yaw_rate_err_deg_s.size() ? r.yaw_rate_err_deg_s[i] : kNaN;
    std::fprintf(f.get(), "%.6f,%.9g,%.9g,%.9g,%.9g,%.9g\n", dtSec(p.t_ns, r.gt_start_ns),
                 p.rot_err_deg_s, p.trans_dir_err_deg_s, yaw, p.yaw_err_deg_s, p.tilt_err_deg_s);
  }
  if (std::ferror(f.get())) throw std::runtime_error("error writing " + path);
}

std::string formatTable(const EvaluationResult& r) {
  std::vector<const RpeResult*> rpes{&r.rpe};
  for (const RpeResult& e : r.rpe_extra) rpes.push_back(&e);
  std::ostringstream os;
  auto row = [&os](const std::string& label) {
    os << "  " << label << std::string(label.size() < 30 ? 30 - label.size() : 1, ' ');
  };
  auto cell = [&os](const std::string& text) {
    os << text << std::string(text.size() < 22 ? 22 - text.size() : 1, ' ');
  };
  auto pair2 = [](double a, double b) { return fmt("%.3f", a) + " / " + fmt("%.3f", b); };

  os << "ground truth " << rangeText(r.gt_start_ns, r.gt_end_ns) << ", estimate "
     << rangeText(r.est_start_ns, r.est_end_ns) << "\n";
  row("relative pose error");
  for (const RpeResult* e : rpes) cell("Delta " + fmt("%g", e->delta_s) + " s");
  os << "\n";
  row("pairs (standstill, untracked)");
  for (const RpeResult* e : rpes)
    cell(std::to_string(e->pairs) + " (" + std::to_string(e->standstill_pairs) + ", " +
         std::to_string(e->untracked_pairs) + ")");
  os << "\n";
  row("rotation RMSE / median");
  for (const RpeResult* e : rpes) cell(pair2(e->rot_rmse_deg_s, e->rot_median_deg_s) + " deg/s");
  os << "\n";
  row("  yaw part RMSE / median");
  for (const RpeResult* e : rpes) cell(pair2(e->yaw_rmse_deg_s, e->yaw_median_deg_s) + " deg/s");
  os << "\n";
  row("  tilt part RMSE / median");
  for (const RpeResult* e : rpes) cell(pair2(e->tilt_rmse_deg_s, e->tilt_median_deg_s) + " deg/s");
  os << "\n";
  row("trans. dir. RMSE / median");
  for (const RpeResult* e : rpes)
    cell(pair2(e->trans_dir_rmse_deg_s, e->trans_dir_median_deg_s) + " deg/s");
  os << "\n";
  for (const RpeResult* e : rpes)
    if (!e->error.empty())
      os << "  (Delta " << fmt("%g", e->delta_s) << " s: " << e->error << ")\n";
  row("planar floor (flat truth)");
  os << "rotation " << fmt("%.3f", r.planar_floor_rot_rmse_deg_s) << ", tilt "
     << fmt("%.3f", r.planar_floor_tilt_rmse_deg_s) << ", trans. dir. "
     << fmt("%.3f", r.planar_floor_trans_dir_rmse_deg_s) << " deg/s (Delta "
     << fmt("%g", r.rpe.delta_s) << " s)\n";
  row("yaw-rate RMSE");
  os << fmt("%.3f", r.yaw_rate_rmse_deg_s) << " deg/s (" << r.yaw_rate_samples << " samples)\n";
  row("yaw-rate lag");
  os << fmt("%+.3f", r.yaw_rate_lag_s) << " s (" << r.yaw_rate_lag_samples
     << " samples; > 0: the estimate is late)\n";
  row("ATE after Sim(3)");
  os << fmt("%.4f", r.ate_rmse_m) << " m = " << fmt("%.3f", r.ate_percent_of_path)
     << " % of path, scale " << fmt("%.5f", r.ate_scale) << "\n";
  row("ATE after SE(3)");
  os << fmt("%.4f", r.ate_se3_rmse_m) << " m\n";
  row("ground-truth path length");
  os << fmt("%.2f", r.path_length_m) << " m\n";
  row("tracked fraction");
  os << fmt("%.1f", 100.0 * r.tracked_fraction) << " %\n";
  row("scale drift per " + fmt("%g", r.scale_drift.segment_m) + " m");
  if (r.scale_drift.ratios.empty())
    os << "no complete segment\n";
  else
    os << "ratio " << fmt("%.4f", r.scale_drift.min_ratio) << " .. "
       << fmt("%.4f", r.scale_drift.max_ratio) << ", max |ratio - 1| "
       << fmt("%.4f", r.scale_drift.max_abs_deviation) << " (" << r.scale_drift.ratios.size()
       << " segments)\n";
  return os.str();
}

bool meanYawRate(const Trajectory3& gt, int64_t t0_ns, int64_t t1_ns, double* rate_rad_s) {
  Pose3 a, b;
  if (t1_ns <= t0_ns || !interpolateTrajectory(gt, t0_ns, &a) ||
      !interpolateTrajectory(gt, t1_ns, &b))
    return false;
  *rate_rad_s = yawOf(a.linear().transpose() * b.linear()) / dtSec(t1_ns, t0_ns);
  return true;
}

WindowYawRateResult evaluateWindowYawRates(const Trajectory3& gt,
                                           const std::vector<WindowYawRate>& windows) {
  WindowYawRateResult r;
  for (const WindowYawRate& w : windows) {
    if (w.standstill) {
      ++r.standstill_windows;
      continue;
    }
    double truth = 0.0;
    if (!meanYawRate(gt, w.t_start_ns, w.t_end_ns, &truth)) {
      ++r.outside;
      continue;
    }
    r.err_deg_s.push_back((w.omega_rad_s - truth) * kDegPerRad);
  }
  r.windows = r.err_deg_s.size();
  std::vector<double> abs_err;
  for (double e : r.err_deg_s) abs_err.push_back(std::abs(e));
  r.rmse_deg_s = rmseOf(r.err_deg_s);
  r.median_abs_deg_s = medianOf(abs_err);
  r.max_abs_deg_s = abs_err.empty() ? 0.0 : *std::max_element(abs_err.begin(), abs_err.end());
  return r;
}

std::vector<WindowYawRate> readArcsCsv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open " + path);
  std::string line;
  if (!std::getline(in, line)) throw std::runtime_error(path + ": empty file");
  std::vector<std::string> header;
  std::stringstream hs(line);
  for (std::string c; std::getline(hs, c, ',');) header.push_back(c);
  auto column = [&](const std::string& name) {
    const auto it = std::find(header.begin(), header.end(), name);
    if (it == header.end()) throw std::runtime_error(path + ":1: no column '" + name + "'");
    return size_t(it - header.begin());
  };
  // The front-end's own yaw rate: without the roll where the file has it (windows refined at a
  // roll rate hand the back-end another).
  const bool has_without_roll =
      std::find(header.begin(), header.end(), "omega_without_roll") != header.end();
  const size_t c0 = column("t_start"), c1 = column("t_end"),
               cw = column(has_without_roll ? "omega_without_roll" : "omega"),
               cs = column("status");
  std::vector<WindowYawRate> out;
  int line_number = 1;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.empty()) continue;
    std::vector<std::string> f;
    std::stringstream ls(line);
    for (std::string c; std::getline(ls, c, ',');) f.push_back(c);
    if (f.size() < header.size())
      throw std::runtime_error(path + ":" + std::to_string(line_number) + ": expected " +
                               std::to_string(header.size()) + " columns, got " +
                               std::to_string(f.size()));
    WindowYawRate w;
    // Times are int64 nanoseconds: a stamp beyond +-9.2e9 s (or not finite) cannot be held.
    const auto time = [&](const std::string& text) {
      const double t_s = std::stod(text);
      if (!(std::abs(t_s) < 9.2e9))
        throw std::runtime_error(path + ":" + std::to_string(line_number) + ": time " + text +
                                 " s is outside the representable range (|t| < 9.2e9 s)");
      return secToNs(t_s);
    };
    try {
      w.t_start_ns = time(f[c0]);
      w.t_end_ns = time(f[c1]);
      w.omega_rad_s = std::stod(f[cw]);
    } catch (const std::runtime_error&) {
      throw;
    } catch (const std::exception&) {
      throw std::runtime_error(path + ":" + std::to_string(line_number) +
                               ": malformed number in '" + line + "'");
    }
    w.standstill = f[cs] == "STANDSTILL";
    out.push_back(w);
  }
  return out;
}

nlohmann::json toJson(const WindowYawRateResult& r) {
  return {{"windows", r.windows},
          {"standstill_windows", r.standstill_windows},
          {"outside_ground_truth", r.outside},
          {"rmse_deg_s", r.rmse_deg_s},
          {"median_abs_deg_s", r.median_abs_deg_s},
          {"max_abs_deg_s", r.max_abs_deg_s}};
}

}  // namespace vwe_vo
