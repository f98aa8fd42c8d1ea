#include "vwe_vo/core/vwe_objective.h"

#include <cmath>

namespace vwe_vo {

EventVector subsampleEvents(const EventVector& events, size_t max_events, uint64_t seed) {
  if (max_events == 0 || events.size() <= max_events) return events;
  EventVector out;
  out.reserve(max_events);
  const double stride = double(events.size()) / double(max_events);
  // Phase in [0, stride) from a splitmix64 hash of the seed: deterministic, seed-dependent.
  uint64_t z = seed + 0x9e3779b97f4a7c15ULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  z ^= z >> 31;
  const double phase = double(z >> 11) / double(1ULL << 53) * stride;
  for (size_t k = 0; k < max_events; ++k) {
    const size_t i = std::min(events.size() - 1, size_t(phase + double(k) * stride));
    out.push_back(events[i]);
  }
  return out;
}

EventVector subsampleEventsPerTimeSlice(const EventVector& events, int64_t t0_ns, int64_t t1_ns, size_t max_events,
                                        int bins, uint64_t seed) {
  if (bins <= 1 || t1_ns <= t0_ns) return subsampleEvents(events, max_events, seed);
  EventVector out;
  out.reserve(max_events);
  const size_t per_bin = std::max<size_t>(1, max_events / size_t(bins));
  size_t begin = 0;
  for (int b = 0; b < bins; ++b) {
    const int64_t edge = t0_ns + (t1_ns - t0_ns) * (b + 1) / bins;
    size_t end = begin;
    while (end < events.size() && (events[end].t_ns < edge || b == bins - 1)) ++end;
    const EventVector slice(events.begin() + begin, events.begin() + end);
    const EventVector kept = subsampleEvents(slice, per_bin, seed + uint64_t(b));
    out.insert(out.end(), kept.begin(), kept.end());
    begin = end;
  }
  return out;
}

VweObjective::VweObjective(const CameraModel& camera, ProjectiveVolume* volume) : camera_(camera), volume_(volume) {}

VweEvaluation VweObjective::buildRays(const EventVector& events, const TrajectoryModel& model, bool with_jacobian) {
  VweEvaluation ev;
  rays_.clear();
  jac_begin_.clear();
  jac_param_.clear();
  jac_value_.clear();
  rays_.reserve(events.size());
  const double fx = volume_->fx(), fy = volume_->fy(), cx = volume_->cx(), cy = volume_->cy();
  for (const PixelEvent& e : events) {
    if (!model.covers(e.t_ns)) {
      ++ev.skipped_time;
      continue;
    }
    const Pose3 T = model.T_Cr_Ct(e.t_ns, with_jacobian ? &pose_jac_ : nullptr);
    const Vec3 f = camera_.bearing(e.x, e.y).cast<double>();
    const Vec3 o = T.translation();
    const Vec3 d = T.linear() * f;
    VolumeRay ray;
    if (!makeVolumeRay(o, d, fx, fy, cx, cy, &ray)) {
      ++ev.skipped_behind;
      continue;
    }
    rays_.push_back(ray);
    if (with_jacobian) {
      jac_begin_.push_back(int(jac_param_.size()));
      const double ax = d.x() / d.z(), ay = d.y() / d.z();
      for (size_t j = 0; j < pose_jac_.param_index.size(); ++j) {
        const Vec3 dd = pose_jac_.dR[j] * f;
        const Vec3& dto = pose_jac_.dt[j];
        const double dax = (dd.x() - ax * dd.z()) / d.z();
        const double day = (dd.y() - ay * dd.z()) / d.z();
        const double dbx = dto.x() - dto.z() * ax - o.z() * dax;
        const double dby = dto.y() - dto.z() * ay - o.z() * day;
        jac_param_.push_back(pose_jac_.param_index[j]);
        jac_value_.emplace_back(fx * dax, fx * dbx, fy * day, fy * dby);
      }
    }
  }
  if (with_jacobian) jac_begin_.push_back(int(jac_param_.size()));
  ev.rays = rays_.size();
  return ev;
}

VweEvaluation VweObjective::voteOnly(const EventVector& events, const TrajectoryModel& model) {
  VweEvaluation ev = buildRays(events, model, false);
  ev.votes = volume_->vote(rays_);
  ev.variance = volume_->variance();
  return ev;
}

VweEvaluation VweObjective::evaluate(const EventVector& events, const TrajectoryModel& model,
                                     Eigen::VectorXd* gradient) {
  VweEvaluation ev = buildRays(events, model, gradient != nullptr);
  ev.votes = volume_->vote(rays_);
  ev.variance = volume_->variance();
  if (gradient) {
    gradient->setZero(model.numParams());
    volume_->varianceRaySensitivities(rays_, &sensitivities_);
    const double scale = 2.0 / double(volume_->numVoxels());
    for (size_t i = 0; i < rays_.size(); ++i) {
      const Eigen::Vector4d& s = sensitivities_[i];
      for (int j = jac_begin_[i]; j < jac_begin_[i + 1]; ++j) (*gradient)[jac_param_[j]] += scale * s.dot(jac_value_[j]);
    }
  }
  volume_->clear(rays_);
  return ev;
}

}  // namespace vwe_vo
