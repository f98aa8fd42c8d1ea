#include "vwe_vo/vwe/vwe_objective.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "vwe_vo/common/validated.h"
#include "vwe_vo/vwe/ray_builder.h"

namespace vwe_vo {

VweObjective::VweObjective(const CameraModel& camera, ProjectiveVolume* volume)
    : camera_(camera), volume_(volume), pool_(volume->options().num_threads) {}

namespace {
// d[u0, du, v0, dv] of the VolumeRay of (o, d) (ax, ay = d_x / d_z, d_y / d_z) for a pose
// derivative that moves the direction by dd and the origin by dto.
inline Eigen::Vector4d rayDerivative(const Vec3& o, const Vec3& d, double ax, double ay,
                                     const Vec3& dd, const Vec3& dto, double fx, double fy) {
  const double dax = (dd.x() - ax * dd.z()) / d.z();
  const double day = (dd.y() - ay * dd.z()) / d.z();
  const double dbx = dto.x() - dto.z() * ax - o.z() * dax;
  const double dby = dto.y() - dto.z() * ay - o.z() * day;
  return Eigen::Vector4d(fx * dax, fx * dbx, fy * day, fy * dby);
}
}  // namespace

void VweObjective::buildChunk(const EventVector& events, size_t begin, size_t end,
                              const TrajectoryModel& model, bool with_jacobian, Chunk* out) const {
  out->rays.clear();
  out->jac_count.clear();
  out->jac_param.clear();
  out->jac_value.clear();
  out->times.clear();
  out->skipped_time = out->skipped_behind = 0;
  const double fx = volume_->fx(), fy = volume_->fy();
  const VolumeRayBuilder<double> make_ray(*volume_);
  const bool planar = with_jacobian && model.hasPlanarJacobian();
  PoseJacobian& pj = out->pose_jac;
  PlanarLocalJacobian lj;
  // The pose of a slice is computed once; slices lie on a fixed grid of absolute times, so the
  // result does not depend on how the events are chunked.
  const int64_t slice = secToNs(volume_->options().pose_slice_s);
  int64_t pose_t = std::numeric_limits<int64_t>::min();
  RayPose<double> pose;
  for (size_t k = begin; k < end; ++k) {
    const PixelEvent& e = events[k];
    if (!model.covers(e.t_ns)) {
      ++out->skipped_time;
      continue;
    }
    int64_t t = poseSliceTime(e.t_ns, slice);
    if (!model.covers(t)) t = e.t_ns;  // the model ends inside this slice
    if (t != pose_t) {
      const Pose3 T =
          planar ? model.T_Cr_CtPlanar(t, &lj) : model.T_Cr_Ct(t, with_jacobian ? &pj : nullptr);
      pose = RayPose<double>(T.linear(), T.translation(),
                             per_camera_min_depth_ ? volume_->options().z_min_m : 0.0);
      pose_t = t;
    }
    const Vec3 f = camera_.bearing(e.x, e.y).cast<double>();
    const Vec3& o = pose.o;
    Vec3 d;
    VolumeRay ray;
    if (!make_ray(pose, f, &ray, &d)) {
      ++out->skipped_behind;
      continue;
    }
    out->rays.push_back(ray);
    if (!with_jacobian) continue;
    const double ax = d.x() / d.z(), ay = d.y() / d.z();
    if (planar) {
      // Three derivatives per ray (psi, x, y); the model chains them to its parameters.
      out->times.push_back(t);
      out->jac_value.push_back(rayDerivative(o, d, ax, ay, lj.dR_dpsi * f, lj.dt_dpsi, fx, fy));
      out->jac_value.push_back(rayDerivative(o, d, ax, ay, Vec3::Zero(), lj.dt_dx, fx, fy));
      out->jac_value.push_back(rayDerivative(o, d, ax, ay, Vec3::Zero(), lj.dt_dy, fx, fy));
      continue;
    }
    out->jac_count.push_back(int(pj.param_index.size()));
    for (size_t j = 0; j < pj.param_index.size(); ++j) {
      out->jac_param.push_back(pj.param_index[j]);
      out->jac_value.push_back(rayDerivative(o, d, ax, ay, pj.dR[j] * f, pj.dt[j], fx, fy));
    }
  }
}

VweEvaluation VweObjective::buildRays(const EventVector& events, const TrajectoryModel& model,
                                      bool with_jacobian) {
  // Chunk boundaries from the event count only (results independent of the threads).
  constexpr size_t kEventsPerChunk = 1024, kMaxChunks = 16;
  const size_t N = events.size();
  const size_t num_chunks = std::max<size_t>(1, std::min(kMaxChunks, N / kEventsPerChunk));
  if (chunks_.size() < num_chunks) chunks_.resize(num_chunks);
  pool_.run(int(num_chunks), [&](int c, int) {
    buildChunk(events, N * size_t(c) / num_chunks, N * size_t(c + 1) / num_chunks, model,
               with_jacobian, &chunks_[size_t(c)]);
  });
  VweEvaluation ev;
  rays_.clear();
  jac_begin_.clear();
  jac_param_.clear();
  jac_value_.clear();
  ray_times_.clear();
  for (size_t c = 0; c < num_chunks; ++c) {
    const Chunk& ch = chunks_[c];
    ev.skipped_time += ch.skipped_time;
    ev.skipped_behind += ch.skipped_behind;
    rays_.insert(rays_.end(), ch.rays.begin(), ch.rays.end());
    ray_times_.insert(ray_times_.end(), ch.times.begin(), ch.times.end());
    if (with_jacobian) {
      int offset = int(jac_param_.size());
      for (int n : ch.jac_count) {
        jac_begin_.push_back(offset);
        offset += n;
      }
      jac_param_.insert(jac_param_.end(), ch.jac_param.begin(), ch.jac_param.end());
      jac_value_.insert(jac_value_.end(), ch.jac_value.begin(), ch.jac_value.end());
    }
  }
  if (with_jacobian) jac_begin_.push_back(int(jac_param_.size()));
  ev.rays = rays_.size();
  return ev;
}

VweEvaluation VweObjective::voteOnly(const EventVector& events, const TrajectoryModel& model) {
  VweEvaluation ev = buildRays(events, model, false);
  ev.votes = volume_->vote(rays_);
  ev.contrast = volume_->contrast();
  return ev;
}

VweEvaluation VweObjective::evaluate(const EventVector& events, const TrajectoryModel& model,
                                     Eigen::VectorXd* gradient) {
  VweEvaluation ev = buildRays(events, model, gradient != nullptr);
  ev.contrast = volume_->contrastOfRays(rays_, &ev.votes, gradient ? &sensitivities_ : nullptr);
  if (gradient) {
    gradient->setZero(model.numParams());
    if (model.hasPlanarJacobian()) {
      planar_g_.resize(rays_.size());
      for (size_t i = 0; i < rays_.size(); ++i) {
        const Eigen::Vector4d& s = sensitivities_[i];
        const Eigen::Vector4d* J = &jac_value_[3 * i];
        planar_g_[i] = Vec3(s.dot(J[0]), s.dot(J[1]), s.dot(J[2]));
      }
      model.addPlanarGradient(ray_times_, planar_g_, gradient);
      return ev;
    }
    for (size_t i = 0; i < rays_.size(); ++i) {
      const Eigen::Vector4d& s = sensitivities_[i];
      for (int j = jac_begin_[i]; j < jac_begin_[i + 1]; ++j)
        (*gradient)[jac_param_[j]] += s.dot(jac_value_[j]);
    }
  }
  return ev;
}

VweObjectivePool::VweObjectivePool(const CameraModel& camera, const VolumeOptions& options)
    : pool_(validated(options).num_threads) {
  VolumeOptions single = options;
  single.num_threads = 1;
  const CameraCalibration& c = camera.calibration();
  for (int t = 0; t < pool_.numThreads(); ++t) {
    volumes_.push_back(
        std::make_unique<ProjectiveVolume>(single, c.width, c.height, c.fx, c.fy, c.cx, c.cy));
    objectives_.push_back(std::make_unique<VweObjective>(camera, volumes_.back().get()));
  }
  if (pool_.numThreads() > 1) {
    wide_volume_ =
        std::make_unique<ProjectiveVolume>(options, c.width, c.height, c.fx, c.fy, c.cx, c.cy);
    wide_objective_ = std::make_unique<VweObjective>(camera, wide_volume_.get());
  }
}

void VweObjectivePool::setPerCameraMinDepth(bool on) {
  for (auto& o : objectives_) o->setPerCameraMinDepth(on);
  if (wide_objective_) wide_objective_->setPerCameraMinDepth(on);
}

void VweObjectivePool::run(int n, const std::function<void(int, VweObjective&)>& fn) {
  // Whole rounds of one volume per thread; the rest (3 volumes on 2 threads: the third) one
  // after another on all threads, instead of leaving threads idle for a round.
  if (n <= 0) return;
  const int T = pool_.numThreads();
  const int spread = wide_objective_ ? n - n % T : n;
  pool_.run(spread, [&](int i, int t) { fn(i, *objectives_[size_t(t)]); });
  for (int i = spread; i < n; ++i) fn(i, *wide_objective_);
}

}  // namespace vwe_vo
