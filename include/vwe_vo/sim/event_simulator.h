// ESIM-style event camera simulator: renders the scene's log intensity on the sensor at adaptive
// time steps (per 16x16 tile: a tile is re-rendered only just before its own predicted image
// motion reaches max_pixel_motion_px), interpolates it linearly in time per pixel and emits an
// event at every crossing of the pixel's contrast threshold, with per-pixel threshold mismatch, a
// refractory period, background-activity noise, hot pixels and an optional illumination toggle (HDR
// / low light).
#pragma once

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <random>
#include <string>
#include <vector>

#include "vwe_vo/common/math.h"
#include "vwe_vo/common/thread_pool.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sensor/events.h"
#include "vwe_vo/sim/scene.h"
#include "vwe_vo/sim/vehicle_trajectory.h"

namespace vwe_vo {
namespace sim {

enum class IlluminationMode {
  kConstant,  // illumination factor 1 throughout
  kToggle,    // 1 <-> illumination_low every illumination_period_s with a short ramp
};

struct EventSimulatorOptions {
  double contrast_threshold = 0.2;  // nominal ON/OFF threshold C [log intensity]
  double threshold_sigma = 0.03;    // per-pixel threshold mismatch, std dev [log intensity]
  double min_threshold = 0.05;      // lower clamp of a pixel's threshold [log intensity]
  double refractory_s = 100e-6;     // refractory period after an event [s]
  double noise_rate_hz = 0.1;       // background-activity noise per pixel [Hz]
  int num_hot_pixels = 0;           // pixels that fire at hot_pixel_rate_hz [-]
  double hot_pixel_rate_hz = 50.0;  // rate of a hot pixel [Hz]
  double log_eps =
      0.02;  // dark-current floor added to linear intensity (white = 1) before the log [-]
  int supersampling = 1;             // s x s rays per pixel (textures are filtered anyway) [-]
  double max_pixel_motion_px = 1.0;  // adaptive render step: max predicted motion per step [px]
  double max_log_step = 0.05;  // adaptive step: max global log-illumination change per step [-]
  double min_render_step_s = 1e-4;  // lower bound of the render step [s]
  double max_render_step_s = 0.02;  // upper bound of the time between two renders of a tile [s]
  IlluminationMode illumination = IlluminationMode::kConstant;  // global illumination over time
  double illumination_low = 0.05;      // dark level of the toggle, factor of full light [-]
  double illumination_period_s = 4.0;  // time at each level of the toggle [s]
  double illumination_ramp_s = 0.2;    // duration of each transition [s]
  double dark_noise_rate_hz = 1.0;     // extra background activity per pixel at the dark level [Hz]
  int num_threads = 2;  // render threads of the simulator's pool (tile rows shared out) [-]
  uint64_t seed = 1;    // seed of threshold mismatch, noise and hot pixels [-]
  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

struct SimulatorStats {
  uint64_t renders = 0;           // number of render steps (each renders the tiles that need it)
  uint64_t tile_renders = 0;      // number of rendered 16x16 tiles
  uint64_t signal_events = 0;     // events from threshold crossings
  uint64_t noise_events = 0;      // background activity + hot pixels
  uint64_t refractory_drops = 0;  // crossings suppressed by the refractory period
};

class EventSimulator {
 public:
  /// The scene is copied (textures are shared); the first render happens at t = 0.
  EventSimulator(const Scene& scene, const CameraModel& camera, const Pose3& T_base_cam,
                 const VehicleTrajectory& trajectory, const EventSimulatorOptions& options = {});
  ~EventSimulator();

  /// Appends the events in (time(), t_end_ns], sorted by time, and advances time() to t_end_ns.
  /// May be called repeatedly to stream a sequence in chunks.
  void simulateUntil(int64_t t_end_ns, EventVector* out);
  int64_t time() const { return t_now_ns_; }

  Pose3 T_odom_cam(int64_t t_ns) const { return trajectory_.T_odom_base(t_ns) * T_base_cam_; }
  /// Global illumination factor at t (1 = full light).
  double illumination(int64_t t_ns) const;
  /// Background-activity rate per pixel at t [Hz] (higher in the dark).
  double noiseRate(int64_t t_ns) const;

  /// Ground-truth depth (z in the camera frame) [m] per pixel at t; 0 where nothing was hit.
  cv::Mat1f depthMap(int64_t t_ns);
  /// Linear irradiance image at t including the illumination factor (white = 1).
  cv::Mat1f intensityImage(int64_t t_ns);

  const SimulatorStats& stats() const { return stats_; }
  const CameraModel& camera() const { return camera_; }
  const VehicleTrajectory& trajectory() const { return trajectory_; }
  /// Per-pixel ON and OFF thresholds (row-major), for tests.
  const std::vector<float>& thresholdsOn() const { return c_on_; }

 private:
  // Predicts the image motion of every tile at t and from it the longest time each tile may go
  // between renders (tile_allowed_ns_); returns the next global step: 1 / kRenderSubsteps of the
  // fastest tile's time, so that every tile is rendered within a fraction of its own time.
  int64_t planStep(int64_t t_ns);
  // Renders at t1 the tiles that could not wait for one more step of next_step_ns (all if
  // flush) and appends their events since each tile's last render, plus the noise of (t0, t1],
  // unsorted.
  void step(int64_t t0_ns, int64_t t1_ns, int64_t next_step_ns, bool flush, EventVector* out);
  // Renders the due tiles of tile row `tile_row` at t1 and emits their threshold crossings into
  // thread_events_[thread].
  void processTileRow(int tile_row, int thread, int64_t t1_ns, float log_illum1);

  CameraModel camera_;
  Scene scene_;
  Pose3 T_base_cam_;
  VehicleTrajectory trajectory_;
  EventSimulatorOptions options_;
  std::unique_ptr<SceneRenderer> renderer_;
  std::unique_ptr<SceneRenderer> depth_renderer_;
  std::unique_ptr<ThreadPool> pool_;
  int width_, height_;
  int64_t t_now_ns_ = 0;
  std::vector<float> intensity_, depth_;   // last render
  std::vector<float> log_prev_, log_ref_;  // per pixel: last rendered and reference log intensity
  std::vector<float> c_on_, c_off_;        // per-pixel thresholds
  std::vector<int64_t> last_event_ns_;     // per pixel, for the refractory period
  int tiles_x_ = 0, tiles_y_ = 0;
  static constexpr int kRenderSubsteps = 2;  // global steps per render interval of the fastest tile
  std::vector<int64_t> tile_allowed_ns_;     // per tile: longest time between two renders [ns]
  std::vector<int64_t> tile_t_ns_;           // per tile: time of its last render
  std::vector<uint8_t> tile_due_;            // per tile: rendered in the current step
  double log_rate_ = 0.0;                    // |d log illumination / dt| [1/s]
  std::vector<int> hot_pixels_;
  std::vector<EventVector> thread_events_;
  std::vector<uint64_t> thread_drops_;
  // Sorts events by (time, row, column, polarity); scratch buffers kept between calls.
  void sortEvents(EventVector::iterator begin, EventVector::iterator end);
  EventVector sort_scratch_;
  std::vector<size_t> sort_start_;
  std::mt19937_64 noise_rng_;
  SimulatorStats stats_;
};

}  // namespace sim
}  // namespace vwe_vo
