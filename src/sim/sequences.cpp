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

VehicleTrajectoryOptions streetDriveMotion(std::vector<ProfileSegment>* profile,
                                           std::vector<ProfileSegment>* layout,
                                           VehicleTrajectoryOptions* layout_options) {
  const double v = 7.5, duration = 40.0;
  *profile = {{duration, v, 0.0}};
  VehicleTrajectoryOptions o;
  ContinuousMotion& m = o.motion;
  // Speed factor: accelerate to +18 %, brake hard to -20 % before the bend (0.3 g: the dive),
  // accelerate out of it, slow down again; a small ripple on top. Stays within +-25 %.
  m.speed_sines = {{0.04, 6.1, 0.0}};
  m.speed_changes = {{2.0, 3.0, 0.18}, {15.0, 1.6, -0.38}, {24.0, 4.0, 0.30}, {31.0, 2.5, -0.20}};
  // Weaving: two curvature sines in cosine phase (the heading oscillates about the street's
  // direction): +-4.3 and +-3.4 deg/s at 7.5 m/s, periods 8 s and 4.4 s.
  m.curvature_sines = {{0.010, 60.0, kPi / 2}, {0.008, 33.0, kPi / 2}};
  // Lane changes of 3 m over 26 m (peak heading 13 deg, peak yaw rate 12 deg/s at 7.5 m/s).
  m.lane_changes = {
      {40.0, 26.0, 3.0}, {100.0, 26.0, -3.0}, {215.0, 26.0, 3.0}, {262.0, 26.0, -3.0}};
  // The street bends 90 deg left (clothoid 12 m, arc 12 m on the axis); the car, in the outer
  // (right) lane 1.5 m off the axis, follows it on lengths scaled by (R + 1.5) / R.
  const double axis_clothoid = 12.0, axis_arc = 12.0;
  const double k_axis = (kPi / 2) / (axis_clothoid + axis_arc), lane_scale = 1.0 + 1.5 * k_axis;
  m.bends = {{150.0, axis_clothoid * lane_scale, axis_arc * lane_scale, kPi / 2}};
  // Right lane: 1.5 m right of the axis, less the weaving's mean lateral offset A lambda^2 / (4
  // pi^2).
  double weave_offset = 0.0;
  for (const CurvatureSine& c : m.curvature_sines)
    weave_offset += c.amplitude_per_m * c.wavelength_m * c.wavelength_m / (4 * kPi * kPi);
  o.start_xyyaw = Vec3(0.0, -1.5 - weave_offset, 0.0);
  // The street's axis: the same bend at the same distance, longer than the car's path.
  *layout = {{duration, 1.15 * v, 0.0}};
  *layout_options = VehicleTrajectoryOptions();
  layout_options->motion.bends = {{150.0, axis_clothoid, axis_arc, kPi / 2}};
  return o;
}

VehicleTrajectoryOptions indoorDriveMotion(std::vector<ProfileSegment>* profile) {
  const double v = 0.3, duration = 34.0;
  *profile = {{duration, v, 0.0}};
  VehicleTrajectoryOptions o;
  ContinuousMotion& m = o.motion;
  m.speed_sines = {{0.12, 9.0, 0.0}, {0.08, 4.1, 1.0}};
  // Two stops: 1.5 s braking, 2 s standstill, 1.5 s start.
  m.stops = {{9.0, 1.5, 2.0, 1.5}, {22.0, 1.5, 2.0, 1.5}};
  // Weaving (+-14 and +-9 deg/s at 0.3 m/s) and two 90-degree left bends (27 deg/s on the arc).
  m.curvature_sines = {{0.8, 3.0, kPi / 2}, {0.5, 1.7, kPi / 2}};
  m.bends = {{2.0, 0.4, 0.6, kPi / 2}, {5.5, 0.4, 0.6, kPi / 2}};
  o.start_xyyaw = Vec3(-1.0, -0.5, 0.0);
  return o;
}

SuspensionOptions carSuspension(uint64_t seed) {
  SuspensionOptions s;
  s.enabled = true;
  s.seed = seed;
  // ISO 8608 between class A and B (Gd(n0) = 16e-6 .. 64e-6 m^3 at n0 = 0.1 cycles/m).
  s.road_gd_m3 = 32e-6;
  s.road_n_min = 0.02;
  s.road_n_max = 5.0;
  // Expansion joints and patches: raised-cosine humps of 2-3 cm, one track or both.
  s.bumps = {
      {60.0, 0.6, 0.03, 0}, {125.0, 0.5, 0.025, 1}, {195.0, 0.4, -0.02, -1}, {240.0, 0.6, 0.03, 0}};
  s.wheelbase_m = 2.7;
  s.track_m = 1.55;
  // Ride frequencies of passenger cars ~1-1.5 Hz, damping ratio 0.2-0.4 (Gillespie,
  // Fundamentals of Vehicle Dynamics, ch. 5).
  s.heave_hz = 1.2;
  s.pitch_hz = 1.4;
  s.roll_hz = 1.5;
  s.damping_ratio = 0.3;
  // Pitch ~1.5 deg at 0.4 g of braking (1-2 deg per 0.3-0.5 g); roll gradient ~4 deg/g.
  s.pitch_per_g_rad = 3.75 * kRadPerDeg;
  s.roll_per_g_rad = 4.0 * kRadPerDeg;
  return s;
}

SuspensionOptions turtlebotSuspension(uint64_t seed) {
  SuspensionOptions s;
  s.enabled = true;
  s.seed = seed;
  // An office floor: wavelengths 5 cm .. 10 m, tilting the small base by ~0.5 deg.
  s.road_gd_m3 = 9e-6;
  s.road_n_min = 0.1;
  s.road_n_max = 20.0;
  s.road_differential = 1.0;
  s.wheelbase_m = 0.25;  // drive axle to caster
  s.track_m = 0.23;      // Kobuki wheel separation
  // A stiff base on tyres and casters: 4 Hz, well damped.
  s.heave_hz = 4.0;
  s.pitch_hz = 4.0;
  s.roll_hz = 4.0;
  s.damping_ratio = 0.5;
  s.pitch_per_g_rad = 3.0 * kRadPerDeg;
  s.roll_per_g_rad = 3.0 * kRadPerDeg;
  return s;
}

Scene buildSequenceScene(const SequenceSpec& spec, const VehicleTrajectory& trajectory) {
  if (spec.layout_profile.empty()) return buildScene(spec.scene, spec.seed, trajectory);
  const VehicleTrajectory layout =
      VehicleTrajectory::fromProfile(spec.layout_profile, spec.layout_trajectory);
  return buildScene(spec.scene, spec.seed, layout, &trajectory);
}

void SequenceSpec::reseed(uint64_t new_seed) {
  seed = new_seed;
  simulator.seed = new_seed;
  imu.seed = new_seed;
  trajectory.suspension.seed = new_seed;
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
  for (const bool flat : {false, true}) {
    SequenceSpec s;
    s.name = flat ? "street_drive_flat" : "street_drive";
    s.description = std::string(
                        "city streets, car at 5.6-9.4 m/s, weaving, 4 lane changes, a 90-degree "
                        "clothoid bend, ") +
                    (flat ? "no suspension (flat twin of street_drive)"
                          : "suspension: pitch/roll 1-2 deg, bumps, braking dive");
    s.scene = "street";
    s.seed = 31;
    s.trajectory = streetDriveMotion(&s.profile, &s.layout_profile, &s.layout_trajectory);
    if (!flat) s.trajectory.suspension = carSuspension(s.seed);
    s.T_base_cam = mountToTBaseCam(Vec3(1.5, 0.0, 1.4), 0.0, 5.0 * kRadPerDeg, 0.0);
    s.simulator.seed = s.seed;
    s.davis_imu = true;
    s.imu.seed = s.seed;
    out.push_back(s);
  }
  for (const bool flat : {false, true}) {
    SequenceSpec s;
    s.name = flat ? "indoor_drive_flat" : "indoor_drive";
    s.description =
        std::string(
            "lab room, turtlebot at 0.24-0.36 m/s and 0 at stops, weaving, two bends, two 2 s "
            "stops, ") +
        (flat ? "flat floor (flat twin of indoor_drive)" : "uneven floor: pitch/roll ~0.5 deg");
    s.scene = "indoor";
    s.seed = 32;
    s.trajectory = indoorDriveMotion(&s.profile);
    if (!flat) s.trajectory.suspension = turtlebotSuspension(s.seed);
    s.simulator.seed = s.seed;
    s.davis_imu = true;
    s.imu.seed = s.seed;
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
