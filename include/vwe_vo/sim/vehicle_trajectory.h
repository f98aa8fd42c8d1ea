// Ground-truth motion of base_link in odom for the simulator: an Ackermann-consistent planar
// path (heading tangent to the path) from smooth speed and yaw-rate profiles, integrated with
// closed-form arcs on a dense table, or a trajectory read from a TUM file.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "vwe_vo/common/math.h"
#include "vwe_vo/io/trajectory_io.h"

namespace vwe_vo {
namespace sim {

/// One piece of a speed / yaw-rate profile; consecutive pieces are blended smoothly.
struct ProfileSegment {
  double duration_s = 1.0;  // length of the piece [s]
  double v = 0.0;           // forward speed [m/s]
  double omega = 0.0;       // yaw rate [rad/s], > 0 turns left
};

/// Small camera-mount vibration applied to base_link (z, roll, pitch); off by default.
struct VibrationOptions {
  double height_amplitude_m = 0.0;   // vertical bounce amplitude [m]
  double pitch_amplitude_rad = 0.0;  // pitch oscillation amplitude [rad]
  double roll_amplitude_rad = 0.0;   // roll oscillation amplitude [rad]
  double frequency_hz = 3.0;         // base frequency of the oscillation [Hz]
  void validate() const;
};

/// Continuous driving on top of the segment profile; empty (off) by default. Speed:
/// v(t) = v_segments(t) * (1 + sum of speed sines + sum of speed changes) * product of stops.
/// Steering is a curvature of the distance s travelled, as an Ackermann vehicle steers:
/// omega(t) = omega_segments(t) + v(t) * kappa(s(t)), so the path's shape does not depend on the
/// speed profile, the yaw rate is continuous wherever v and kappa are, and it is 0 at a stop.
struct SpeedSine {
  double relative_amplitude = 0.0;  // fraction of the segment speed [-]
  double period_s = 10.0;           // [s]
  double phase_rad = 0.0;           // [rad]
};
struct SpeedChange {  // smooth acceleration / braking: a raised-cosine step of the speed factor
  double t_start_s = 0.0;
  double duration_s = 2.0;
  double relative_change = 0.0;  // added to the speed factor [-] (< 0: braking)
};
struct StopEvent {  // stop-and-go: raised-cosine braking to 0, standstill, raised-cosine start
  double t_start_s = 0.0;  // braking begins [s]
  double brake_s = 2.0;    // [s]
  double dwell_s = 2.0;    // exact standstill [s]
  double go_s = 2.0;       // [s]
};
struct CurvatureSine {  // kappa = amplitude * sin(2 pi s / wavelength + phase): gentle weaving
  double amplitude_per_m = 0.0;  // [1/m]
  double wavelength_m = 50.0;    // [m]
  double phase_rad = 0.0;        // pi / 2: the heading oscillates about the start heading
};
struct LaneChange {  // curvature doublet kappa = A sin(2 pi (s - s0) / L) on [s0, s0 + L]
  double s_start_m = 0.0;
  double length_m = 20.0;
  double lateral_m = 3.0;  // lateral displacement (small-angle), > 0 to the left [m]
};
struct Bend {  // clothoid in (kappa 0 -> K linear in s), arc at K, clothoid out
  double s_start_m = 0.0;
  double clothoid_m = 10.0;
  double arc_m = 10.0;
  double angle_rad = 0.0;  // heading change, > 0 left: K = angle / (clothoid_m + arc_m)
};
struct ContinuousMotion {
  std::vector<SpeedSine> speed_sines;
  std::vector<SpeedChange> speed_changes;
  std::vector<StopEvent> stops;
  std::vector<CurvatureSine> curvature_sines;
  std::vector<LaneChange> lane_changes;
  std::vector<Bend> bends;
  bool enabled() const;
  void validate() const;
};

/// A bump of the road: a raised-cosine hump of the given height and length at distance s_m, under
/// one wheel track (side +1 left, -1 right) or both (0).
struct RoadBump {
  double s_m = 0.0;
  double length_m = 0.5;
  double height_m = 0.02;
  int side = 0;
};

/// Body motion on the suspension: pitch, roll about base_link and heave, each the response of a
/// damped second-order system to a seeded road profile under the wheels (ISO 8608 displacement
/// PSD Gd(n) = Gd(n0) (n / n0)^-2, n0 = 0.1 cycles/m) and to the accelerations (braking dive,
/// acceleration squat, roll out of a turn). Off by default.
struct SuspensionOptions {
  bool enabled = false;
  uint64_t seed = 1;
  double road_gd_m3 = 16e-6;  // Gd(n0) [m^3]; ISO 8608 class A: 16e-6 (< 32e-6), class B: 64e-6
  double road_n_min = 0.05;   // band of the road profile [cycles/m]
  double road_n_max = 5.0;    // [cycles/m]
  double road_differential = 0.5;  // PSD of the left-right difference over that of the mean [-]
  std::vector<RoadBump> bumps;
  double wheelbase_m = 2.7;  // front-rear axle distance (pitch from the road) [m]
  double track_m = 1.55;     // left-right wheel distance (roll from the road) [m]
  double heave_hz = 1.2;     // natural frequencies [Hz]
  double pitch_hz = 1.4;
  double roll_hz = 1.5;
  double damping_ratio = 0.3;      // [-]
  double pitch_per_g_rad = 0.065;  // static pitch per g of braking (nose down) [rad/g]
  double roll_per_g_rad = 0.07;    // static roll per g of lateral acceleration (outwards) [rad/g]
  void validate() const;
};

struct VehicleTrajectoryOptions {
  double table_step_s = 0.5e-3;  // integration / table step [s]
  double blend_s = 0.4;  // smooth transition between profile segments [s] (centred at the boundary)
  Vec3 start_xyyaw = Vec3::Zero();  // start pose (x [m], y [m], yaw [rad])
  VibrationOptions vibration;
  ContinuousMotion motion;
  SuspensionOptions suspension;
  void validate() const;
};

/// Exact kinematics of base_link at one time (for the IMU): pose, body-frame angular velocity and
/// acceleration, and the world-frame acceleration of base_link's origin.
struct BaseKinematics {
  Pose3 T_odom_base;
  Vec3 omega_B = Vec3::Zero();  // [rad/s]
  Vec3 alpha_B = Vec3::Zero();  // [rad/s^2]
  Vec3 a_odom = Vec3::Zero();   // [m/s^2]
};

/// Body attitude on the suspension at one time: heave [m], pitch, roll [rad].
struct SuspensionState {
  double heave_m = 0, pitch_rad = 0, roll_rad = 0;
};

/// A trajectory of base_link in odom over [0, duration]; time 0 is the start of the sequence.
class VehicleTrajectory {
 public:
  /// Integrates the blended profile. The blend is antisymmetric about each boundary, so the
  /// heading change of every segment is exactly duration * omega (turns of exactly 90 deg stay
  /// exactly 90 deg) and a segment with v = omega = 0 longer than blend_s is an exact standstill.
  static VehicleTrajectory fromProfile(const std::vector<ProfileSegment>& segments,
                                       const VehicleTrajectoryOptions& options = {});
  /// A TUM trajectory of base_link (times shifted so the first is 0); v and omega by finite
  /// differences of the planar part.
  static VehicleTrajectory fromTum(const Trajectory3& tum,
                                   const VehicleTrajectoryOptions& options = {});

  int64_t durationNs() const { return duration_ns_; }
  double durationSec() const { return nsToSec(duration_ns_); }
  /// Length of the planar path [m].
  double pathLength() const { return path_length_; }

  /// Pose of base_link in odom at t (clamped to [0, duration]).
  Pose3 T_odom_base(int64_t t_ns) const;
  /// Exact forward speed [m/s] and yaw rate [rad/s] at t.
  double speed(int64_t t_ns) const;
  double yawRate(int64_t t_ns) const;
  /// Planar pose (x, y, yaw) at t, without vibration and suspension.
  Vec3 planar(int64_t t_ns) const;
  /// Distance travelled at t [m] (profile trajectories).
  double distance(int64_t t_ns) const;
  /// Heave, pitch and roll of the body at t (zero without suspension).
  SuspensionState suspension(int64_t t_ns) const;
  /// Exact derivatives of T_odom_base at t. Profile trajectories without vibration only (throws
  /// std::logic_error otherwise).
  BaseKinematics kinematics(int64_t t_ns) const;
  /// Poses sampled every step_ns from 0 to duration (inclusive), for TUM output.
  Trajectory3 sample(int64_t step_ns) const;

 private:
  struct Sample {
    double x, y, yaw;
    double v, omega;            // at the sample time
    double v_step, omega_step;  // constant over [t_k, t_k+1): the arc that integrates to sample k+1
    double s;                   // distance travelled [m]
  };
  struct SuspensionSample {
    double q[3], qd[3];  // heave, pitch, roll and their rates
  };
  double profileValue(double t_s, bool want_v) const;
  double speedAt(double t_s) const;
  double yawRateAt(double t_s, double s_m) const;
  double curvature(double s_m) const;
  void integrateSuspension();
  /// Heave, pitch, roll (value, rate, second derivative) by cubic Hermite interpolation.
  void suspensionAt(int64_t t_ns, double q[3], double qd[3], double qdd[3]) const;
  void locate(int64_t t_ns, size_t* k, double* d_s) const;

  std::vector<ProfileSegment> segments_;
  bool from_profile_ = true;
  VehicleTrajectoryOptions options_;
  int64_t step_ns_ = 0;
  int64_t duration_ns_ = 0;
  double path_length_ = 0.0;
  std::vector<Sample> table_;
  std::vector<SuspensionSample> suspension_;  // per table sample, when suspension is enabled
  Trajectory3 tum_;                           // when built from a TUM file
};

}  // namespace sim
}  // namespace vwe_vo
