// The front-end: per window of events, the 1-DoF Ackermann arc (yaw rate omega at a fixed
// speed v) that maximises the contrast of the Volume of Warped Events; arcs chained into a
// dead-reckoned pose. Synchronous and ROS-free: the offline runner and frontend_node drive it.
#pragma once

#include <algorithm>
#include <cstdint>
#include <deque>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "vwe_vo/frontend/ground_yaw.h"
#include "vwe_vo/frontend/one_sided.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sensor/events.h"
#include "vwe_vo/sensor/ground_mask.h"
#include "vwe_vo/trajectory/ackermann_arc.h"
#include "vwe_vo/trajectory/dead_reckoning.h"
#include "vwe_vo/trajectory/stamped_trajectory.h"
#include "vwe_vo/vwe/projective_volume.h"
#include "vwe_vo/vwe/vwe_objective.h"

namespace vwe_vo {

enum class ArcStatus : uint8_t { kOk = 0, kStandstill = 1, kLost = 2, kLowEvents = 3 };
const char* toString(ArcStatus s);

struct FrontendOptions {
  VolumeOptions volume = defaultVolume();  // the VWE grid of every window
  static VolumeOptions defaultVolume() {
    VolumeOptions v;
    v.grid_scale = 1.0;  // full resolution: half resolution biases slow, straight driving
    v.num_planes = 30;
    // Nearest plane 0.8 m: the rays of the floor in front of a turtlebot meet in nearer planes
    // at a wrong yaw rate, a broad second maximum that pulls straight driving off; much deeper
    // planes lose the structure that slow straight driving needs.
    v.z_min_m = 0.8;
    return v;
  }
  bool window_by_count = false;    // windows of window_events events instead of a duration
  double window_duration_s = 0.3;  // window length when by duration [s]
  double window_stride_s = 0.0;  // start-to-start spacing of windows by duration [s]; 0: no overlap
  size_t window_events = 60000;  // window size when by count [events]
  size_t max_events_per_volume = 8000;  // events voted per window (uniform subsampling)
  int subsample_time_slices = 10;       // equal budget per time slice of the window (1: by count)
  double nominal_speed_mps = 0.3;       // v when no odometry is given [m/s]
  double omega_max_rad_s = 1.2;         // |omega| bound of the full scan [rad/s]
  double scan_half_range_rad_s = 0.15;  // scan around the previous omega [rad/s]
  double scan_step_rad_s = 0.03;        // coarse scan step [rad/s]
  double full_scan_step_rad_s =
      0.09;                      // step of a full-range scan, refined at scan_step_rad_s [rad/s]
  int full_scan_candidates = 2;  // maxima of a full-range scan refined at scan_step_rad_s
  size_t full_scan_max_events = 2000;  // events the coarse grid of a full-range scan votes (0: all)
  double refine_tolerance_rad_s = 3e-4;     // 1-D refinement stops at this bracket width [rad/s]
  double standstill_event_rate_hz = 30000;  // below this event rate the vehicle is standing [ev/s]
  double standstill_speed_mps = 0.03;  // odometry speed below this means standstill [m/s] (a window
                                       // that barely moves has no parallax to fix omega)
  size_t min_events = 1500;            // fewer events in a window: LOW_EVENTS, omega held
  double min_confidence = 0.02;        // below: LOST, next window scans the full range
  double rescan_confidence = 0.07;     // a flatter scan around the previous omega is repeated
                                       // over the full range (a fast turn began)
  double split_omega_change_rad_s = 0.05;  // a window whose omega differs more from the last is
                                           // estimated again as two halves (0: never)
  // Without odometry, a window with fewer events per second than this fraction of the moving
  // event rate (an average over recent windows above it) is driven slower: the nominal speed
  // times rate / (fraction * moving rate). Off by default: the events of a turn outnumber
  // those of a straight 2-3 times at the same speed, so straights after turns were driven at
  // half speed (indoor_long without /odom: translation direction 0.95 deg/s, 0.48 without);
  // the back-end's braking ramps (BackendOptions::stop_ramp_max_s) follow the rate only into a
  // stop (0: off).
  double slow_rate_fraction = 0.0;
  // Without odometry, the first window after a standstill is also estimated at 1/16 and 1/4 of
  // the nominal speed, and the arc of highest contrast is kept: starting from rest the vehicle
  // covers a fraction of the nominal distance in that window (indoor_drive turns away at
  // 1-3 cm/s), and the nominal speed's parallax puts degrees per second into the yaw rate.
  bool restart_speed_scan = true;
  bool use_gyro_prior = false;               // centre and narrow the scan on the gyro yaw rate
  double gyro_prior_half_range_rad_s = 0.1;  // scan half range around the gyro yaw rate [rad/s]
  double max_backwards_jump_s =
      0.5;  // events older than newest - this reset (YAML: input.max_backward_jump_s) [s]
  // Windows with structure on one side of the street only (one_sided.h; YAML one_sided_balance,
  // one_sided_z_min_m, one_sided_min_depth_m): the facade's depth is measured at the predicted
  // yaw rate, the gyro's if /dvs/imu is given, else the previous arc's.
  OneSidedOptions one_sided;
  // Leave out of the volume the events of pixels whose line of sight meets the ground (base_link
  // z = 0 under T_base_cam) nearer than volume.z_min_m: they cannot focus in any plane and pull
  // the yaw rate (sensor/ground_mask.h). The front-end's only: over the back-end's 1 s volumes
  // the same ground is seen again from nearer and further poses, and masking it there made the
  // refined yaw rate worse (street_long with /odom, true arcs: 0.45 -> 0.57 deg/s). Indoors
  // (camera 0.3 m up, planes from 0.8 m) indoor_long's refined yaw RPE with /odom 0.23 -> 0.17
  // deg/s; on the car street_drive's 1.03 -> 0.69 (docs/method.md).
  bool ground_mask = true;
  // Also leave out the pixels whose bearing, relative to the direction of travel (base_link x
  // under T_base_cam), has a vertical tangent below this times its horizontal one (0: off). To
  // first order a yaw-rate error d_omega refocuses such a point's rays at another depth and
  // leaves only a vertical spread (phi / theta) d_omega t (docs/method.md), so the wedge around
  // the horizon row beside the focus of expansion (facades seen at grazing angles) pins nothing
  // and only adds the objective's second-order biases. car.yaml 0.3: back-end yaw RPE on
  // street_long with /odom 0.567 -> 0.477, street_drive without /odom 0.763 -> 0.578; on
  // street_drive with /odom over four starts 0.686 -> 0.700, and 0.618 with the back-end's
  // volumes masked as well (BackendOptions::parallax_mask_slope). Indoors mixed: off in
  // vwe_vo.yaml.
  double parallax_mask_slope = 0.0;
  // The body's roll rate about base_link's x axis as a nuisance parameter (0: off): after omega,
  // the window is evaluated at roll rates -+this, the parabola's vertex (within +-2x) tried, and
  // the best kept; omega is then refined again at that roll rate (one coordinate step: at the
  // biased omega the roll rate found is short of the truth, and so is the correction). A body
  // rolling on its suspension (a car's 1-2 deg/s) turns the image about the optical axis, a
  // horizontal flow proportional to the row: with the events mostly above the horizon it shifts
  // them all, as a yaw rate does. Only in windows with a measured speed (/odom): at a nominal
  // speed the scale is off and the roll took up that misfit instead (without /odom, four starts:
  // street_drive 0.549 -> 0.585, its flat twin 0.478 -> 0.539, seed 7 0.688 -> 0.750). car.yaml
  // 1 deg/s: back-end yaw RPE with /odom over four starts, street_drive 0.618 -> 0.568, its flat
  // twin 0.467 -> 0.402, seed 7 0.543 -> 0.524 (docs/method.md). The flat twin gains too: the
  // roll also takes up what a rigid 1-DoF arc misfits row by row. Indoors within +-0.02 deg/s:
  // off in vwe_vo.yaml. It costs about 40 % more front-end evaluations.
  double roll_rate_step_rad_s = 0.0;
  // With a measured speed (/odom), the rays of each window vote only from volume.z_min_m in front
  // of their own camera, not only of the window's middle: driving forward, the cameras of the
  // window's second half meet the nearest planes close to their own centres, all near the focus
  // of expansion, and that pile-up pulls the yaw rate (street_drive with /odom, back-end yaw RPE
  // 0.65 -> 0.57 deg/s). z_min_m is metric: at a nominal speed 20 % below the true one the
  // street shrinks and the cut removes real facade points (0.78 -> 0.94), so windows without
  // /odom keep the reference view's range only.
  bool per_camera_min_depth = false;
  // With a measured speed (/odom), each window's yaw rate is also measured on the road and the
  // two averaged (ground_yaw.h; YAML section ground:, weight 0: off). The road cannot take up a
  // yaw error with depth, as one-sided facades and those seen at grazing angles do; it needs
  // the body's pitch, which it estimates as a nuisance. car.yaml 0.5 (and the back-end's arc
  // prior 1e-2): street_drive's back-end yaw RPE with /odom over four starts 0.521 -> 0.376,
  // over three subsampling seeds 0.583 -> 0.386, its flat twin 0.421 -> 0.267 (docs/method.md).
  // It costs ~120 evaluations of the road's objective a window.
  GroundYawOptions ground;
  uint64_t seed = 1;  // subsampling seed
  /// Throws std::invalid_argument naming the field by its YAML key, section + "." + key.
  void validate(const std::string& section = "frontend") const;
};

/// One front-end window's result (mirrors vwe_vo/AckermannArc).
struct ArcEstimate {
  int64_t t_ref_ns = 0, t_start_ns = 0, t_end_ns = 0;
  double omega = 0.0, v = 0.0;
  double contrast = 0.0, confidence = 0.0;
  uint32_t num_events = 0;   // events voted (after subsampling)
  size_t window_events = 0;  // events in the window (before subsampling)
  ArcStatus status = ArcStatus::kOk;
  int evaluations = 0;     // objective evaluations spent
  double roll_rate = 0.0;  // the roll rate omega was refined at (roll_rate_step_rad_s) [rad/s]
  /// omega less the yaw rate of the window's best arc at roll rate 0 (non-zero only in windows
  /// refined at a roll rate) [rad/s]. The back-end refines from omega; the front-end's own
  /// odometry (T_odom_base, integrateArcs, the odom of frontend_node) dead-reckons the arc without
  /// the roll, whose windows scatter less (docs/method.md).
  double roll_omega_shift = 0.0;
  double omegaWithoutRoll() const { return omega - roll_omega_shift; }
  /// The road's measurement (frontend.ground), averaged into omega with road_share: its yaw rate
  /// [rad/s], the body's pitch at t_ref [rad] and its rate [rad/s] it found, the roll it was
  /// warped with [rad] and its curvature (GroundYawEstimate); NaN in windows without it.
  double road_omega = std::numeric_limits<double>::quiet_NaN();
  double road_pitch = std::numeric_limits<double>::quiet_NaN();
  double road_pitch_rate = std::numeric_limits<double>::quiet_NaN();
  double road_roll = std::numeric_limits<double>::quiet_NaN();
  double road_curvature = std::numeric_limits<double>::quiet_NaN();
  double road_share = std::numeric_limits<double>::quiet_NaN();
};

/// Dead reckoning through the arcs with omegaWithoutRoll() and v ramping between the arcs'
/// reference times (integrateRamps: each arc estimates the mean rate over its window, i.e. the rate
/// at its middle), integrated in steps of step_ns. Poses of base_link in odom from the identity at
/// the first arc's start to the last arc's end. Follows ramps in the yaw rate that a chain of
/// constant arcs would turn into steps.
Trajectory3 integrateArcs(const std::vector<ArcEstimate>& arcs, int64_t step_ns);

struct FrontendStats {
  size_t events_in = 0, events_outside = 0, events_out_of_order = 0;
  size_t windows = 0, windows_dropped = 0, windows_split = 0, resets = 0;
  size_t windows_thinned = 0;  // estimated on 1/k of max_events_per_volume (setVolumeThinning)
  size_t evaluations = 0;
  size_t events_ground_masked = 0;      // of the estimated windows, left out by ground_mask
                                        // and parallax_mask_slope
  size_t windows_slow = 0;              // without odometry: nominal speed scaled by the event rate
  size_t windows_standstill_edges = 0;  // standstill (or mostly still) windows split where /odom
                                        // stops or starts
  size_t windows_restart_slower = 0;    // restart_speed_scan kept a slower arc (a window or half)
  size_t windows_one_sided = 0;         // estimated with the deeper planes (one_sided.z_min_m)
  size_t windows_rolled = 0;            // omega refined at a non-zero roll rate
                                        // (roll_rate_step_rad_s)
  size_t windows_one_sided_near =
      0;                          // one-sided, but the structure nearer than one_sided.min_depth_m
  size_t windows_ground = 0;      // yaw rate averaged with the road's (ground.weight)
  size_t windows_ground_few = 0;  // ... not: fewer road events than ground.min_events
  size_t windows_ground_alone = 0;  // ... the road's alone (GroundYaw::share: the VWE's was apart)
  size_t windows_ground_refused = 0;  // ... the VWE's alone (the road's was apart or had no peak)
  size_t ground_evaluations = 0;      // of the road's objective
  double ground_shift_abs_sum_rad_s = 0.0;  // sum of |road - VWE| yaw rate [rad/s]
};

/// How the front-end scans a window beyond its centre and half range.
struct WindowScan {
  bool deep_planes =
      false;  // the one-sided window's planes (one_sided.z_min_m); needs one_sided.balance > 0
  // The range a flat or edge-bound scan is repeated over (the full range, but for the halves
  // of a split window), clipped to +-omega_max_rad_s.
  double rescan_lo_rad_s = -std::numeric_limits<double>::infinity();
  double rescan_hi_rad_s = std::numeric_limits<double>::infinity();
  // Try the body's roll rate as a nuisance (FrontendOptions::roll_rate_step_rad_s): the
  // front-end sets it for windows with a measured speed.
  bool roll_nuisance = false;
};

class Frontend {
 public:
  Frontend(const FrontendOptions& options, const CameraModel& camera, const Pose3& T_base_cam);

  const FrontendOptions& options() const { return options_; }
  /// Adds time-ordered events. Events outside the sensor are dropped and counted; a jump
  /// back in time larger than max_backwards_jump_s resets the front-end (returns true), a
  /// smaller one drops the late events (counted).
  bool addEvents(const EventVector& events);
  /// Wheel odometry speed and yaw rate at t (optional input).
  void addOdometry(int64_t t_ns, double v_mps, double yaw_rate_rad_s);
  /// Gyro yaw rate of base_link at t (optional input).
  void addGyro(int64_t t_ns, double yaw_rate_rad_s);

  /// Estimates the complete windows, oldest first, at most `max_windows` of them (a node takes
  /// one at a time to look at its backlog in between). Returns the new arcs (also kept for the
  /// pose).
  std::vector<ArcEstimate> process(size_t max_windows = std::numeric_limits<size_t>::max());
  /// Skips every complete window but the newest `keep` (a node that falls behind); counted.
  /// Each skipped window becomes a kLost arc in `skipped` (if given) at the last yaw rate and the
  /// window's /odom speed (0 without /odom: the dead reckoning holds its position), so whoever
  /// follows the arcs sees no gap in time.
  size_t dropBacklog(size_t keep, std::vector<ArcEstimate>* skipped = nullptr);
  /// A node that falls behind: the windows that follow vote max_events_per_volume / k events (at
  /// least 100 and 10 per time slice), about k times less work each; every window is still
  /// estimated (counted in windows_thinned). k = 1 restores the configured budget.
  void setVolumeThinning(size_t k) { volume_thinning_ = std::max<size_t>(1, k); }
  size_t volumeThinning() const { return volume_thinning_; }
  /// Complete windows waiting in the buffer.
  size_t pendingWindows() const;

  /// Estimates one window of events about t_ref (exposed for tests and the objective plots).
  ArcEstimate estimateWindow(const EventVector& window_events, int64_t t_ref_ns, double v,
                             double omega_center, double half_range,
                             const WindowScan& setup = WindowScan());
  /// The events of a window the front-end votes from: those off the near ground (ground_mask),
  /// kept in *storage, or `events` itself without the mask or if it would leave fewer than
  /// min_events.
  const EventVector& offGround(const EventVector& events, EventVector* storage) const;
  /// Contrast of the VWE of `events` for an arc (omega, v) about t_ref (with the one-sided
  /// window's planes if deep_planes).
  double contrast(const EventVector& events, int64_t t_ref_ns, double omega, double v,
                  bool deep_planes = false);
  /// contrast() at every omega, one evaluation per thread (the same values as contrast()).
  std::vector<double> contrasts(const EventVector& events, int64_t t_ref_ns,
                                const std::vector<double>& omegas, double v,
                                bool deep_planes = false);

  /// Replaces the speed used when no odometry is given (e.g. the back-end's refined speed);
  /// throws std::invalid_argument unless positive and finite.
  void setNominalSpeed(double v_mps);
  /// The same for a speed measured at t_ns, taken only if the window that covers t_ns was not a
  /// slow one (slow_rate_fraction), so the nominal speed stays that of a vehicle at the moving
  /// event rate.
  void setNominalSpeed(double v_mps, int64_t t_ns);
  /// Event rate of the recent moving windows the slow-window rule compares with (0: none yet).
  double movingEventRate() const { return moving_rate_hz_; }

  /// Dead-reckoned pose of base_link in odom at t (arcs chained from the identity).
  Pose3 T_odom_base(int64_t t_ns) const;
  bool hasPose() const { return chain_ != nullptr && chain_->numArcs() > 0; }
  const FrontendStats& stats() const { return stats_; }
  void reset();

 private:
  bool nextWindow(EventVector* window, int64_t* t0, int64_t* t1) const;
  int64_t strideNs() const;
  /// One span of events [t0, t1): standstill / low-events checks, subsampling, the one-sided
  /// check (which sets setup.deep_planes), estimation. *scanned tells whether the objective was
  /// optimised.
  ArcEstimate estimateSpan(const EventVector& events, int64_t t0, int64_t t1, WindowScan setup,
                           bool* scanned);
  /// A STANDSTILL window [t0, t1) whose /odom speed reaches standstill_speed_mps at its start
  /// (braking into the stop) or its end (starting): the window split at those crossings, the
  /// moving edges as arcs at their /odom speed and the curvature before the stop
  /// (last_curvature_), the rest STANDSTILL. Empty if the window has no such edge.
  std::vector<ArcEstimate> standstillEdges(const EventVector& events, int64_t t0, int64_t t1) const;
  /// Extends the dead reckoning over the part of time the span [t0, t1) stands for.
  void extendChain(int64_t t0, int64_t t1, double omega, double v);
  void moveToNextWindow(int64_t t0, int64_t t1);
  /// Mean /odom speed over [t0, t1], else the nominal speed (*measured false).
  double speedAt(int64_t t0_ns, int64_t t1_ns, bool* standstill, bool* measured = nullptr) const;
  bool gyroAt(int64_t t0_ns, int64_t t1_ns, double* yaw_rate) const;
  /// The odometry's acceleration over [t0, t1] (a line through its speeds there and 0.1 s
  /// either side) [m/s^2]; 0 without odometry.
  double accelerationAt(int64_t t0_ns, int64_t t1_ns) const;

  FrontendOptions options_;
  const CameraModel& camera_;
  Pose3 T_base_cam_;
  ProjectiveVolume volume_;
  VweObjective objective_;            // one evaluation on all threads (the refinement)
  double roll_rate_ = 0.0;            // body roll rate the evaluations use (roll_rate_step_rad_s)
  VweObjectivePool scan_objectives_;  // one evaluation per thread (the scans)
  // The same with the deeper planes of one-sided windows (one_sided.balance > 0).
  OneSidedRule one_sided_;
  GroundMask ground_mask_;                 // keeps every pixel unless options.ground_mask
  std::unique_ptr<GroundYaw> ground_yaw_;  // ground.weight > 0
  std::unique_ptr<VweObjectivePool> one_sided_scan_objectives_;
  std::unique_ptr<ProjectiveVolume> one_sided_volume_;
  std::unique_ptr<VweObjective> one_sided_objective_;
  EventBuffer buffer_;
  int64_t next_window_start_ns_ = -1;
  struct RateSample {
    int64_t t_ns;
    double v, yaw_rate;
  };
  std::deque<RateSample> odometry_, gyro_;
  double last_omega_ = 0.0;
  // Path curvature (omega / v) of the last estimated moving arc [1/m]: the steering, which a
  // vehicle keeps through a stop (the moving edges of a standstill window, standstillEdges()).
  double last_curvature_ = 0.0;
  bool lost_ = true;
  bool after_standstill_ = false;  // the last window ended in a standstill (restart_speed_scan)
  double moving_rate_hz_ = 0.0;    // slow_rate_fraction: the moving windows' event rate
  struct SpeedFactor {
    int64_t t0_ns, t1_ns;
    double factor;
  };
  std::deque<SpeedFactor> speed_factors_;  // of the newest windows (setNominalSpeed)
  std::unique_ptr<ArcChain> chain_;
  size_t volume_thinning_ = 1;  // setVolumeThinning
  FrontendStats stats_;
};

}  // namespace vwe_vo
