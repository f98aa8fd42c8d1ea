// Trajectory accuracy against ground truth (docs/evaluation.md): relative pose error
// over a fixed interval, yaw-rate error, ATE after Sim(3) Umeyama alignment, scale drift per
// distance segment and the tracked fraction. Both trajectories are poses of base_link in their
// own world frame (the frames may differ by a similarity; RPE and yaw rate do not depend on it).
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "vwe_vo/common/math.h"
#include "vwe_vo/io/trajectory_io.h"

namespace vwe_vo {

struct EvaluationOptions {
  double delta_s = 1.0;       // RPE interval Delta [s]
  double pair_step_s = 0.05;  // spacing of RPE pair start times and ATE samples [s]
  double standstill_threshold_m =
      0.01;                    // |t_gt_rel| below this: pair left out of translation RPE [m]
  double max_gap_s = 0.5;      // estimate samples further apart than this: untracked [s]
  double yaw_rate_dt_s = 0.1;  // interval of the finite-difference yaw rate [s]
  double segment_m = 10.0;     // ground-truth distance per scale-drift segment [m]
  std::vector<double> extra_deltas_s = {
      0.5};                         // further RPE intervals reported as "rpe_<delta>" [s]
  double lag_max_s = 1.0;           // yaw-rate lag searched within +-lag_max_s [s]
  double lag_resolution_s = 0.001;  // grid of the lag search (then refined by a parabola) [s]
  double lag_sample_step_s = 0.01;  // spacing of the yaw-rate samples compared [s]

  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

/// Similarity transform y = scale * R * x + t.
struct Sim3 {
  double scale = 1.0;
  Mat3 R = Mat3::Identity();
  Vec3 t = Vec3::Zero();
  Vec3 apply(const Vec3& x) const { return scale * (R * x) + t; }
};

/// Least-squares similarity (or rigid motion if !with_scale) mapping src onto dst (Umeyama 1991,
/// with the reflection fix, so R is always a rotation). Throws std::invalid_argument on size
/// mismatch or fewer than 3 points, std::runtime_error if src has no spread.
Sim3 alignUmeyama(const std::vector<Vec3>& src, const std::vector<Vec3>& dst,
                  bool with_scale = true);

/// One RPE pair (t, t + Delta). trans_dir_err_deg_s is NaN for standstill pairs.
struct RpePair {
  int64_t t_ns = 0;
  double rot_err_deg_s = 0;
  double trans_dir_err_deg_s = 0;
  // Swing-twist split of the rotation error E = R_gt_rel^T R_est_rel about base_link's z axis:
  // the twist (heading-change error) and the swing (how far E tilts the vertical).
  double yaw_err_deg_s = 0;
  double tilt_err_deg_s = 0;
};

struct RpeResult {
  double delta_s = 0;
  int pairs = 0;             // pairs evaluated (both ends tracked, no estimate gap in between)
  int standstill_pairs = 0;  // of those, left out of the translation statistic
  int untracked_pairs = 0;   // pair start times in the overlap skipped for an estimate gap
  int est_still_pairs = 0;   // ground truth moved, the estimate did not: direction error 90 deg
  std::string error;         // why no pair could be evaluated (only for extra deltas); else empty
  double rot_rmse_deg_s = 0, rot_median_deg_s = 0;
  double yaw_rmse_deg_s = 0, yaw_median_deg_s = 0;              // planar part of the rotation error
  double tilt_rmse_deg_s = 0, tilt_median_deg_s = 0;            // roll/pitch part
  double trans_dir_rmse_deg_s = 0, trans_dir_median_deg_s = 0;  // NaN if every pair stood still
  std::vector<RpePair> series;
};

/// Scale ratios (aligned estimated distance / true distance) over consecutive segments of
/// segment_m metres of ground-truth distance. Empty when the sequence is shorter than a segment.
struct ScaleDrift {
  double segment_m = 0;
  std::vector<double> ratios;
  double min_ratio = 0, max_ratio = 0, max_abs_deviation = 0;  // NaN when ratios is empty
};

struct EvaluationResult {
  RpeResult rpe;                     // at options.delta_s
  std::vector<RpeResult> rpe_extra;  // at options.extra_deltas_s that fit into the overlap
  double yaw_rate_rmse_deg_s = 0;
  int yaw_rate_samples = 0;
  // Time shift of the truth's yaw rate (within +-lag_max_s) that fits the estimate's best in the
  // least-squares sense: > 0 the estimate lags behind, < 0 it is early. NaN if the truth's yaw
  // rate does not vary or fewer than 10 samples are tracked.
  double yaw_rate_lag_s = 0;
  int yaw_rate_lag_samples = 0;
  std::vector<double>
      yaw_rate_err_deg_s;  // estimated minus true, at rpe.series times (NaN if untracked)
  double ate_rmse_m = 0;
  double ate_percent_of_path = 0;  // ate_rmse_m / path_length_m * 100
  double ate_scale = 1;            // scale of the Sim(3) that aligns the estimate to ground truth
  double ate_se3_rmse_m = 0;       // the same after a rigid (no scale) alignment
  int ate_samples = 0;
  Sim3 alignment;               // estimate world -> ground-truth world
  double path_length_m = 0;     // ground-truth distance over the evaluated overlap
  double tracked_fraction = 0;  // estimate-covered time (gaps > max_gap_s excluded) / gt duration
  int64_t gt_start_ns = 0, gt_end_ns = 0, est_start_ns = 0, est_end_ns = 0;
  ScaleDrift scale_drift;
  // The RPE at options.delta_s of the truth's own planar projection (x, y and yaw of each
  // ground-truth pose, z = 0, no roll or pitch) on the same pairs: what any planar estimate
  // scores at best. Zero for a planar truth; on a body that pitches and rolls it is the part of
  // the rotation and translation-direction errors that only a 3D estimate can remove.
  double planar_floor_rot_rmse_deg_s = 0, planar_floor_tilt_rmse_deg_s = 0,
         planar_floor_trans_dir_rmse_deg_s = 0;
};

/// Relative pose error over delta_s with the pair sampling, standstill and gap rules of options.
/// Throws std::runtime_error if the trajectories do not overlap, overlap for less than delta_s,
/// or no pair is tracked.
RpeResult computeRpe(const Trajectory3& gt, const Trajectory3& est, double delta_s,
                     const EvaluationOptions& options);

/// The yaw-rate lag alone (see EvaluationResult::yaw_rate_lag_s); *samples gets the count.
double yawRateLag(const Trajectory3& gt, const Trajectory3& est, const EvaluationOptions& options,
                  int* samples = nullptr);

/// Each pose of `trajectory` projected onto the ground plane: x, y and yaw kept, z, roll and
/// pitch zero.
Trajectory3 planarProjection(const Trajectory3& trajectory);

/// Every metric above. Throws like computeRpe (at options.delta_s).
EvaluationResult evaluate(const Trajectory3& gt, const Trajectory3& est,
                          const EvaluationOptions& options);

/// JSON with the keys listed in docs/evaluation.md; NaN becomes null. "series" only if with_series.
nlohmann::json toJson(const EvaluationResult& result, bool with_series = false);

/// A front-end window: its interval and the yaw rate estimated for it.
struct WindowYawRate {
  int64_t t_start_ns = 0, t_end_ns = 0;
  double omega_rad_s = 0.0;
  bool standstill = false;  // reported as standstill: excluded, counted
};
/// Yaw-rate error per window (docs/evaluation.md, "yaw rate"): the estimate against
/// the ground truth's mean yaw rate over the same window, (yaw(t_end) - yaw(t_start)) / length.
struct WindowYawRateResult {
  size_t windows = 0, standstill_windows = 0, outside = 0;
  double rmse_deg_s = 0.0, median_abs_deg_s = 0.0, max_abs_deg_s = 0.0;
  std::vector<double> err_deg_s;  // per evaluated window
};
WindowYawRateResult evaluateWindowYawRates(const Trajectory3& gt,
                                           const std::vector<WindowYawRate>& windows);
/// The ground truth's mean yaw rate over [t0, t1], (yaw(t1) - yaw(t0)) / (t1 - t0) [rad/s];
/// false if t1 <= t0 or the truth does not cover both ends.
bool meanYawRate(const Trajectory3& gt, int64_t t0_ns, int64_t t1_ns, double* rate_rad_s);
/// Reads the front-end's arcs.csv (columns t_start, t_end, omega_without_roll or else omega,
/// status by header name).
std::vector<WindowYawRate> readArcsCsv(const std::string& path);
nlohmann::json toJson(const WindowYawRateResult& result);

/// CSV of the main RPE series: `t_s,rot_err_deg_s,trans_dir_err_deg_s,yaw_rate_err_deg_s`
/// (t_s = pair start since the first ground-truth pose, nan where left out). Throws on I/O error.
void writeSeriesCsv(const std::string& path, const EvaluationResult& result);

/// A readable multi-line table of the result.
std::string formatTable(const EvaluationResult& result);

}  // namespace vwe_vo
