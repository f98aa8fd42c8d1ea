// APS frames for the simulator (DAVIS346-like, mono8): each frame integrates the scene's
// irradiance over its exposure (motion blur), with shot noise, read noise, fixed-pattern noise,
// 8-bit quantisation and a lagging auto-exposure, so that the simulator's illumination toggle
// (HDR / low light) under- and over-exposes frames the way a real APS does.
#pragma once

#include <cstdint>
#include <random>
#include <vector>

#include <opencv2/core.hpp>

#include "vwe_vo/core/sim/event_simulator.h"

namespace vwe_vo {
namespace sim {

struct FrameSimulatorOptions {
  double rate_hz = 25.0;                 // frame rate [Hz]
  double exposure_s = 5e-3;              // initial (and fixed, without auto-exposure) exposure [s]
  bool auto_exposure = true;             // exposure follows the image mean with a lag
  double ae_target = 0.4;                // auto-exposure target: mean / full scale [-]
  double ae_time_constant_s = 0.5;       // auto-exposure lag (first order) [s]
  double exposure_min_s = 0.1e-3;        // auto-exposure lower bound [s]
  double exposure_max_s = 30e-3;         // auto-exposure upper bound (< frame period) [s]
  double saturation_exposure_s = 8e-3;   // exposure at which white (irradiance 1) saturates [s]
  double full_well_e = 8000.0;           // electrons at saturation (sets the shot noise) [e-]
  double read_noise_dn = 1.5;            // read noise, std dev [DN of 255]
  double fpn_dn = 1.0;                   // fixed-pattern (per-pixel offset) noise, std dev [DN]
  double black_level_dn = 2.0;           // offset of a dark pixel [DN]
  double blur_step_s = 2.5e-3;           // spacing of the renders averaged over an exposure [s]
  int max_blur_renders = 12;             // cap on renders per frame [-]
  uint64_t seed = 1;                     // noise seed [-]
  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

struct SimulatedFrame {
  int64_t t_ns = 0;          // stamp: middle of the exposure
  double exposure_s = 0.0;   // exposure used [s]
  double saturated_fraction = 0.0;  // pixels at 255 [-]
  cv::Mat1b image;           // mono8, sensor size
};

/// Renders frames through an EventSimulator's scene, camera, trajectory and illumination. The
/// event simulator's state is not changed (only its renderer is reused), so frames and events can
/// be generated in any interleaving.
class FrameSimulator {
 public:
  FrameSimulator(EventSimulator* simulator, const FrameSimulatorOptions& options = {});

  /// Frame k is stamped k / rate_hz. Returns the frames not yet returned with stamps <= t_end_ns
  /// (and within the sequence) and advances the auto-exposure after each; the exposure window is
  /// centred on the stamp and shifted to stay inside the sequence.
  std::vector<SimulatedFrame> simulateUntil(int64_t t_end_ns);
  /// The frame at an arbitrary stamp with the current exposure (auto-exposure not advanced).
  SimulatedFrame render(int64_t t_ns);
  double exposure() const { return exposure_s_; }

 private:
  SimulatedFrame renderWithExposure(int64_t t_ns, double exposure_s);

  EventSimulator* sim_;
  FrameSimulatorOptions options_;
  double exposure_s_;
  int64_t next_frame_index_ = 0;
  cv::Mat1f fpn_;
  std::mt19937_64 rng_;
};

}  // namespace sim
}  // namespace vwe_vo
