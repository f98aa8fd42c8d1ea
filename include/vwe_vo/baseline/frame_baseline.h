// The frame-based baseline of the paper's Table I: KLT feature tracks between consecutive APS
// frames and the 1-point Ackermann solution of Scaramuzza et al. (2009) with RANSAC, chained
// into a dead-reckoned trajectory with the same arc model as the event front-end.
//
// 1-point solver. Between two frames base_link moves on a planar arc: yaw theta, translation
// direction theta/2, arc length s = v * dt (v from odometry or the nominal speed, exactly as the
// event front-end; the arc is arcT_Cr_Ct(omega = theta / dt, v, dt) of ackermann_arc.h). The
// camera is not on the rear axle, so its motion T_Cr_Ct(theta) = T_base_cam^-1 * arc(theta) *
// T_base_cam has a theta-dependent offset term (R(theta) - I) t_base_cam that depends on s: each
// correspondence (bearing f_r in frame r, f_t in frame t) gives theta as a root of the full
// epipolar constraint e(theta) = f_r . (t(theta) x R(theta) f_t) = 0, found by a 1-D search
// (grid bracketing + safeguarded Newton), exact for any offset. For comparison, the closed form
// of the on-axle case: With a = R_base_cam f_r and b = R_base_cam f_t (vehicle axes)
// and the camera on the axle, e = s_h (a_x b_z + a_z b_x) + c_h (a_z b_y - a_y b_z) with
// s_h = sin(theta/2), c_h = cos(theta/2), hence theta = 2 atan((a_y b_z - a_z b_y) / (a_x b_z + a_z
// b_x)). (with our 0.10 m offset it is off by up to ~1e-2 rad per track at turtlebot speeds, see
// the tests). RANSAC tries the per-track thetas, scores them by MSAC on the Sampson distance in
// pixels and refines theta over the inliers (Gauss-Newton on their Sampson residuals, last round
// trimmed at 3 MAD sigmas).
#pragma once

#include <cstdint>
#include <deque>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "vwe_vo/common/math.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/trajectory/ackermann_arc.h"
#include "vwe_vo/trajectory/dead_reckoning.h"
#include "vwe_vo/trajectory/stamped_trajectory.h"

namespace vwe_vo {

struct FrameBaselineOptions {
  int max_features = 300;            // features kept per frame (detection tops up to this) [-]
  double quality_level = 0.01;       // goodFeaturesToTrack quality, relative to the best corner [-]
  double min_distance_px = 8.0;      // minimum distance between features [px]
  int klt_window_px = 21;            // pyramidal KLT window side [px]
  int klt_levels = 3;                // pyramid levels above the base [-]
  double max_fb_error_px = 0.5;      // forward-backward KLT check [px]
  int border_px = 5;                 // features closer to the border are dropped [px]
  int min_tracks = 20;               // fewer surviving tracks: LOST [-]
  int min_inliers = 12;              // fewer RANSAC inliers: LOST [-]
  double min_inlier_fraction = 0.3;  // smaller inlier fraction: LOST [-]
  double inlier_threshold_px = 1.0;  // Sampson distance of an inlier [px]
  int max_hypotheses = 200;          // RANSAC hypotheses (per-track thetas) tried at most [-]
  double omega_max_rad_s = 3.0;      // |theta| / dt beyond this: hypothesis refused [rad/s]
  double nominal_speed_mps = 0.4;    // speed when no odometry is given [m/s]
  double standstill_speed_mps = 0.02;   // odometry speed below this: STANDSTILL [m/s]
  double odom_max_age_s = 0.5;          // odometry older than this is ignored [s]
  double min_contrast_dn = 3.0;         // image std dev below this (black, saturated): LOST [DN]
  double max_saturated_fraction = 0.5;  // more pixels at 255: LOST [-]
  double min_median_flow_px = 0.02;     // median track motion below this while moving: LOST [px]
  double max_frame_gap_s = 0.5;         // a longer gap between frames restarts tracking [s]
  uint64_t seed = 1;                    // RANSAC sampling seed [-]
  /// Throws std::invalid_argument naming the first bad field by its YAML key, section + "." + key.
  void validate(const std::string& section = "baseline") const;
};

enum class FrameStatus { kOk = 0, kStandstill = 1, kLost = 2, kFirst = 3 };
const char* toString(FrameStatus s);

/// The motion estimated between the previous frame and this one.
struct FrameEstimate {
  int64_t t_prev_ns = 0, t_ns = 0;
  FrameStatus status = FrameStatus::kFirst;
  double theta = 0.0;  // yaw change between the frames [rad]
  double omega = 0.0;  // theta / dt [rad/s]
  double v = 0.0;      // speed used [m/s]
  int tracks = 0;      // correspondences after the KLT checks
  int inliers = 0;     // RANSAC inliers
  std::string reason;  // why not OK (empty when OK)
};

struct FrameBaselineStats {
  size_t frames = 0, ok = 0, standstill = 0, lost = 0;
  double processing_s = 0.0;
};

/// All thetas in [-theta_max, theta_max] that satisfy the epipolar constraint of one
/// correspondence under the Ackermann arc of arc length s_m (T_base_cam: the mount), from unit
/// bearings f_r (earlier frame) and f_t (later frame). With the camera off the axle the
/// constraint is not a pure half-angle sinusoid and a track can have more than one root (mostly
/// near-degenerate tracks whose constraint hardly depends on theta); all are returned, RANSAC
/// sorts them out. Roots: sign changes on a grid of <= 0.005 rad, polished by safeguarded
/// Newton on the analytic derivative (ArcJacobian). Returns the number of roots.
int solveTheta1Point(const Vec3& f_r, const Vec3& f_t, double s_m, const Pose3& T_base_cam,
                     double theta_max, std::vector<double>* thetas);
/// The on-axle closed form theta = 2 atan((a_y b_z - a_z b_y) / (a_x b_z + a_z b_x)).
double theta1PointOnAxle(const Vec3& f_r, const Vec3& f_t, const Pose3& T_base_cam);
/// Sampson distance [in units of normalised image coordinates] of a correspondence under
/// T_Cr_Ct (infinite for a bearing behind the camera).
double sampsonDistance(const Pose3& T_Cr_Ct, const Vec3& f_r, const Vec3& f_t);

struct ThetaRansacResult {
  bool ok = false;
  double theta = 0.0;
  std::vector<int> inliers;  // indices into the correspondences
};
/// RANSAC over per-correspondence thetas (all of them if there are at most max_hypotheses),
/// inliers by Sampson distance below threshold_norm (normalised units), refinement over the
/// inliers. ok is false if there are fewer than min_inliers.
ThetaRansacResult estimateThetaRansac(const std::vector<Vec3>& f_r, const std::vector<Vec3>& f_t,
                                      double s_m, const Pose3& T_base_cam, double theta_max,
                                      double threshold_norm, int max_hypotheses, int min_inliers,
                                      uint64_t seed);

/// Frame-to-frame visual odometry over mono8 frames of the calibrated size.
class FrameBaseline {
 public:
  FrameBaseline(const FrameBaselineOptions& options, const CameraModel& camera,
                const Pose3& T_base_cam);

  /// Processes a frame (stamps increasing). Throws std::invalid_argument for an image that is
  /// not 8-bit single channel or not of the calibrated size, or a stamp not after the previous.
  FrameEstimate addFrame(int64_t t_ns, const cv::Mat& image);
  /// Wheel odometry: speed [m/s] (and yaw rate, unused) at t_ns; replaces the nominal speed.
  void addOdometry(int64_t t_ns, double v_mps, double yaw_rate_rad_s);

  /// Dead reckoning through all frames (LOST intervals keep the last yaw rate so the chain stays
  /// continuous, but they are not in trajectory()).
  const ArcChain& chain() const { return chain_; }
  /// Poses of base_link at the frames whose estimate is OK or STANDSTILL (and the first frame).
  const Trajectory3& trajectory() const { return trajectory_; }
  const std::vector<FrameEstimate>& estimates() const { return estimates_; }
  const FrameBaselineStats& stats() const { return stats_; }
  /// The last frame with its tracks (green: inliers, red: outliers, grey: new features), BGR.
  cv::Mat debugImage() const;

 private:
  double speedAt(int64_t t_ns) const;
  FrameEstimate finish(FrameEstimate e);
  void detectFeatures(const cv::Mat& image);

  FrameBaselineOptions options_;
  const CameraModel& camera_;
  Pose3 T_base_cam_;
  double focal_px_;
  cv::Mat prev_image_;
  std::vector<cv::Point2f> prev_points_;
  int64_t prev_t_ns_ = -1;
  double last_omega_ = 0.0;
  bool started_ = false;
  ArcChain chain_;
  Trajectory3 trajectory_;
  std::vector<FrameEstimate> estimates_;
  std::deque<std::pair<int64_t, double>> odom_;  // (t_ns, v)
  FrameBaselineStats stats_;
  // Debug drawing of the last frame.
  std::vector<cv::Point2f> dbg_from_, dbg_to_;
  std::vector<bool> dbg_inlier_;
  uint64_t rng_counter_ = 0;
};

}  // namespace vwe_vo
