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

struct VehicleTrajectoryOptions {
  double table_step_s = 0.5e-3;  // integration / table step [s]
  double blend_s = 0.4;  // smooth transition between profile segments [s] (centred at the boundary)
  Vec3 start_xyyaw = Vec3::Zero();  // start pose (x [m], y [m], yaw [rad])
  VibrationOptions vibration;
  void validate() const;
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
  /// Planar pose (x, y, yaw) at t, without vibration.
  Vec3 planar(int64_t t_ns) const;
  /// Poses sampled every step_ns from 0 to duration (inclusive), for TUM output.
  Trajectory3 sample(int64_t step_ns) const;

 private:
  struct Sample {
    double x, y, yaw;
    double v, omega;            // at the sample time
    double v_step, omega_step;  // constant over [t_k, t_k+1): the arc that integrates to sample k+1
  };
  double profileValue(double t_s, bool want_v) const;
  void locate(int64_t t_ns, size_t* k, double* d_s) const;

  std::vector<ProfileSegment> segments_;
  bool from_profile_ = true;
  VehicleTrajectoryOptions options_;
  int64_t step_ns_ = 0;
  int64_t duration_ns_ = 0;
  double path_length_ = 0.0;
  std::vector<Sample> table_;
  Trajectory3 tum_;  // when built from a TUM file
};

}  // namespace sim
}  // namespace vwe_vo
