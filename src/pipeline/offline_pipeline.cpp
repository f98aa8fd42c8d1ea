#include "vwe_vo/pipeline/offline_pipeline.h"

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>

#include "vwe_vo/eval/evaluation.h"
#include "vwe_vo/io/files.h"
#include "vwe_vo/io/ply.h"

namespace vwe_vo {
namespace {
using Clock = std::chrono::steady_clock;
double secondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// Events waiting for the back-end (64 MB; 2 s of the street's 1.9 M events/s): enough for the
// front-end to run on through a refinement (256 chunks of 1 ms had it wait 7 of 16 s).
constexpr size_t kMaxQueuedEvents = 4000000;
}  // namespace

OfflinePipeline::OfflinePipeline(const PipelineConfig& config)
    : config_(config),
      input_(config.input),
      camera_(config.camera),
      frontend_(config.frontend, camera_, config.T_base_cam) {
  if (config.frontend_only) return;
  backend_ = std::make_unique<Backend>(config.backend, camera_, config.T_base_cam);
  BackendDriverOptions driver_options;
  driver_options.odom_rate_hz = config.backend.output_rate_hz;
  // The input policy resets on gaps first; the driver's own rule is its second line (0: never).
  if (config.input.max_gap_s > 0) driver_options.max_gap_s = config.input.max_gap_s;
  BackendDriver::Callbacks callbacks;
  callbacks.odometry = [this](int64_t t_ns, const Pose3& T, double, double) {
    odometry_trajectory_.push_back({t_ns, T});
  };
  callbacks.refinement = [this](size_t) {
    auto spline = std::make_shared<const BSpline>(backend_->spline());
    std::lock_guard<std::mutex> lock(backend_mutex_);
    refined_ = std::move(spline);
  };
  driver_ = std::make_unique<BackendDriver>(backend_.get(), driver_options, callbacks);
  if (config.backend_thread) backend_thread_ = std::thread(&OfflinePipeline::backendLoop, this);
}

OfflinePipeline::~OfflinePipeline() {
  if (!backend_thread_.joinable()) return;
  {
    std::lock_guard<std::mutex> lock(backend_mutex_);
    backend_stop_ = true;
    backend_jobs_.clear();  // finish() waited for them; otherwise the run is abandoned
    backend_queued_events_ = 0;
  }
  backend_cv_.notify_all();
  backend_thread_.join();
}

void OfflinePipeline::runBackend(const BackendJob& job) {
  const auto t0 = Clock::now();
  if (job.reset) driver_->reset("the input reset: " + job.reset_why);
  driver_->addEvents(job.events);
  for (const ImuSample& s : job.imu) backend_->addImu(s);
  // The job's arcs are one batch (BackendDriver's processing rule).
  const int64_t newest_pending = job.arcs.empty() ? -1 : job.arcs.back().t_end_ns;
  for (ArcEstimate arc : job.arcs) {
    if (!arc_truth_.empty()) {
      double truth = 0.0;
      if (meanYawRate(arc_truth_, arc.t_start_ns, arc.t_end_ns, &truth)) {
        arc.omega = truth + arc_truth_blend_ * (arc.omega - truth);
        ++arcs_from_truth_;
      } else {
        ++arcs_outside_truth_;
      }
    }
    driver_->addArc(arc, newest_pending);
  }
  if (job.at_end) driver_->finish();
  backend_s_ += secondsSince(t0);
}

void OfflinePipeline::submitBackend(BackendJob job) {
  if (!backend_) return;
  if (!backend_thread_.joinable()) {
    runBackend(job);
    return;
  }
  std::unique_lock<std::mutex> lock(backend_mutex_);
  auto room = [&] { return backend_queued_events_ < kMaxQueuedEvents || backend_error_; };
  if (!room()) {
    ++backend_waits_;
    const auto t0 = Clock::now();
    backend_cv_.wait(lock, room);
    backend_wait_s_ += secondsSince(t0);
  }
  if (backend_error_) std::rethrow_exception(backend_error_);
  backend_queued_events_ += job.events.size();
  backend_jobs_.push_back(std::move(job));
  lock.unlock();
  backend_cv_.notify_all();
}

void OfflinePipeline::backendLoop() {
  std::unique_lock<std::mutex> lock(backend_mutex_);
  while (true) {
    backend_cv_.wait(lock, [&] { return backend_stop_ || !backend_jobs_.empty(); });
    if (backend_jobs_.empty()) return;
    BackendJob job = std::move(backend_jobs_.front());
    backend_jobs_.pop_front();
    backend_queued_events_ -= job.events.size();
    backend_busy_ = true;
    const bool failed = backend_error_ != nullptr;  // after an error the jobs are only drained
    lock.unlock();
    backend_cv_.notify_all();  // room in the queue
    std::exception_ptr error;
    if (!failed) {
      try {
        runBackend(job);
      } catch (...) {
        error = std::current_exception();
      }
    }
    lock.lock();
    if (error) backend_error_ = error;
    backend_busy_ = false;
    backend_cv_.notify_all();
  }
}

void OfflinePipeline::waitBackend() const {
  if (!backend_thread_.joinable()) return;
  std::unique_lock<std::mutex> lock(backend_mutex_);
  backend_cv_.wait(lock,
                   [&] { return (backend_jobs_.empty() && !backend_busy_) || backend_error_; });
  if (backend_error_) std::rethrow_exception(backend_error_);
}

void OfflinePipeline::setBackendArcsFromTruth(Trajectory3 truth, double blend) {
  if (!backend_)
    throw std::logic_error("setBackendArcsFromTruth: there is no back-end (frontend_only)");
  if (truth.empty()) throw std::invalid_argument("setBackendArcsFromTruth: the truth has no pose");
  if (!std::isfinite(blend))
    throw std::invalid_argument("setBackendArcsFromTruth: blend must be finite");
  if (t_first_ >= 0)
    throw std::logic_error("setBackendArcsFromTruth: call it before the first events");
  arc_truth_ = std::move(truth);
  arc_truth_blend_ = blend;
}

void OfflinePipeline::setFrontendFollowsBackend(const FollowOptions& options,
                                                bool frontend_has_odometry) {
  if (t_first_ >= 0)
    throw std::logic_error("setFrontendFollowsBackend: call it before the first events");
  follower_ = FrontendFollower(options, frontend_has_odometry);
}

void OfflinePipeline::setSpeedsMeasured(bool measured) {
  if (t_first_ >= 0) throw std::logic_error("setSpeedsMeasured: call it before the first events");
  if (backend_) backend_->setSpeedsMeasured(measured);
}

void OfflinePipeline::followBackend() {
  waitBackend();
  std::shared_ptr<const BSpline> spline;
  {
    std::lock_guard<std::mutex> lock(backend_mutex_);
    spline = refined_;
  }
  if (!spline || spline == followed_) return;
  followed_ = spline;
  follower_.follow(*spline, t_last_, &frontend_);
}

void OfflinePipeline::addEvents(const EventVector& raw) {
  // A reset hands on at least the event it happened at, so its job reaches the back-end.
  const bool reset = input_.process(raw, &input_events_) == TimestampAction::kReset;
  const EventVector& events = input_events_;
  if (reset) {
    frontend_.reset();
    if (!events.empty()) follower_.reset(events.front().t_ns);
  }
  if (events.empty()) return;
  if (t_first_ < 0) {
    t_first_ = events.front().t_ns;
    wall0_ = Clock::now();
  }
  t_last_ = std::max(t_last_, events.back().t_ns);
  events_ += events.size();
  const auto t0 = Clock::now();
  BackendJob job;
  if (frontend_.addEvents(events)) {
    int64_t oldest = events.front().t_ns;
    for (const PixelEvent& e : events) oldest = std::min(oldest, e.t_ns);
    follower_.reset(oldest);  // as frontend_node: splines from before the jump are not followed
  }
  for (const ArcEstimate& a : frontend_.process()) arcs_.push_back(a), job.arcs.push_back(a);
  frontend_s_ += secondsSince(t0);
  if (!backend_) return;
  job.events = events;
  job.imu.swap(imu_pending_);
  const bool follow = follower_.changesArcs() && !job.arcs.empty();
  if (reset) job.reset = true, job.reset_why = input_.lastEvent();
  submitBackend(std::move(job));
  if (follow) followBackend();
}

void OfflinePipeline::addOdometry(int64_t t_ns, double v, double w) {
  frontend_.addOdometry(t_ns, v, w);
  if (baseline_) baseline_->addOdometry(t_ns, v, w);
}

void OfflinePipeline::enableBaseline() {
  if (!baseline_)
    baseline_ = std::make_unique<FrameBaseline>(config_.baseline, camera_, config_.T_base_cam);
}

void OfflinePipeline::addFrame(int64_t t_ns, const cv::Mat& image) {
  if (baseline_) baseline_->addFrame(t_ns, image);
}
void OfflinePipeline::addGyro(int64_t t_ns, double w) {
  frontend_.addGyro(t_ns, w);
}

void OfflinePipeline::enableImu() {
  if (!backend_) throw std::logic_error("OfflinePipeline::enableImu: no back-end (frontend_only)");
  backend_->enableImu(config_.imu, config_.imu.T_cam_imu());
}

void OfflinePipeline::addImu(const ImuSample& sample) {
  if (usesImu()) imu_pending_.push_back(sample);
}

void OfflinePipeline::finish() {
  const auto t0 = Clock::now();
  BackendJob job;
  job.at_end = true;
  job.imu.swap(imu_pending_);
  for (const ArcEstimate& a : frontend_.process()) arcs_.push_back(a), job.arcs.push_back(a);
  frontend_s_ += secondsSince(t0);
  submitBackend(std::move(job));
  waitBackend();
  if (t_first_ >= 0) pipeline_wall_s_ = secondsSince(wall0_);
}

void OfflinePipeline::startMapping(const std::string& depth_png_dir) {
  waitBackend();
  // The back-end's spline sampled densely (linear/slerp in between is far below a pixel).
  map_trajectory_ =
      backend_ && backend_->hasSpline() ? backend_->sampleTrajectory(200.0) : frontendTrajectory();
  mapper_ = std::make_unique<EmvsMapper>(config_.mapping, camera_);
  map_ = std::make_unique<GlobalMap>(config_.global_map);
  depth_png_dir_ = depth_png_dir;
  if (!depth_png_dir_.empty()) makeDirs(depth_png_dir_);
}

void OfflinePipeline::onKeyframes(const std::vector<EmvsKeyframe>& keyframes) {
  for (const EmvsKeyframe& kf : keyframes) {
    map_->insert(kf.points_odom);
    map_counts_ += kf.counts;
    if (!depth_png_dir_.empty()) {
      char name[64];
      std::snprintf(name, sizeof(name), "/depth_%04zu.png", map_keyframes_);
      const std::string path = depth_png_dir_ + name;
      if (!cv::imwrite(path, colorizeDepth(kf.depth_m, config_.mapping.volume.z_min_m,
                                           config_.mapping.volume.z_max_m)))
        throw std::runtime_error("cannot write " + path);
    }
    ++map_keyframes_;
  }
}

void OfflinePipeline::addMappingEvents(const EventVector& events) {
  if (!mapper_) throw std::logic_error("OfflinePipeline: addMappingEvents before startMapping");
  const auto t0 = Clock::now();
  const Pose3 T_base_cam = config_.T_base_cam;
  const auto pose = [this, &T_base_cam](int64_t t_ns, Pose3* T_odom_cam) {
    Pose3 T_odom_base;
    if (!interpolateTrajectory(map_trajectory_, t_ns, &T_odom_base)) return false;
    *T_odom_cam = T_odom_base * T_base_cam;
    return true;
  };
  mapper_->addEvents(events);
  // Everything is final offline: events the trajectory does not cover are skipped and counted.
  onKeyframes(mapper_->process(pose, std::numeric_limits<int64_t>::max()));
  mapping_s_ += secondsSince(t0);
}

void OfflinePipeline::finishMapping() {
  if (!mapper_) return;
  const auto t0 = Clock::now();
  EmvsKeyframe last;
  if (mapper_->finish(&last)) onKeyframes({last});
  mapping_s_ += secondsSince(t0);
}

Trajectory3 OfflinePipeline::backendTrajectory() const {
  if (!backend_) return {};
  waitBackend();
  return backend_->sampleTrajectory(config_.backend.output_rate_hz);
}

void writeSplineJson(const std::string& path, const BSpline& spline) {
  nlohmann::json j;
  j["degree"] = spline.degree();
  j["epoch_ns"] = spline.epochNs();
  j["epoch_s"] = nsToSec(spline.epochNs());
  j["valid_from_s"] = spline.validFrom();
  j["valid_to_s"] = spline.validTo();
  j["knots_s"] = spline.knots();
  nlohmann::json cps = nlohmann::json::array();
  for (const Vec2& p : spline.controlPoints()) cps.push_back({p.x(), p.y()});
  j["control_points_m"] = cps;
  nlohmann::json still = nlohmann::json::array();
  for (const BSpline::Interval& s : spline.standstills()) still.push_back({s.from_s, s.to_s});
  j["standstills_s"] = still;
  std::ofstream out(path);
  if (!out) throw std::runtime_error("cannot write " + path);
  out << j.dump(2) << "\n";
}

Trajectory3 OfflinePipeline::frontendTrajectory() const {
  return integrateArcs(arcs_, secToNs(0.01));
}

void writeArcsCsv(const std::string& path, const std::vector<ArcEstimate>& arcs) {
  FILE* f = std::fopen(path.c_str(), "w");
  if (!f) throw std::runtime_error("cannot write " + path + ": " + std::strerror(errno));
  std::fprintf(f,
               "t_ref,t_start,t_end,omega,v,contrast,confidence,num_events,window_events,status,"
               "evaluations,roll_rate,omega_without_roll,road_omega,road_pitch,road_roll,"
               "road_pitch_rate,road_curvature,road_share\n");
  for (const ArcEstimate& a : arcs)
    std::fprintf(
        f,
        "%.9f,%.9f,%.9f,%.9f,%.6f,%.9g,%.6f,%u,%zu,%s,%d,%.6f,%.9f,%.9f,%.7f,%.7f,%.7f,%.6g,"
        "%.4f\n",
        nsToSec(a.t_ref_ns), nsToSec(a.t_start_ns), nsToSec(a.t_end_ns), a.omega, a.v, a.contrast,
        a.confidence, a.num_events, a.window_events, toString(a.status), a.evaluations, a.roll_rate,
        a.omegaWithoutRoll(), a.road_omega, a.road_pitch, a.road_roll, a.road_pitch_rate,
        a.road_curvature, a.road_share);
  std::fclose(f);
}

nlohmann::json OfflinePipeline::report() const {
  waitBackend();
  const double duration = t_first_ >= 0 ? dtSec(t_last_, t_first_) : 0.0;
  size_t by_status[4] = {0, 0, 0, 0};
  for (const ArcEstimate& a : arcs_) ++by_status[int(a.status)];
  const FrontendStats& st = frontend_.stats();
  nlohmann::json j;
  j["duration_s"] = duration;
  j["events"] = events_;
  j["windows"] = arcs_.size();
  const double total_s = processingSeconds();
  j["processing_s"] = total_s;
  j["real_time_factor"] = duration > 0 ? total_s / duration : 0.0;
  // Front-end and back-end together, by the wall clock (the stages' busy times are below).
  j["event_pipeline"] = {{"wall_s", pipeline_wall_s_},
                         {"real_time_factor", duration > 0 ? pipeline_wall_s_ / duration : 0.0},
                         {"backend_thread", backend_thread_.joinable()},
                         {"frontend_waits_for_backend", backend_waits_},
                         {"frontend_wait_s", backend_wait_s_}};
  j["stages"]["frontend"] = {
      {"processing_s", frontend_s_},
      {"real_time_factor", duration > 0 ? frontend_s_ / duration : 0.0},
      {"windows", arcs_.size()},
      {"windows_ok", by_status[0]},
      {"windows_standstill", by_status[1]},
      {"windows_lost", by_status[2]},
      {"windows_low_events", by_status[3]},
      {"windows_dropped", st.windows_dropped},
      {"windows_split", st.windows_split},
      {"windows_standstill_edges", st.windows_standstill_edges},
      {"windows_restart_slower", st.windows_restart_slower},
      {"windows_one_sided", st.windows_one_sided},
      {"windows_one_sided_near", st.windows_one_sided_near},
      {"windows_rolled", st.windows_rolled},
      {"windows_ground", st.windows_ground},
      {"windows_ground_few", st.windows_ground_few},
      {"windows_ground_alone", st.windows_ground_alone},
      {"windows_ground_refused", st.windows_ground_refused},
      {"ground_evaluations", st.ground_evaluations},
      {"mean_ground_shift_deg_s", st.windows_ground > 0 ? st.ground_shift_abs_sum_rad_s *
                                                              kDegPerRad / double(st.windows_ground)
                                                        : 0.0},
      {"objective_evaluations", st.evaluations},
      {"events_ground_masked", st.events_ground_masked},
      {"follows_backend", follower_.changesArcs()},
      {"speeds_from_backend", follower_.speedsTaken()}};
  if (backend_) {
    const BackendStats& b = backend_->stats();
    j["stages"]["backend"] = {
        {"processing_s", backend_s_},
        {"real_time_factor", duration > 0 ? backend_s_ / duration : 0.0},
        {"solver_s", b.solver_s},
        {"updates", b.updates},
        {"volumes", b.volumes},
        {"volumes_skipped", b.volumes_skipped},
        {"objective_evaluations", b.evaluations},
        {"refinements_rejected", b.rejected},
        {"solver_iterations", b.solver_iterations},
        {"refinements_at_max_iterations", b.max_iteration_stops},
        {"refinements_accepted", b.accepted},
        {"mean_objective_gain", b.accepted > 0 ? b.gain_sum / double(b.accepted) : 0.0},
        {"yaw_scans", b.yaw_scans},
        {"yaw_scans_moved", b.yaw_scans_moved},
        {"outlier_runs_tried", b.outlier_runs_tried},
        {"outlier_runs_replaced", b.outlier_runs_replaced},
        {"stop_ramps", b.stop_ramps},
        {"start_ramps", b.start_ramps},
        {"standstill_gaps_closed", b.standstill_gaps_closed},
        {"mean_yaw_scan_offset_deg_s",
         b.yaw_scans > 0 ? b.yaw_scan_abs_sum_rad_s / double(b.yaw_scans) * 180.0 / M_PI : 0.0},
        {"arcs_held", b.arcs_held},
        {"arcs_stale", driver_->stats().arcs_stale},
        {"gaps", driver_->stats().gaps},
        {"loops", driver_->stats().loops},
        {"refinements_merged", driver_->stats().refinements_merged},
        {"resets", b.resets},
        {"events_outside_sensor", b.events_outside},
        {"events_out_of_order", b.events_out_of_order},
        {"events_parallax_masked", b.events_masked},
        {"control_points", backend_->hasSpline() ? backend_->spline().numControlPoints() : 0},
        {"pose_tilt", !backend_->tiltInPose() ? "planar"
                      : backend_->usesImu()   ? "imu"
                                              : "accelerations"}};
    if (!arc_truth_.empty())
      j["stages"]["backend"]["arcs_from_truth"] = {{"blend", arc_truth_blend_},
                                                   {"arcs", arcs_from_truth_},
                                                   {"arcs_outside_truth", arcs_outside_truth_}};
    if (backend_->usesImu()) {
      const BackendImuStats& m = backend_->imuStats();
      // The gyro bias in the IMU's frame (as the sensor reports it, imu_bias.txt) and base_link.
      const Mat3 R_base_imu = config_.T_base_cam.linear() * config_.imu.T_cam_imu().linear();
      const Vec3 b_imu = R_base_imu.transpose() * m.gyro_bias_base;
      j["stages"]["backend"]["imu"] = {
          {"samples", m.samples_in},
          {"samples_dropped", m.samples_dropped},
          {"gyro_prior_bins", m.prior_bins},
          {"bias_updates", m.bias_updates},
          {"bias_refused", m.bias_refused},
          {"yaw_rate_bias_deg_s", m.yaw_bias_rad_s * kDegPerRad},
          {"yaw_rate_bias_sigma_deg_s", m.yaw_bias_sigma_rad_s * kDegPerRad},
          {"tilt_in_pose", m.tilt_in_pose},
          {"gyro_bias_base_deg_s",
           {m.gyro_bias_base.x() * kDegPerRad, m.gyro_bias_base.y() * kDegPerRad,
            m.gyro_bias_base.z() * kDegPerRad}},
          {"gyro_bias_imu_deg_s",
           {b_imu.x() * kDegPerRad, b_imu.y() * kDegPerRad, b_imu.z() * kDegPerRad}},
          {"attitude_samples", m.attitude.samples},
          {"attitude_corrections_skipped", m.attitude.corrections_skipped},
          {"attitude_gaps", m.attitude.gaps}};
    }
  }
  if (mapper_) {
    j["stages"]["mapping"] = {
        {"processing_s", mapping_s_},
        {"real_time_factor", duration > 0 ? mapping_s_ / duration : 0.0},
        {"trajectory", backend_ && backend_->hasSpline() ? "backend" : "frontend"},
        {"keyframes", map_keyframes_},
        {"events", map_counts_.events},
        {"events_voted", map_counts_.voted},
        {"events_not_covered", map_counts_.skipped_time},
        {"events_nan_pose", map_counts_.skipped_nan},
        {"events_behind", map_counts_.skipped_behind},
        {"events_outside_sensor", map_counts_.skipped_outside},
        {"events_out_of_order", mapper_->droppedOutOfOrder()},
        {"events_thinned_pending", mapper_->thinnedPending()},
        {"events_thinned", mapper_->thinned()},
        {"keyframes_left_out", mapper_->keyframesSkipped()},
        {"keyframe_points", map_counts_.points},
        {"outliers_removed", map_counts_.outliers},
        {"map_points", map_->size()},
        {"map_points_dropped", map_->dropped()}};
  }
  if (baseline_) {
    const FrameBaselineStats& b = baseline_->stats();
    const auto& est = baseline_->estimates();
    // Tracked fraction: time between frames covered by an OK or STANDSTILL estimate.
    double covered = 0, span = 0;
    for (const FrameEstimate& e : est) {
      if (e.t_prev_ns < 0 || e.status == FrameStatus::kFirst) continue;
      if (e.status == FrameStatus::kOk || e.status == FrameStatus::kStandstill)
        covered += dtSec(e.t_ns, e.t_prev_ns);
    }
    if (est.size() > 1) span = dtSec(est.back().t_ns, est.front().t_ns);
    const double frames_span = span > 0 ? span : duration;
    j["stages"]["baseline"] = {
        {"processing_s", b.processing_s},
        {"real_time_factor", frames_span > 0 ? b.processing_s / frames_span : 0.0},
        {"frames", b.frames},
        {"frames_ok", b.ok},
        {"frames_standstill", b.standstill},
        {"frames_lost", b.lost},
        {"tracked_fraction", span > 0 ? covered / span : 0.0}};
  }
  const TimestampPolicyStats& in = input_.stats();
  j["input"] = {{"packets", in.packets},
                {"backward_jumps", in.backward_jumps},
                {"events_absorbed", in.events_absorbed},
                {"largest_backward_jump_s", in.largest_backward_jump_s},
                {"resets", in.resets},
                {"resets_backward_jump", in.resets_backward},
                {"resets_gap", in.resets_gap},
                {"events_dropped_at_reset", in.events_dropped_at_reset},
                {"largest_gap_s", in.largest_gap_s},
                {"max_backward_jump_s", config_.input.max_backward_jump_s},
                {"max_gap_s", config_.input.max_gap_s}};
  j["dropped"] = {{"events_outside_sensor", st.events_outside},
                  {"events_out_of_order", st.events_out_of_order},
                  {"resets", st.resets}};
  j["config"] = config_.path;
  return j;
}

void OfflinePipeline::writeOutputs(const std::string& out_dir, const nlohmann::json& extra) const {
  waitBackend();
  makeDirs(out_dir);
  writeTum(out_dir + "/frontend.tum", frontendTrajectory());
  writeArcsCsv(out_dir + "/arcs.csv", arcs_);
  if (backend_ && backend_->hasSpline()) {
    writeTum(out_dir + "/backend.tum", backendTrajectory());
    writeTum(out_dir + "/odom.tum", odometry_trajectory_);
    writeSplineJson(out_dir + "/spline.json", backend_->spline());
  }
  if (map_) writePly(out_dir + "/map.ply", toPlyCloud(map_->points()));
  if (baseline_) writeTum(out_dir + "/baseline.tum", baseline_->trajectory());
  nlohmann::json j = report();
  for (auto it = extra.begin(); it != extra.end(); ++it) {
    if (j.contains(it.key()) && j[it.key()].is_object() && it.value().is_object())
      j[it.key()].update(
          it.value());  // the caller's "input" (bag, packets) joins the policy's counts
    else
      j[it.key()] = it.value();
  }
  std::ofstream(out_dir + "/report.json") << j.dump(2) << "\n";
}

}  // namespace vwe_vo
