// APS frames for the simulator, modelled on a DAVIS346 with its ROS driver: a global-shutter
// exposure that integrates the scene's irradiance (motion blur grows with the exposure), photo-
// electrons with shot noise, a full well that clips, read noise that limits the dynamic range to
// ~55 dB, per-pixel gain and offset non-uniformity, 8-bit output, and the driver's auto-exposure
// (trimmed-mean metering, capped at 25 ms, applied a frame late, first-order lag). The events'
// simulator is untouched: in its illumination toggle (HDR / low light) the frames under- and
// over-exposure and blur while the events keep their ~120 dB.
#pragma once

#include <cstdint>
#include <deque>
#include <opencv2/core.hpp>
#include <random>
#include <vector>

#include "vwe_vo/sim/event_simulator.h"

namespace vwe_vo {
namespace sim {

struct FrameSimulatorOptions {
  double rate_hz = 25.0;      // frame rate [Hz]
  double exposure_s = 5e-3;   // initial (and fixed, without auto-exposure) exposure [s]
  bool auto_exposure = true;  // exposure follows the frame's trimmed mean, late and with a lag
  double ae_target = 0.5;  // auto-exposure target: trimmed mean / full scale (driver: 128 DN) [-]
  double ae_trim_fraction =
      0.25;  // share of the darkest and of the brightest pixels left out of the metering [-]
  double ae_time_constant_s = 0.3;  // auto-exposure lag (first order in log exposure) [s]
  int ae_delay_frames =
      1;  // frames between the metered frame and the first one exposed with the result [-]
  double exposure_min_s = 10e-6;  // auto-exposure lower bound (driver: 10 us) [s]
  double exposure_max_s = 25e-3;  // auto-exposure upper bound (driver: 25 ms; < frame period) [s]
  double saturation_exposure_s =
      8e-3;  // exposure at which white (irradiance 1, full light) fills the well [s]
  double full_well_e = 10000.0;  // electrons at saturation (sets the shot noise) [e-]
  double read_noise_e = 18.0;    // temporal read noise, std dev: 20 log10(10000 / 18) = 55 dB [e-]
  double prnu = 0.01;            // photo-response (gain) non-uniformity per pixel, std dev [-]
  double dsnu_dn = 0.5;          // offset non-uniformity per pixel, std dev [DN]
  double black_level_dn = 2.0;   // offset of a dark pixel [DN]
  double blur_step_s = 2.5e-3;   // spacing of the renders averaged over an exposure [s]
  int max_blur_renders = 12;     // cap on renders per frame [-]
  uint64_t seed = 1;             // noise seed [-]
  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
  /// Full well over read noise [dB] (the 8-bit output adds quantisation on top).
  double dynamicRangeDb() const;
};

struct SimulatedFrame {
  int64_t t_ns = 0;                 // stamp: middle of the exposure
  double exposure_s = 0.0;          // exposure used [s]
  double saturated_fraction = 0.0;  // pixels at 255 [-]
  cv::Mat1b image;                  // mono8, sensor size
};

/// Renders frames through an EventSimulator's scene, camera, trajectory and illumination. The
/// event simulator's state is not changed (only its renderer is reused), so frames and events can
/// be generated in any interleaving.
class FrameSimulator {
 public:
  FrameSimulator(EventSimulator* simulator, const FrameSimulatorOptions& options = {});

  /// Frame k is stamped k / rate_hz. Returns the frames not yet returned with stamps <= t_end_ns
  /// (and within the sequence) and runs the auto-exposure after each; the exposure window is
  /// centred on the stamp and shifted to stay inside the sequence.
  std::vector<SimulatedFrame> simulateUntil(int64_t t_end_ns);
  /// The frame at an arbitrary stamp with the next frame's exposure (auto-exposure not run).
  SimulatedFrame render(int64_t t_ns);
  /// The exposure of the next frame of simulateUntil() [s].
  double exposure() const { return pending_exposures_.front(); }
  /// What the auto-exposure meters: the mean of the frame without the ae_trim_fraction darkest
  /// and brightest pixels, minus the black level, over full scale [-].
  double meteredLevel(const cv::Mat1b& image) const;

 private:
  SimulatedFrame renderWithExposure(int64_t t_ns, double exposure_s);

  EventSimulator* sim_;
  FrameSimulatorOptions options_;
  // Exposures of the next frames: [0] is the next one; the auto-exposure appends one per frame,
  // ae_delay_frames behind.
  std::deque<double> pending_exposures_;
  int64_t next_frame_index_ = 0;
  cv::Mat1f gain_;    // 1 + PRNU per pixel
  cv::Mat1f offset_;  // black level + DSNU per pixel [DN]
  std::mt19937_64 rng_;
};

}  // namespace sim
}  // namespace vwe_vo
