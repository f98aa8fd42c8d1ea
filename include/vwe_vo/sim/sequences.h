// The simulator's standard sequences (scene, trajectory, simulator options, fixed seed) by name,
// and the trajectory kinds they are made of. These sequences are what accuracy is measured on.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "vwe_vo/io/config.h"
#include "vwe_vo/sim/event_simulator.h"
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
  double durationSec() const;
};

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
