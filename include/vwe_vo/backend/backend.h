// The back-end (paper Sec. III-C): a planar B-spline of base_link refined over a sliding window
// by maximising the summed contrast of M Volumes of Warped Events (paper eq. 5), initialised
// from the front-end's dead-reckoned arcs. Synchronous and ROS-free.
#pragma once

#include <ceres/first_order_function.h>

#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <utility>
#include <vector>

#include "vwe_vo/frontend/frontend.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sensor/events.h"
#include "vwe_vo/sensor/ground_mask.h"
#include "vwe_vo/sensor/imu.h"
#include "vwe_vo/trajectory/ackermann_arc.h"
#include "vwe_vo/trajectory/bspline.h"
#include "vwe_vo/trajectory/dead_reckoning.h"
#include "vwe_vo/trajectory/stamped_trajectory.h"
#include "vwe_vo/vwe/projective_volume.h"
#include "vwe_vo/vwe/vwe_objective.h"

namespace vwe_vo {

struct BackendOptions {
  VolumeOptions volume = defaultVolume();  // the VWE grid of every back-end volume
  static VolumeOptions defaultVolume() {
    VolumeOptions v;
    v.grid_scale =
        1.0;          // full resolution: at half resolution the refinement made the rotation worse
    v.z_min_m = 0.8;  // as the front-end: nearer planes collect floor rays at wrong yaw rates
    return v;
  }
  int degree = 3;               // spline degree p (1..5)
  double knot_spacing_s = 0.2;  // uniform knot span [s]
  double tau1_s = 0.2;          // spacing of the volume reference times [s]
  double tau2_s = 1.0;  // events span of one volume [s], > tau1_s (parallax over 1 s is what beats
                        // the front-end's 0.3 s)
  double window_s = 1.6;                 // length of the optimised sliding window [s]
  double update_interval_s = 1.0;        // new arcs that trigger a refinement [s]
  size_t max_events_per_volume = 10000;  // events voted per volume (uniform subsampling)
  size_t min_events_per_volume = 300;    // fewer events: the volume is skipped [events]
  int max_iterations = 20;               // LBFGS iterations per refinement
  double function_tolerance = 4e-5;   // LBFGS stops when the relative cost change is below this [1]
  int max_line_search_steps = 4;      // evaluations a line search may take (Ceres' default is 20)
  double step_scale_per_span = 0.25;  // solver unit of a control-point coordinate, as a fraction of
                                      // the distance driven per knot span (at least 1 mm) [1]
  double init_sample_interval_s = 0.05;  // spacing of the dead-reckoned poses fitted [s]
  double smoothness_weight = 0.05;       // second-difference prior of the initial fit [1]
  bool interpolate_arc_rates =
      true;  // dead reckoning with rates linear between the arcs' middles (false: steps)
  double speed_prior_weight = 10.0;  // relative-speed prior vs the normalised VWE (0: off) [1]
  double deformation_weight =
      1.0;  // third-difference prior on the control-point moves (0: off) [1]
  double arc_rate_prior_weight = 1e-2;  // the arcs' mean yaw rates as measurements, per (deg/s)^2
                                        // vs the normalised VWE (0: off) [1]
  double arc_rate_prior_scale_deg_s = 0.0;  // Cauchy scale of its residuals (0: quadratic) [deg/s]
  // Before the gradient steps, the new part of the spline (past the previous refinement) is
  // turned by a constant yaw-rate offset from a grid of +-yaw_scan_half_range_rad_s in steps of
  // yaw_scan_step_rad_s, and the solver starts from the offset of least cost. Over the back-end's
  // volumes (tau2_s of parallax) the cost tells a yaw rate the front-end's 0.3 s arcs cannot (a
  // lane change along a facade), but only near the start: the solver alone keeps the front-end's
  // yaw rate. Off by default: it helps weaving along facades and costs accuracy on some
  // turns (docs/method.md) (0: off) [rad/s].
  double yaw_scan_half_range_rad_s = 0.0;
  double yaw_scan_step_rad_s = 0.025;  // step of the scanned offsets [rad/s]
  /// Before the solver, each run of one or two new arcs whose yaw rates all lie at least this
  /// far beyond the range of the arcs before and after it (a bump, not a step) is tried at the
  /// rates interpolated between those two, and the start of least cost kept: a window whose flat
  /// scan found a wrong maximum is undone by the volumes' parallax, where the solver alone stays
  /// in the arcs' basin. Needs a robust arc prior (arc_rate_prior_scale_deg_s) to ever replace
  /// a run against it (0: off) [rad/s].
  double outlier_arc_min_rad_s = 0.0;
  /// Leave out of the volumes the events of the low-parallax wedge beside the horizon row
  /// (FrontendOptions::parallax_mask_slope, sensor/ground_mask.h): over a volume's 1 s as over a
  /// window's 0.3 s a yaw-rate error refocuses them at another depth, so they pin nothing and add
  /// the objective's second-order biases. They are dropped on arrival (counted), so the stop
  /// ramps read the event rate of the kept pixels. car.yaml 0.3, back-end yaw RPE with /odom over
  /// four starts: street_drive 0.700 -> 0.618, its flat twin 0.678 -> 0.468, street_long 0.509 ->
  /// 0.457; indoors within +-0.02 (off in vwe_vo.yaml) (0: off) [1].
  double parallax_mask_slope = 0.0;
  /// Without /odom (setSpeedsMeasured(false)), the first fit's speed within this long before a
  /// standstill follows the event rate above the standstill's noise: braking into a stop on a
  /// path of constant curvature, the flow (rotation included: omega = curvature * v) and the
  /// events scale with the speed. The ramp reaches back to where the rate peaked; the fit's
  /// speed there is the cruise speed the rest scales. The refinement that first sees the
  /// standstill reaches back to the ramp's start (0: off; also the length of start ramps) [s].
  double stop_ramp_max_s = 1.5;
  /// Without /odom, also the speed after a standstill follows the event rate (starting on a
  /// path of constant curvature), once the rate stopped rising; the cruise speed is the fit's
  /// where it peaked.
  bool start_ramps = true;
  /// Without /odom, the spline's tangent gives the heading only above this speed (slower: the
  /// nearest faster tangent). A braking ramp's fit slows to ~0 at the stop, where its ringing
  /// could reverse the tangent and hold the standstill's heading turned by 180 deg [m/s].
  double nominal_min_tangent_speed_mps = 0.03;
  double max_backwards_jump_s = 0.5;  // arcs older than newest - this reset (YAML:
                                      // input.max_backward_jump_s) [s]
  /// With /odom and without the IMU, the published poses (backend.tum, tf, /vwe/odom) carry the
  /// body's pitch and roll on its suspension as the response to the vehicle's own accelerations,
  /// from the refined trajectory: pitch = pitch_per_g * (-dv/dt) / g (braking dives the nose,
  /// pitch > 0), roll = roll_per_g * v omega / g (the body leans out of a turn). Each
  /// refinement's volumes see the camera tilted the same way (held during the solve); the spline
  /// stays planar. A car's pitch gradient is a few deg/g (config/car.yaml), a turtlebot's
  /// accelerations too small to matter (0: off) [deg/g].
  double pitch_per_g_deg = 0.0;
  double roll_per_g_deg = 0.0;   // roll gradient (0: off) [deg/g]
  double output_rate_hz = 20.0;  // rate of the sampled trajectory (backend.tum) [Hz]
  uint64_t seed = 1;             // subsampling seed
  /// Throws std::invalid_argument naming the field by its YAML key, section + "." + key.
  void validate(const std::string& section = "backend") const;
};

struct BackendStats {
  size_t events_in = 0;
  size_t events_outside = 0;       // outside the sensor: dropped
  size_t events_out_of_order = 0;  // older than the newest buffered event: dropped
  size_t events_masked = 0;        // in the parallax wedge (parallax_mask_slope): not voted
  size_t arcs_in = 0;
  size_t arcs_held =
      0;  // LOST / LOW_EVENTS / non-finite arcs dead-reckoned at the last measured rates
  size_t updates = 0;          // refinements run
  size_t volumes = 0;          // volumes optimised (summed over refinements)
  size_t volumes_skipped = 0;  // in a standstill or with too few events
  size_t evaluations = 0;      // objective + gradient evaluations
  size_t rejected = 0;         // refinements whose result was worse than the start (reverted)
  size_t resets = 0;
  size_t solver_iterations = 0;    // LBFGS iterations (summed over refinements)
  size_t max_iteration_stops = 0;  // refinements that ended at max_iterations (not converged)
  size_t accepted = 0;             // refinements whose result was kept
  double gain_sum = 0.0;           // sum over accepted refinements of f_final / f_start - 1
  double solver_s = 0.0;           // wall time in the solver [s]
  size_t yaw_scans = 0;            // refinements that scanned a yaw-rate offset
  size_t yaw_scans_moved = 0;      // ... and started the solver away from the front-end's rates
  double yaw_scan_abs_sum_rad_s = 0.0;  // sum of |offset| chosen [rad/s]
  size_t outlier_runs_tried = 0;        // runs of arcs tried at their neighbours' rates
  size_t outlier_runs_replaced = 0;     // refinements that started from such a run replaced
  size_t stop_ramps = 0;   // braking ramps into standstills fit from the event rate (no /odom)
  size_t start_ramps = 0;  // ramps out of standstills fit from the event rate (no /odom)
  size_t standstill_gaps_closed =
      0;  // paths after a standstill moved to start where it held the pose (per refinement)
  double last_gain = 0.0;  // objective ratio final / initial of the last refinement
};

/// The IMU's part of the back-end (Backend::enableImu).
struct BackendImuStats {
  size_t samples_in = 0;
  size_t samples_dropped = 0;          // non-finite, or older than the previous sample
  size_t prior_bins = 0;               // gyro bins used by the refinements (summed)
  size_t bias_updates = 0;             // refinements whose window measured the yaw-rate bias
  size_t bias_refused = 0;             // ... too far from the estimate (GyroBiasFilter): not used
  double yaw_bias_rad_s = 0.0;         // the slow filter's yaw-rate bias estimate [rad/s]
  double yaw_bias_sigma_rad_s = 0.0;   // its spread in the next solve's prior [rad/s]
  Vec3 gyro_bias_base = Vec3::Zero();  // x, y from the attitude filter, z = yaw_bias [rad/s]
  bool tilt_in_pose = false;           // the published pose has the pitch and roll (tiltInPose)
  AttitudeStats attitude;
};

/// One volume of the multi-volume objective: reference time and its (subsampled) events.
struct BackendVolume {
  int64_t t_ref_ns = 0;
  EventVector events;
};

/// Sum of the VWE contrasts of several volumes (paper eq. 5) as a function of the control
/// points [first_free, n) of a shared spline (the older ones stay fixed). Parameters are the free
/// control points stacked [x, y, ...] in metres.
class MultiVolumeObjective {
 public:
  /// spline, objectives must outlive this; the spline's free control points are overwritten by
  /// every evaluation. The volumes are evaluated in parallel, one per thread of the pool; the sums
  /// run in volume order (results independent of the thread count).
  MultiVolumeObjective(std::shared_ptr<BSpline> spline, const Pose3& T_base_cam, int first_free,
                       std::vector<BackendVolume> volumes, VweObjectivePool* objectives);
  int numFree() const { return 2 * (spline_->numControlPoints() - first_free_); }
  int firstFree() const { return first_free_; }
  const std::vector<BackendVolume>& volumes() const { return volumes_; }
  /// The free control points currently in the spline.
  Eigen::VectorXd freeParams() const;
  /// Sum of contrasts at params; gradient (if not null) w.r.t. the free parameters. Sets the
  /// spline's free control points to params. The last few results are kept: asking again for
  /// the same params (the solver's start and end points) costs no evaluation.
  double evaluate(const Eigen::VectorXd& params, Eigen::VectorXd* gradient);
  /// Sets the spline's free control points to params (no evaluation).
  void setParams(const Eigen::VectorXd& params);
  /// Evaluations computed (not served from the kept results).
  size_t evaluations() const { return evaluations_; }
  /// The body's tilt composed into every volume's camera poses (BSplineCameraModel::setTilt);
  /// set before the first evaluation.
  void setTilt(std::function<Mat3(int64_t)> tilt) { tilt_ = std::move(tilt); }

 private:
  std::shared_ptr<BSpline> spline_;
  Pose3 T_base_cam_;
  std::function<Mat3(int64_t)> tilt_;
  int first_free_;
  std::vector<BackendVolume> volumes_;
  VweObjectivePool* objectives_;
  std::vector<double> contrasts_;                // per volume
  std::vector<Eigen::VectorXd> full_gradients_;  // per volume, w.r.t. every control point
  size_t evaluations_ = 0;
  struct Kept {
    Eigen::VectorXd params, gradient;  // gradient empty if not computed
    double value;
  };
  std::vector<Kept> kept_;  // the newest last
};

class GyroRatePrior;

/// A soft prior on the free control points of a spline (part of the back-end's cost).
class SplinePrior {
 public:
  virtual ~SplinePrior() = default;
  /// Value at the spline's current control points; gradient (if not null, sized and written
  /// here) w.r.t. the free ones.
  virtual double evaluate(Eigen::VectorXd* gradient) const = 0;
};

/// Soft prior on the speed |c'(u)| of the free part of the spline, the scale the VWE fixes only
/// through the overlap of the volumes (rays beyond the depth range bias it: shrinking the path
/// brings far points into the grid). Two kinds of terms, targets the spline's current speeds:
///  - speeds: weight / K * sum_k ((|c'(u_k)| - v_k) / v_k)^2 at the K samples u_k, the speed
///    shape (measured speeds, or the refined past);
///  - scale: weight * ((S - S0) / S0)^2 with S the mean speed over the samples u_scale, the
///    distance driven alone: the speed shape there is left to the VWE.
/// Samples with speed below min_speed_mps, in a standstill or out of the free control points'
/// reach are left out.
class SpeedPrior : public SplinePrior {
 public:
  SpeedPrior(std::shared_ptr<const BSpline> spline, int first_free, const std::vector<double>& u,
             double weight, double min_speed_mps = 0.05,
             const std::vector<double>& u_scale = std::vector<double>());
  double evaluate(Eigen::VectorXd* gradient) const override;
  size_t numSamples() const { return u_.size(); }
  size_t numScaleSamples() const { return u_scale_.size(); }

 private:
  std::vector<double> usable(const std::vector<double>& u, double min_speed_mps) const;
  /// Adds d|c'(u)|/d(free control points) * factor to gradient; returns |c'(u)|.
  double speed(double u, double factor, Eigen::VectorXd* gradient) const;

  std::shared_ptr<const BSpline> spline_;
  int first_free_;
  std::vector<double> u_, v_, u_scale_;
  double scale_target_ = 0.0;  // S0: the mean target speed over u_scale_
  double weight_;
};

/// The front-end's arcs as measurements of the spline's mean yaw rate over their windows:
/// weight / K * sum_k ((psi(b_k) - psi(a_k)) / (b_k - a_k) - omega_k)^2 with the residual in
/// deg/s. Each arc measures the heading change over its own window (steps at the windows' borders
/// integrate to the same heading), so the prior holds the heading where the VWE says little (slow
/// driving, where a tiny move of the control points turns the tangent) without pulling towards
/// a dead reckoning's interpolation between the arcs. With a scale s > 0 each squared residual
/// r^2 becomes s^2 ln(1 + r^2 / s^2) (Cauchy): the same for |r| << s, a bounded pull of an arc
/// the volumes disagree with (a window whose scan found a wrong maximum).
class ArcRatePrior : public SplinePrior {
 public:
  struct Arc {
    double u_start, u_end;  // spline time [s]
    double omega;           // mean yaw rate [rad/s]
  };
  /// Arcs whose window the free control points do not reach, or shorter than 1 ms, are left out.
  ArcRatePrior(std::shared_ptr<const BSpline> spline, int first_free, const std::vector<Arc>& arcs,
               double weight, double scale_deg_s = 0.0);
  double evaluate(Eigen::VectorXd* gradient) const override;
  size_t numArcs() const { return arcs_.size(); }

 private:
  std::shared_ptr<const BSpline> spline_;
  int first_free_;
  std::vector<Arc> arcs_;
  double weight_;
  double scale_;  // Cauchy scale [deg/s] (0: quadratic)
};

/// Ceres view of a MultiVolumeObjective: minimises -sum(C)/sum(C at x0) of the volumes'
/// contrasts C (+ the priors, + a deformation prior) over x = (params - params0) / step_scale,
/// so that the start is x = 0 with cost -1. The deformation prior is deformation_weight *
/// sum_i |x_i - 3 x_{i+1} + 3 x_{i+2} - x_{i+3}|^2 over the control-point moves x_i (the fixed
/// points before the free ones count as zero moves): it leaves moves that are quadratic in the
/// control-point index free (an offset of heading or of yaw rate) and damps wiggles the VWE's
/// noise would put into the heading.
class MultiVolumeCost : public ceres::FirstOrderFunction {
 public:
  MultiVolumeCost(MultiVolumeObjective* objective, Eigen::VectorXd params0, double step_scale,
                  double normaliser, std::vector<const SplinePrior*> priors = {},
                  double deformation_weight = 0.0);
  bool Evaluate(const double* x, double* cost, double* gradient) const override;
  /// The cost at x without the deformation prior (which measures moves from params0): what
  /// compares starts of the solver that differ by more than a solver's move.
  bool startCost(const double* x, double* cost) const;
  int NumParameters() const override { return static_cast<int>(params0_.size()); }
  Eigen::VectorXd params(const double* x) const;

 private:
  MultiVolumeObjective* objective_;
  Eigen::VectorXd params0_;
  double step_scale_, normaliser_;
  std::vector<const SplinePrior*> priors_;
  double deformation_weight_;
  bool evaluate(const double* x, double* cost, double* gradient, bool deformation) const;
};

/// Inside a standstill [a, b] a BSpline holds the pose at c(a), and after it the path goes on
/// from c(b): nothing in the refinement keeps c(b) at c(a) (no volume sees a standstill), and a
/// gap between them is a jump of the vehicle where it starts again. For each standstill that
/// has ended (b < validTo()), this translates the control points from the first j >= first with
/// knot j >= a on by c(a) - c(b), if knot j + degree <= b: the curve after knot j + degree moves
/// whole, the curve before knot j not at all, and the blend between lies where the pose is held.
/// The path after b then starts exactly at c(a) with its shape unchanged. Returns the number of
/// gaps closed (standstills too short for such a j, or whose j is before `first`, stay open).
int closeStandstillGaps(BSpline* spline, int first);

/// Least squares of the control points [first, n) of `spline` to positions p_odom at spline
/// times u (the others fixed), with a second-difference smoothness prior of weight w on the free
/// points (it determines points the samples barely touch). Throws std::invalid_argument on sizes.
void fitControlPoints(BSpline* spline, int first, const std::vector<double>& u,
                      const std::vector<Vec2>& p_odom, double smoothness_weight);

/// The sliding-window back-end. The spline has uniform, unclamped knots (k - p) * knot_spacing_s
/// from the first arc's start: extending it appends knots and control points without moving the
/// curve already refined (Piegl & Tiller placement would move every knot as data arrives). Each
/// update (every update_interval_s of new arcs): the control points whose support reaches past
/// the previous update are refit by least squares to the refined curve up to there and, beyond,
/// to the front-end's dead reckoning composed onto the refined pose there; then every control
/// point whose support ends before the window (and always the first p + 1: origin, heading and
/// scale) is fixed and the others maximise the summed contrast of the volumes in the window
/// (LBFGS on the analytic gradient, plus the SpeedPrior). Volumes whose reference time is in a
/// standstill are skipped; STANDSTILL arcs become held intervals of the spline.
class Backend {
 public:
  Backend(const BackendOptions& options, const CameraModel& camera, const Pose3& T_base_cam);
  ~Backend();

  /// Fuses the IMU (call before the first data; options validated): addImu() samples then give
  /// the refinements the gyro's yaw rate as a measurement (GyroRatePrior, its bias estimated) and
  /// the poses (poseAt, sampleTrajectory) the body's pitch and roll from the attitude filter,
  /// composed onto the planar spline (only with measured speeds: tiltInPose). Without it (or
  /// without samples) nothing changes.
  void enableImu(const ImuFusionOptions& options, const Pose3& T_cam_imu);
  bool usesImu() const { return imu_ != nullptr; }
  /// Whether the poses carry the IMU's pitch and roll: with the IMU and measured speeds. The
  /// accelerometer measures the vehicle's own acceleration with gravity, and without /odom the
  /// speed, so that acceleration, is unknown: its tilt was worse than none (street_drive without
  /// /odom: translation direction RPE 1.80 deg/s with the tilt, 0.28 planar; indoor_drive 0.41,
  /// 0.32). Without, the pose stays planar; the gyro's yaw rate is fused all the same.
  /// Without the IMU, with measured speeds and a pitch or roll gradient (pitch_per_g_deg), the
  /// tilt is the suspension's response to the trajectory's accelerations (accelerationTiltAt).
  bool tiltInPose() const {
    return speeds_measured_ &&
           (imu_ != nullptr || options_.pitch_per_g_deg != 0.0 || options_.roll_per_g_deg != 0.0);
  }
  /// One IMU sample in the IMU frame (time order; ignored unless enableImu()). It is used once the
  /// arcs reach its time.
  void addImu(const ImuSample& sample);
  /// Valid with usesImu().
  const BackendImuStats& imuStats() const;
  /// The estimated tilt of base_link at t_ns: the IMU's, else the one of the accelerations (zero
  /// unless tiltInPose()).
  Tilt tiltAt(int64_t t_ns) const;
  /// The body's tilt from the refined trajectory's accelerations at t_ns, with the pitch and roll
  /// gradients (pitch_per_g_deg, roll_per_g_deg); zero where the trajectory has no pose.
  Tilt accelerationTiltAt(int64_t t_ns) const;

  const BackendOptions& options() const { return options_; }
  /// Whether the arcs' speeds are measurements (/odom), the default, or the front-end's nominal
  /// speed. Measured speeds are held sample by sample (speed_prior_weight); a nominal speed only
  /// sets the scale: the speeds the spline was refined to anchor it, and where the window holds
  /// none (the first refinement, after a stop) the mean speed of the new part does, its shape
  /// left to the volumes (a constant nominal speed through a stop would bend the path).
  void setSpeedsMeasured(bool measured) { speeds_measured_ = measured; }
  bool speedsMeasured() const { return speeds_measured_; }
  /// Time-ordered events; events outside the sensor or out of order are dropped and counted,
  /// a jump back by more than max_backwards_jump_s resets the back-end. Events older than the
  /// window are dropped as time advances.
  void addEvents(const EventVector& events);
  /// Front-end arcs in time order; an arc older than the newest by more than
  /// max_backwards_jump_s resets the back-end (returns true). LOST and LOW_EVENTS arcs (or ones
  /// with non-finite rates) carry no motion estimate: they are dead-reckoned at the last
  /// measured rates (counted in arcs_held) and are not yaw-rate measurements.
  bool addArc(const ArcEstimate& arc);
  /// Runs a refinement if update_interval_s of new arcs have arrived; returns true if it did.
  bool process();
  /// Extends and refines up to the newest arc (end of data).
  void finish();

  bool hasSpline() const { return spline_ != nullptr; }
  /// The refined spline (valid if hasSpline()).
  const BSpline& spline() const { return *spline_; }
  /// Newest time the spline is initialised and refined up to.
  int64_t processedUntil() const { return processed_ns_; }
  /// Start of the first arc and end of the newest arc since the last reset (-1: none yet).
  int64_t oldestArcTime() const;
  int64_t newestArcTime() const { return newest_arc_ns_; }
  /// Newest time up to which poseAt() will not change when later arcs arrive (unless a
  /// refinement moves it): the newest arc's end with steps, its middle with interpolate_arc_rates
  /// (the ramp to the next arc's middle is not known before that arc). -1 without arcs.
  int64_t finalUntil() const;
  /// First control point the last refinement optimised (the ones before it are fixed).
  int firstFree() const { return first_free_; }
  /// Pose of base_link in odom at t_ns with its speed [m/s] and yaw rate [rad/s] (may be null):
  /// on the refined spline up to where finalUntil() was at the last refinement (processedUntil()
  /// with steps), beyond it (up to the newest arc) the arcs' dead reckoning anchored on the spline
  /// there; before the first refinement that dead reckoning alone. The dead reckoning follows the
  /// same rule as the spline's fit: with interpolate_arc_rates the rates ramp between the arcs'
  /// middles (poses up to finalUntil() are final, the ones after it extrapolate the newest arc),
  /// else each arc's rates over its own window. False if t_ns is outside [first arc, newest arc].
  /// With measured speeds and the IMU or a pitch / roll gradient (tiltInPose) the pose is composed
  /// with the estimated tilt (tiltAt); the rates are the planar pose's.
  bool poseAt(int64_t t_ns, Pose3* T_odom_base, double* v, double* omega) const;
  /// The same without the tilt (the planar pose; equal to poseAt without the IMU).
  bool planarPoseAt(int64_t t_ns, Pose3* T_odom_base, double* v, double* omega) const;
  /// The front-end's dead reckoning the spline is fit to beyond its refined part (rates ramping
  /// between the arcs' middles with interpolate_arc_rates, else steps), in the back-end's first
  /// odom frame; the identity before the first arc.
  Pose3 initialGuess(int64_t t_ns) const {
    return dead_reckoning_ ? dead_reckoning_->ramped().T_odom_base(t_ns) : Pose3::Identity();
  }
  /// Poses of base_link in odom every 1/rate_hz from the first arc to processedUntil().
  Trajectory3 sampleTrajectory(double rate_hz) const;
  const BackendStats& stats() const { return stats_; }
  /// Events held for the next refinement (bounded by the window, not the sequence).
  size_t bufferedEvents() const { return buffer_.size(); }
  void reset();

 private:
  void update(int64_t t_new_ns);
  void extendSpline(int64_t t_new_ns);
  std::vector<BSpline::Interval> standstillIntervals(int64_t epoch_ns) const;
  /// Braking ramps into the standstills (stop_ramp_max_s) that start in (from_ns, to_ns + max],
  /// and (start_ramps) the ramps out of those that ended before the newest arc, once complete
  /// and peaking after from_ns.
  struct SpeedRamp;
  std::vector<SpeedRamp> speedRamps(int64_t from_ns, int64_t to_ns) const;
  /// The first fit's samples (times u, positions pos) driven at each ramp's cruise speed times
  /// its factor inside it; the headings of the steps are kept.
  void applySpeedRamps(const std::vector<SpeedRamp>& ramps, int64_t epoch,
                       const std::vector<double>& u, std::vector<Vec2>* pos) const;
  void refine(int64_t t_new_ns);
  /// The solver's start, as x of `cost` (zero: the start as fit): the least cost of the fit, its
  /// yaw-rate offsets past the previous refinement (yaw_scan_*) and its outlying arcs replaced
  /// (outlier_arc_min_rad_s).
  class TurnedStart;
  Eigen::VectorXd scanStart(const MultiVolumeCost& cost, const Eigen::VectorXd& params0,
                            int first_free, double step_m);
  // The IMU (backend_imu.cpp).
  struct Imu;
  std::unique_ptr<Imu> imu_;
  // The gyro's yaw rates up to the newest arc; the attitude filter a central difference of the
  // speed (diff_ns) behind it, all the way with to_newest (finish()).
  void advanceImu(bool to_newest = false);
  std::unique_ptr<SplinePrior> makeGyroPrior(double u_window, double u_new, int first_free);
  /// The yaw-rate offset of the new part the volumes prefer (parabola through the contrasts at
  /// offsets of 0, +-1, +-2 x imu bias_window_sigma_deg_s) [rad/s]; NaN if it cannot be turned.
  double preferredYawRateOffset(MultiVolumeObjective* objective, int first_free, double step_m);
  /// The yaw-rate bias filter's measurement of a refined window: a standstill's gyro, or moving
  /// the gyro against the spline turned by the volumes' preferred offset (events_offset_rad_s).
  void updateGyroBias(const GyroRatePrior& gyro, int64_t t_new_ns, double events_offset_rad_s);
  /// The gyro's mean yaw rate over [a, b] less the yaw-rate bias estimate, from the samples not
  /// yet filtered; false unless they cover most of it.
  bool gyroMeanYawRate(int64_t a_ns, int64_t b_ns, double* omega) const;
  Pose3 withTilt(int64_t t_ns, const Pose3& T_planar) const;
  /// The planar trajectory's speed, yaw rate and (central difference over diff_ns each side, cut
  /// at the first and newest arcs) acceleration at t_ns; false where it has no pose.
  bool vehicleMotionAt(int64_t t_ns, int64_t diff_ns, VehicleMotion* motion) const;
  /// The span of that central difference: at least 0.1 s and one arc. The arcs' speeds are
  /// constant per window; a shorter difference across their steps gives spikes of acceleration.
  int64_t accelerationSpan_ns() const;
  /// tiltAt over [t0, t1] from the trajectory as it is now, in a TiltHistory every 10 ms: the tilt
  /// a refinement's volumes hold while the solver moves the spline.
  std::function<Mat3(int64_t)> tiltTable(int64_t t0_ns, int64_t t1_ns) const;

  BackendOptions options_;
  bool speeds_measured_ = true;
  const CameraModel& camera_;
  Pose3 T_base_cam_;
  VweObjectivePool objectives_;
  EventBuffer buffer_;
  GroundMask mask_;  // parallax_mask_slope's wedge; keeps every pixel when off
  std::vector<std::pair<int64_t, int64_t>> standstills_ns_;  // merged STANDSTILL arcs
  // The arcs' dead reckoning since the last reset: ramped() is what the spline's fit starts from
  // and poseAt() beyond the spline (up to finalUntil() a pose published there is final,
  // ContinuousOdometry).
  std::unique_ptr<ArcDeadReckoning> dead_reckoning_;
  std::deque<ArcEstimate> arcs_;  // measured (OK) arcs of the last window (arc_rate_prior_weight)
  bool has_good_rates_ = false;   // the newest measured arc's rates (held through unmeasured arcs)
  double good_omega_ = 0.0, good_v_ = 0.0;
  int64_t newest_arc_ns_ = -1;
  int64_t processed_ns_ = -1;
  // poseAt() follows the spline up to here, finalUntil() at the last refinement: beyond it the
  // spline's end was fit to poses that were not final, and the volumes barely hold it.
  int64_t spline_final_ns_ = -1;
  int first_free_ = 0;
  std::shared_ptr<BSpline> spline_;
  // The last extension fit control points fit_first_.. at the times fit_u_ (TurnedStart).
  int fit_first_ = 0;
  std::vector<double> fit_u_;
  int64_t overruled_until_ns_ = -1;  // end of the newest arcs replaced by scanStart
  // Start of the earliest speed ramp the last extension refit (spline time; inf: none).
  double ramp_from_u_ = std::numeric_limits<double>::infinity();
  // The newest standstill edges whose stop / start ramp was counted (stats_.stop_ramps, ...).
  int64_t counted_stop_edge_ns_ = std::numeric_limits<int64_t>::min();
  int64_t counted_start_edge_ns_ = std::numeric_limits<int64_t>::min();
  BackendStats stats_;
};

/// Odometry as REP-105 wants it: continuous, no jumps. Each output pose is the previous output
/// composed with the back-end's current best estimate of the motion since then, so a refinement
/// changes the increments that follow it, never a pose already published (Backend::poseAt
/// re-anchors on every refinement, which would make odom -> base_link jump). The refined
/// trajectory itself is the spline (/vwe/path, backend.tum).
class ContinuousOdometry {
 public:
  /// Pose of base_link at t_ns (later than the previous call's), with speed and yaw rate (may be
  /// null). False if the back-end has no pose at t_ns.
  bool next(const Backend& backend, int64_t t_ns, Pose3* T_odom_base, double* v, double* omega);
  /// The stream backend_node publishes (and vwe_vo_offline's odom.tum): next() every step_ns
  /// from the back-end's first arc up to its finalUntil(), each time once, as
  /// emit(t_ns, T_odom_base, v, omega). Call it on every new arc, before the refinement.
  template <typename Emit>
  void advance(const Backend& backend, int64_t step_ns, Emit&& emit) {
    if (next_ns_ < 0) next_ns_ = backend.oldestArcTime();
    for (; next_ns_ >= 0 && next_ns_ <= backend.finalUntil(); next_ns_ += step_ns) {
      Pose3 T;
      double v = 0.0, omega = 0.0;
      if (next(backend, next_ns_, &T, &v, &omega)) emit(next_ns_, T, v, omega);
    }
  }
  void reset() { has_previous_ = false, next_ns_ = -1; }

 private:
  int64_t next_ns_ = -1;  // advance(): time of the next pose
  bool has_previous_ = false;
  int64_t t_previous_ns_ = 0;
  Pose3 T_previous_ = Pose3::Identity();
};

}  // namespace vwe_vo
