// The simulator's standard sequences (scene, trajectory, simulator options, fixed seed) by name,
// and the trajectory kinds they are made of. These sequences are what accuracy is measured on.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "vwe_vo/io/config.h"
#include "vwe_vo/sim/event_simulator.h"
#include "vwe_vo/sim/imu_simulator.h"
#include "vwe_vo/sim/scene.h"
#include "vwe_vo/sim/vehicle_trajectory.h"

namespace vwe_vo {
namespace sim {

/// Trajectory kinds as speed / yaw-rate profiles.
std::vector<ProfileSegment> circleProfile(double v, double omega, double duration_s);
std::vector<ProfileSegment> straightProfile(double v, double duration_s);
/// Several turns of both signs, stop-and-go and one standstill (v = omega = 0) of standstill_s.
std::vector<ProfileSegment> longIndoorProfile(double v, double standstill_s = 3.0);
/// A left circle then a right circle of the same radius.
std::vector<ProfileSegment> figureEightProfile(double v, double omega);
/// City driving: straights at 5-8 m/s with 90-degree turns, as a grid of streets.
std::vector<ProfileSegment> streetProfile(uint64_t seed, double duration_s);
/// Continuous driving in city streets (street_drive): speed 7.5 m/s +-25 % with accelerations and
/// a hard braking, weaving, two pairs of lane changes and a 90-degree clothoid bend; the
/// street's axis (the scene layout) is returned in *layout.
VehicleTrajectoryOptions streetDriveMotion(std::vector<ProfileSegment>* profile,
                                           std::vector<ProfileSegment>* layout,
                                           VehicleTrajectoryOptions* layout_options);
/// Continuous driving of a turtlebot in a room (indoor_drive): 0.3 m/s +-20 %, two stops,
/// weaving and two 90-degree bends.
VehicleTrajectoryOptions indoorDriveMotion(std::vector<ProfileSegment>* profile);
/// Suspension of a passenger car on an ISO 8608 class A/B road with bumps, and of a turtlebot
/// on an office floor.
SuspensionOptions carSuspension(uint64_t seed);
SuspensionOptions turtlebotSuspension(uint64_t seed);
/// In place rotation (v = 0) at omega for duration_s.
std::vector<ProfileSegment> rotationProfile(double omega, double duration_s);

struct SequenceSpec {
  std::string name;
  std::string description;
  std::string scene;  // scene kind for buildScene()
  uint64_t seed = 1;  // scene, noise and threshold seed
  std::vector<ProfileSegment> profile;
  VehicleTrajectoryOptions trajectory;
  EventSimulatorOptions simulator;
  Pose3 T_base_cam = defaultTBaseCam();  // camera mount used unless the caller's config gives one
  // The scene's layout path (a street's axis) when the vehicle does not follow it; empty: the
  // scene is laid out along the vehicle's own path.
  std::vector<ProfileSegment> layout_profile;
  VehicleTrajectoryOptions layout_trajectory;
  // The DAVIS-like 1 kHz IMU (imu_simulator.h); off: the bag's /dvs/imu is the older 200 Hz
  // finite-difference gyro of the flat sequences, and no imu.txt is written.
  bool davis_imu = false;
  ImuOptions imu;
  double durationSec() const;
  /// Another realisation of the same sequence: the scene, the event noise and thresholds, the
  /// suspension's road and the IMU's noise and bias all follow `seed` (vwe_vo_sim --seed); the
  /// planned motion stays.
  void reseed(uint64_t seed);
};

/// The sequence's scene: along layout_profile when it has one (keeping clear of the vehicle's
/// path too), else along the vehicle's path.
Scene buildSequenceScene(const SequenceSpec& spec, const VehicleTrajectory& trajectory);

/// All standard sequences, in a fixed order.
std::vector<SequenceSpec> standardSequences();
/// The named standard sequence; throws std::invalid_argument listing the valid names.
SequenceSpec findSequence(const std::string& name);

struct SequenceInfo {
  std::string name, description;
  double duration_s = 0;     // [s]
  double path_length_m = 0;  // [m]
  uint64_t seed = 0;         // fixed seed of the sequence
};
std::vector<SequenceInfo> listSequences();

}  // namespace sim
}  // namespace vwe_vo
