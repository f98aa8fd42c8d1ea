#include "vwe_vo/sim/sequences.h"

#include <cmath>
#include <random>
#include <stdexcept>

namespace vwe_vo {
namespace sim {

std::vector<ProfileSegment> circleProfile(double v, double omega, double duration_s) {
  return {{duration_s, v, omega}};
}

std::vector<ProfileSegment> straightProfile(double v, double duration_s) {
  return {{duration_s, v, 0.0}};
}

std::vector<ProfileSegment> rotationProfile(double omega, double duration_s) {
  return {{duration_s, 0.0, omega}};
}

std::vector<ProfileSegment> longIndoorProfile(double v, double standstill_s) {
  // Turn segments turn by exactly duration * omega (blends are antisymmetric).
  return {
      {3.0, v, 0.0},                     // straight
      {3.0, 0.8 * v, 30 * kRadPerDeg},   // 90 deg left
      {2.5, v, 0.0},                     //
      {2.0, 0.7 * v, 45 * kRadPerDeg},   // 90 deg left, tighter
      {1.5, 0.6 * v, 0.0},               // slow down
      {standstill_s + 0.4, 0.0, 0.0},    // standstill (exactly zero for standstill_s)
      {2.5, v, 0.0},                     // go again
      {3.0, 0.8 * v, -30 * kRadPerDeg},  // 90 deg right
      {2.0, v, 0.0},                     //
      {2.0, 0.7 * v, 60 * kRadPerDeg},   // 120 deg left, fast yaw
      {1.5, 1.2 * v, 0.0},               // faster straight
      {3.0, 0.8 * v, 30 * kRadPerDeg},   // 90 deg left
      {1.1, v, 0.0},
  };
}

std::vector<ProfileSegment> figureEightProfile(double v, double omega) {
  const double loop = 2.0 * kPi / std::abs(omega);
  return {{loop, v, omega}, {loop, v, -omega}};
}

std::vector<ProfileSegment> streetProfile(uint64_t seed, double duration_s) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::vector<ProfileSegment> out;
  double t = 0.0;
  int turn_sign = 1;
  while (t < duration_s) {
    const double v = 5.0 + 3.0 * u01(rng);
    const double straight = std::min(duration_s - t, 6.0 + 6.0 * u01(rng));
    out.push_back({straight, v, 0.0});
    t += straight;
    if (t >= duration_s) break;
    // 90-degree turn at 5 m/s on a 12-16 m radius.
    const double v_turn = 5.0, radius = 12.0 + 4.0 * u01(rng);
    const double omega = turn_sign * v_turn / radius;
    const double d = (kPi / 2) / std::abs(omega);
    out.push_back({d, v_turn, omega});
    t += d;
    // Alternate mostly, sometimes turn the same way twice (a block around).
    if (u01(rng) < 0.7) turn_sign = -turn_sign;
  }
  return out;
}

double SequenceSpec::durationSec() const {
  double d = 0;
  for (const auto& s : profile) d += s.duration_s;
  return d;
}

std::vector<SequenceSpec> standardSequences() {
  std::vector<SequenceSpec> out;
  {
    SequenceSpec s;
    s.name = "indoor_circle";
    s.description = "lab room, turtlebot on a circle, 0.4 m/s, 25 deg/s (one loop)";
    s.scene = "indoor";
    s.seed = 11;
    s.profile = circleProfile(0.4, 25 * kRadPerDeg, 14.4);
    s.simulator.seed = s.seed;
    out.push_back(s);
  }
  {
    SequenceSpec s;
    s.name = "indoor_straight";
    s.description = "lab room, turtlebot straight ahead at 0.4 m/s";
    s.scene = "indoor";
    s.seed = 12;
    s.profile = straightProfile(0.4, 10.0);
    s.trajectory.start_xyyaw = Vec3(-2.0, 0.0, 0.0);
    s.simulator.seed = s.seed;
    out.push_back(s);
  }
  {
    SequenceSpec s;
    s.name = "indoor_long";
    s.description =
        "lab room, 0.35 m/s, left/right turns up to 60 deg/s, stop-and-go, 3 s standstill";
    s.scene = "indoor";
    s.seed = 13;
    s.profile = longIndoorProfile(0.35, 3.0);
    s.simulator.seed = s.seed;
    out.push_back(s);
  }
  {
    SequenceSpec s;
    s.name = "indoor_hdr";
    s.description =
        "lab room circle 0.35 m/s, 20 deg/s; light toggles 1 <-> 0.05 every 4 s, more noise in the "
        "dark";
    s.scene = "indoor";
    s.seed = 14;
    s.profile = circleProfile(0.35, 20 * kRadPerDeg, 18.0);
    s.simulator.seed = s.seed;
    s.simulator.illumination = IlluminationMode::kToggle;
    s.simulator.illumination_low = 0.05;
    s.simulator.illumination_period_s = 4.0;
    s.simulator.illumination_ramp_s = 0.2;
    s.simulator.dark_noise_rate_hz = 1.0;
    out.push_back(s);
  }
  {
    SequenceSpec s;
    s.name = "indoor_figure8";
    s.description = "lab room, figure eight at 0.35 m/s, +-30 deg/s";
    s.scene = "indoor";
    s.seed = 15;
    s.profile = figureEightProfile(0.35, 30 * kRadPerDeg);
    s.simulator.seed = s.seed;
    out.push_back(s);
  }
  {
    SequenceSpec s;
    s.name = "corridor_straight";
    s.description = "corridor 2.4 m wide, doors and posters, straight at 0.5 m/s";
    s.scene = "corridor";
    s.seed = 16;
    s.profile = straightProfile(0.5, 12.0);
    s.simulator.seed = s.seed;
    out.push_back(s);
  }
  {
    SequenceSpec s;
    s.name = "street_long";
    s.description =
        "city streets, car at 5-8 m/s, 90-degree turns, facades 5-8 m from the road centre";
    s.scene = "street";
    s.seed = 21;
    s.profile = streetProfile(s.seed, 40.0);
    // A car mount: 1.4 m above the road, 1.5 m ahead of the rear axle, pitched 5 deg down.
    s.T_base_cam = mountToTBaseCam(Vec3(1.5, 0.0, 1.4), 0.0, 5.0 * kRadPerDeg, 0.0);
    s.simulator.seed = s.seed;
    out.push_back(s);
  }
  return out;
}

SequenceSpec findSequence(const std::string& name) {
  const auto all = standardSequences();
  std::string valid;
  for (const auto& s : all) {
    if (s.name == name) return s;
    valid += (valid.empty() ? "" : ", ") + s.name;
  }
  throw std::invalid_argument("unknown sequence '" + name + "' (valid: " + valid + ")");
}

std::vector<SequenceInfo> listSequences() {
  std::vector<SequenceInfo> out;
  for (const auto& s : standardSequences()) {
    const auto tr = VehicleTrajectory::fromProfile(s.profile, s.trajectory);
    out.push_back({s.name, s.description, tr.durationSec(), tr.pathLength(), s.seed});
  }
  return out;
}

}  // namespace sim
}  // namespace vwe_vo
