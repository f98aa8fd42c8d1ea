// The pipeline run at full speed over recorded data (the offline runner and the benchmarks): the
// same core objects the nodes use, fed in time order, with timing per stage. As frontend_node and
// backend_node do live, the back-end runs beside the front-end (its own thread, unless
// config.backend_thread is false) through the same BackendDriver and gets the same inputs in the
// same order, and the front-end can follow the back-end (FrontendFollower) as frontend_node does:
// the results do not depend on the threading.
#pragma once

#include <chrono>
#include <condition_variable>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "vwe_vo/backend/backend.h"
#include "vwe_vo/backend/backend_driver.h"
#include "vwe_vo/baseline/frame_baseline.h"
#include "vwe_vo/frontend/frontend.h"
#include "vwe_vo/io/options_yaml.h"
#include "vwe_vo/io/trajectory_io.h"
#include "vwe_vo/mapping/emvs.h"

namespace vwe_vo {

class OfflinePipeline {
  using Clock = std::chrono::steady_clock;

 public:
  explicit OfflinePipeline(const PipelineConfig& config);
  ~OfflinePipeline();
  OfflinePipeline(const OfflinePipeline&) = delete;
  OfflinePipeline& operator=(const OfflinePipeline&) = delete;

  /// Feeds events (any chunk size, one sensor packet or more) and runs the stages that can run.
  /// The input's timestamp policy (config.input) comes first: events older than the newest are
  /// dropped and counted, a large jump back or a long gap resets the front-end and the back-end.
  void addEvents(const EventVector& events);
  /// The input's throttled warning about timestamp jumps and resets (empty: nothing to say);
  /// at the end, inputSummary() gives the jumps not yet warned about.
  std::string takeInputWarning() { return input_.takeWarning(); }
  std::string inputSummary() { return input_.takeSummary(); }
  const TimestampPolicy& input() const { return input_; }
  void addOdometry(int64_t t_ns, double v_mps, double yaw_rate_rad_s);
  void addGyro(int64_t t_ns, double yaw_rate_rad_s);
  /// The back-end fuses the IMU (config.imu; Backend::enableImu). Call before the first data.
  void enableImu();
  bool usesImu() const { return backend_ && backend_->usesImu(); }
  /// One IMU sample in the IMU frame (ignored unless enableImu()); it goes to the back-end with
  /// the next events, in input order. The front-end's gyro prior takes addGyro() as before.
  void addImu(const ImuSample& sample);
  /// Processes what is left and waits for the back-end. Call once at the end. An error of the
  /// back-end's thread is rethrown here (or by the next addEvents).
  void finish();

  /// The front-end follows the back-end's refined spline as frontend_node does
  /// (FrontendFollower; off unless called): after each job whose arcs triggered a refinement,
  /// the front-end takes the spline's speed before it goes on, unless frontend_has_odometry. Only
  /// then does following change the outputs, so only then does the front-end wait for the
  /// back-end's job (the two stages run in turn). Call before the first events.
  void setFrontendFollowsBackend(const FollowOptions& options, bool frontend_has_odometry);
  /// Whether the front-end's speeds come from /odom (the default) or are its nominal speed: the
  /// back-end then holds only the scale, not the speed shape (Backend::setSpeedsMeasured).
  void setSpeedsMeasured(bool measured);

  /// Runs the frame-based baseline (config.baseline) on frames given to addFrame().
  void enableBaseline();
  /// A mono8 APS frame for the baseline (ignored unless enableBaseline() was called); throws
  /// std::invalid_argument for a frame of another size or type than the calibration.
  void addFrame(int64_t t_ns, const cv::Mat& image);
  /// Null unless enableBaseline() was called.
  const FrameBaseline* baseline() const { return baseline_.get(); }

  /// Research (vwe_vo_offline --truth-arcs): the back-end gets, instead of each front-end arc's
  /// yaw rate w, the truth's mean rate w_true over the arc's window moved towards w by `blend`:
  /// w_true + blend * (w - w_true). Blend 0 starts the refinement at the truth (what is left then
  /// is the back-end objective's own bias), blend 0.5 halfway (how much of a front-end error it
  /// corrects). Arcs outside the truth keep w and are counted. The front-end's outputs (arcs.csv,
  /// frontend.tum) are unchanged. Call before the first events; throws without a back-end.
  void setBackendArcsFromTruth(Trajectory3 truth, double blend);

  const std::vector<ArcEstimate>& arcs() const { return arcs_; }
  /// Front-end dead reckoning (integrateArcs) of base_link in odom, every 10 ms.
  Trajectory3 frontendTrajectory() const;

  /// Back-end trajectory sampled at backend.output_rate_hz (empty without a back-end).
  Trajectory3 backendTrajectory() const;
  /// The back-end (null if config.frontend_only), once it has caught up with the input.
  const Backend* backend() const {
    waitBackend();
    return backend_.get();
  }
  /// The continuous odometry backend_node would publish live (/vwe/odom, REP-105): each pose
  /// composed from the back-end's estimate when its arc arrived, before the refinement it
  /// triggers, at backend.output_rate_hz; a pose once out is never changed.
  const Trajectory3& odometryTrajectory() const {
    waitBackend();
    return odometry_trajectory_;
  }

  /// Mapping (EMVS) in a second pass over the events, after finish(): on the back-end's refined
  /// trajectory, or the front-end's dead reckoning with frontend_only. With depth_png_dir, a
  /// colour-coded depth PNG per keyframe is written there.
  void startMapping(const std::string& depth_png_dir = "");
  void addMappingEvents(const EventVector& events);
  void finishMapping();
  /// The fused cloud (null before startMapping()).
  const GlobalMap* map() const { return map_.get(); }

  /// Writes frontend.tum, arcs.csv, report.json and, with the back-end, backend.tum, odom.tum
  /// (odometryTrajectory()) and spline.json, with mapping map.ply (binary), with the baseline
  /// baseline.tum, into out_dir (created if missing).
  void writeOutputs(const std::string& out_dir, const nlohmann::json& extra = {}) const;
  nlohmann::json report() const;

  size_t events() const { return events_; }
  int64_t firstTime() const { return t_first_; }
  int64_t lastTime() const { return t_last_; }
  /// Wall-clock seconds of the event pipeline, from the first addEvents() to the end of finish()
  /// (what the caller does in between, such as decoding a bag or running the frame baseline,
  /// included), plus mapping's.
  double processingSeconds() const { return pipeline_wall_s_ + mapping_s_; }
  const Frontend& frontend() const { return frontend_; }

 private:
  PipelineConfig config_;
  TimestampPolicy input_;
  EventVector input_events_;  // the policy's output for the current chunk
  CameraModel camera_;
  Frontend frontend_;
  std::unique_ptr<Backend> backend_;
  std::unique_ptr<BackendDriver> driver_;  // feeds backend_ (on the back-end's thread)
  Trajectory3 odometry_trajectory_;
  FrontendFollower follower_{FollowOptions{false, FollowOptions().min_speed_mps}};
  std::shared_ptr<const BSpline> refined_;   // the newest refinement's spline (backend_mutex_)
  std::shared_ptr<const BSpline> followed_;  // the last one the front-end followed
  void followBackend();
  std::unique_ptr<FrameBaseline> baseline_;
  std::vector<ArcEstimate> arcs_;
  std::vector<ImuSample> imu_pending_;  // for the next back-end job
  Trajectory3 arc_truth_;               // setBackendArcsFromTruth()
  double arc_truth_blend_ = 0.0;
  size_t arcs_from_truth_ = 0, arcs_outside_truth_ = 0;
  size_t events_ = 0;
  int64_t t_first_ = -1, t_last_ = -1;
  double frontend_s_ = 0.0, backend_s_ = 0.0;  // busy time of each stage
  Clock::time_point wall0_;
  double pipeline_wall_s_ = 0.0;
  // The back-end's thread: jobs in input order, at most kMaxQueuedEvents events waiting.
  struct BackendJob {
    EventVector events;
    std::vector<ArcEstimate> arcs;  // the arcs the front-end made after these events
    std::vector<ImuSample> imu;     // IMU samples since the previous job (enableImu)
    bool at_end = false;
    bool reset = false;  // the input reset (a jump back or a gap): reset the back-end first
    std::string reset_why;
  };
  void submitBackend(BackendJob job);
  void backendLoop();
  /// Blocks until the back-end has done every job; rethrows its error.
  void waitBackend() const;
  void runBackend(const BackendJob& job);
  std::thread backend_thread_;
  mutable std::mutex backend_mutex_;
  mutable std::condition_variable backend_cv_;
  std::deque<BackendJob> backend_jobs_;
  size_t backend_queued_events_ = 0;
  bool backend_busy_ = false, backend_stop_ = false;
  std::exception_ptr backend_error_;
  size_t backend_waits_ = 0;  // the front-end waited for a full queue
  double backend_wait_s_ = 0.0;
  // Mapping.
  void onKeyframes(const std::vector<EmvsKeyframe>& keyframes);
  std::unique_ptr<EmvsMapper> mapper_;
  std::unique_ptr<GlobalMap> map_;
  Trajectory3 map_trajectory_;  // T_odom_base used by the mapper
  std::string depth_png_dir_;
  EmvsCounts map_counts_;
  size_t map_keyframes_ = 0;
  double mapping_s_ = 0.0;
};

/// Writes a spline as JSON: degree, knot epoch, knots [s], control points [m], standstills [s].
void writeSplineJson(const std::string& path, const BSpline& spline);

/// Writes the arcs as CSV (t_ref, t_start, t_end in s; omega, v, contrast, confidence, events,
/// status).
void writeArcsCsv(const std::string& path, const std::vector<ArcEstimate>& arcs);

}  // namespace vwe_vo
