// A front-end window's yaw rate measured a second way, on the road (vwe/ground_objective.h), and
// averaged with the VWE's. The two fail in different places: the VWE where the structure is
// one-sided or seen at grazing angles (a yaw error refocuses it at other depths), the road where
// the body's pitch is off or the road is hidden. On the road a pitch error of a tenth of a degree
// misplaces the plane by centimetres, so the body's pitch at the window's middle and its rate
// are nuisance parameters of the road's estimate (a car pitches 0.2-0.3 deg RMS on its
// suspension; street_drive's per-window yaw-rate error on the road, 0.3 s windows: 1.8 deg/s
// RMS at pitch 0, 0.9 with the nuisance, 0.51 at the true pitch, 0.34 at the true pitch and
// roll). Only with a measured speed: the road is metric (docs/method.md).
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "vwe_vo/common/math.h"
#include "vwe_vo/common/thread_pool.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sensor/events.h"
#include "vwe_vo/trajectory/trajectory_model.h"
#include "vwe_vo/vwe/ground_objective.h"

namespace vwe_vo {

struct GroundYawOptions {
  // The road's share of a window's yaw rate: (1 - weight) VWE + weight road (0: off). On a bumpy
  // street (0.3 s windows) the road is ~0.45 deg/s RMS off, the VWE ~1.0, nearly independently:
  // their inverse variances give the road 0.8 (car.yaml). Where the two lie further apart than
  // half_range_rad_s, one of them is alone (GroundYaw::share).
  double weight = 0.0;
  GroundObjectiveOptions objective;
  size_t max_events = 10000;          // road events per window (uniform per time slice)
  size_t min_events = 2000;           // fewer: the window keeps the VWE's yaw rate
  double half_range_rad_s = 0.075;    // searched +-this around the VWE's (estimate()) [rad/s]
  double step_rad_s = 0.0025;         // finest step of that search [rad/s]
  double pitch_half_range_deg = 0.6;  // the body's pitch, searched within +-this
  double pitch_step_deg = 0.1;        // in these steps [deg]
  double pitch_rate_half_range_deg_s = 2.0;  // its rate likewise [deg/s]
  double pitch_rate_step_deg_s = 0.25;
  // The body's pitch per g of deceleration, nose down (backend.pitch_per_g_deg, which the
  // configuration copies here): the pitch search centres on the dive the window's /odom
  // deceleration predicts (a car braking at 0.3 g dives about 1 deg, past the search's range).
  double pitch_per_g_rad = 0.0;
  // The body's roll per g of lateral acceleration, out of the turn (backend.roll_per_g_deg,
  // copied likewise): the road is warped with the body leaning by the roll the window's speed
  // and yaw rate predict, roll_per_g v omega / g (a car at 7 m/s turning at 10 deg/s leans
  // 0.6 deg at 5 deg/g). Held there, not searched: street_drive's roll is 0.46 deg RMS, 0.16 deg
  // from this prediction, 0.27 deg from the road's own best roll.
  double roll_per_g_rad = 0.0;
  // At most this many rounds of (pitch, pitch rate, yaw rate) searches; they stop once none moves
  // (0: pitch 0). Pitch and pitch rate trade along a ridge: two rounds stop short of its top.
  int pitch_rounds = 8;
  int num_threads = 2;  // evaluations in parallel (the front-end sets volume.num_threads)
  /// Throws std::invalid_argument naming the field by its key, section + "." + key.
  void validate(const std::string& section) const;
};

struct GroundYawEstimate {
  bool valid = false;                    // false: too few road events
  double omega = 0.0;                    // the road's yaw rate [rad/s]
  double pitch = 0.0, pitch_rate = 0.0;  // the nuisance at its best [rad, rad/s]
  double roll = 0.0;                     // the lean it was warped with [rad]
  double contrast = 0.0;
  // -f''/f over the yaw rate at the best (0: no peak) [(rad/s)^-2]: how sharply the road's
  // contrast peaks. Broad where its texture holds few edges across the motion; there the estimate
  // scatters with the events voted (street_drive, 12 subsamples of a window: 0.05-0.15 deg/s
  // apart at 160-300 (rad/s)^-2, 0.2-0.4 at 30, 1 at 15), yet stays better than the VWE's.
  double curvature = 0.0;
  // The road's yaw rate lies beyond half_range_rad_s of omega_center (the VWE's): one of the two
  // found a spurious peak. near_prior: it lies within half_range_rad_s of omega_prior.
  bool apart = false, near_prior = false;
  size_t events = 0;  // road events voted
  int evaluations = 0;
};

/// An Ackermann arc of base_link whose body pitches (about base_link's y axis, nose down > 0) by
/// pitch + pitch_rate (t - t_ref) and leans (about x) by a constant roll above the road:
/// T_Cr_Ct = (B(t_ref) T_base_cam)^-1 arc(t) B(t) T_base_cam, B = Ry(pitch) Rx(roll) (as Tilt in
/// sensor/imu.h).
class PitchedArcModel : public TrajectoryModel {
 public:
  PitchedArcModel(double omega, double v, int64_t t_ref_ns, const Pose3& T_base_cam, double pitch,
                  double pitch_rate, double roll = 0.0);
  int numParams() const override { return 2; }
  int64_t referenceTime() const override { return t_ref_ns_; }
  bool covers(int64_t) const override { return true; }
  Pose3 T_Cr_Ct(int64_t t_ns, PoseJacobian* jac = nullptr) const override;
  /// The road (base_link z = 0 at t_ref) in the reference camera frame.
  GroundPlane groundInReference() const;

 private:
  Pose3 T_ground_cam(int64_t t_ns) const;  // the camera at t in the arc's road frame at t
  double omega_, v_;
  int64_t t_ref_ns_;
  Pose3 T_base_cam_, T_ref_inv_;
  double pitch_, pitch_rate_, roll_;
};

class GroundYaw {
 public:
  GroundYaw(const GroundYawOptions& options, const CameraModel& camera, const Pose3& T_base_cam);
  bool enabled() const { return options_.weight > 0 && objectives_.front()->groundPixels() > 0; }
  const GroundYawOptions& options() const { return options_; }
  /// The road's yaw rate of a window's events [t0, t1] (all of them: this picks the road's),
  /// driven at v [m/s] about t_ref and accelerating at dv [m/s^2] (the dive's centre for the
  /// pitch), searched around omega_center [rad/s] (the VWE's) and, where that lies further than
  /// half_range_rad_s from it, around omega_prior too (the previous window's; NaN: none).
  GroundYawEstimate estimate(const EventVector& events, int64_t t0_ns, int64_t t1_ns,
                             int64_t t_ref_ns, double v, double dv, double omega_center,
                             uint64_t seed,
                             double omega_prior = std::numeric_limits<double>::quiet_NaN());
  /// The road's share of a window's yaw rate for this estimate: GroundYawOptions::weight; where
  /// it lies apart from the VWE's, 1 if the previous window's yaw rate is near it (the VWE's peak
  /// was spurious) and 0 if not (the road's was); 0 where the road's contrast has no peak or it is
  /// not valid.
  double share(const GroundYawEstimate& road) const;

 private:
  struct Params {
    double omega, pitch, pitch_rate, roll;
  };
  /// The contrast at each of `params`, in parallel.
  std::vector<double> evaluate(const std::vector<Params>& params);

  GroundYawOptions options_;
  Pose3 T_base_cam_;
  ThreadPool pool_;
  std::vector<std::unique_ptr<GroundObjective>> objectives_;  // one per thread
  EventVector road_;                                          // the window's road events
  GroundEvents events_;                                       // of the window being estimated
  int64_t t_ref_ns_ = 0;
  double v_ = 0.0;
  int evaluations_ = 0;
};

}  // namespace vwe_vo
