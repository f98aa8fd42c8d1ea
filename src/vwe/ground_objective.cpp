#include "vwe_vo/vwe/ground_objective.h"

#include <limits>
#include <stdexcept>

#include "vwe_vo/vwe/ray_builder.h"

namespace vwe_vo {

void GroundObjectiveOptions::validate(const std::string& section) const {
  auto fail = [&](const std::string& m) { throw std::invalid_argument(section + "." + m); };
  if (!(min_depth_m > 0)) fail("min_depth_m must be positive");
  if (!(max_depth_m > min_depth_m)) fail("max_depth_m must be larger than min_depth_m");
  if (!(grid_scale > 0.05 && grid_scale <= 2.0)) fail("grid_scale must be in (0.05, 2]");
  if (margin_px < 0 || margin_px > 200) fail("margin_px must be in [0, 200]");
  if (!(pose_slice_s >= 0 && pose_slice_s <= 0.01)) fail("pose_slice_s must be in [0, 0.01]");
}

GroundObjective::GroundObjective(const GroundObjectiveOptions& options, const CameraModel& camera,
                                 const Pose3& T_base_cam)
    : options_(options), camera_(camera), width_(camera.width()), height_(camera.height()) {
  options_.validate("ground");
  const CameraCalibration& c = camera.calibration();
  const double s = options_.grid_scale;
  const int m = options_.margin_px;
  grid_w_ = int(std::ceil(width_ * s)) + 2 * m;
  grid_h_ = int(std::ceil(height_ * s)) + 2 * m;
  fx_ = float(c.fx * s), fy_ = float(c.fy * s);
  cx_ = float((c.cx + 0.5) * s - 0.5 + m);
  cy_ = float((c.cy + 0.5) * s - 0.5 + m);
  // The plane z = 0 of base_link in the camera frame: n . X + h = 0.
  const Vec3 n = T_base_cam.linear().transpose() * Vec3::UnitZ();
  const double h = T_base_cam.translation().z();
  ground_.assign(size_t(width_) * height_, 0);
  if (h > 0)
    for (int y = 0; y < height_; ++y)
      for (int x = 0; x < width_; ++x) {
        const Vec3 f = camera.bearing(x, y).cast<double>();
        const double nf = n.dot(f);
        if (!(nf < -1e-9)) continue;  // at or above the horizon
        const double depth = -h / nf * f.z();
        if (depth < options_.min_depth_m || depth > options_.max_depth_m) continue;
        ground_[size_t(y) * width_ + x] = 1;
        ++ground_pixels_;
      }
  grid_.assign(size_t(grid_w_) * grid_h_, 0.0f);
}

EventVector GroundObjective::groundEvents(const EventVector& events) const {
  EventVector out;
  out.reserve(events.size() / 2);
  for (const PixelEvent& e : events)
    if (seesGround(e.x, e.y)) out.push_back(e);
  return out;
}

GroundEvents GroundObjective::prepare(const EventVector& events,
                                      const TrajectoryModel& covers) const {
  const int64_t slice = secToNs(options_.pose_slice_s);
  GroundEvents out;
  out.bearings.reserve(events.size());
  for (const PixelEvent& e : events) {
    if (!seesGround(e.x, e.y) || !covers.covers(e.t_ns)) continue;
    int64_t t = poseSliceTime(e.t_ns, slice);
    if (!covers.covers(t)) t = e.t_ns;  // the model ends inside this slice
    if (out.slice_times.empty() || t != out.slice_times.back()) {
      out.slice_times.push_back(t);
      out.slice_begin.push_back(uint32_t(out.bearings.size()));
    }
    out.bearings.push_back(camera_.bearing(e.x, e.y));
  }
  out.slice_begin.push_back(uint32_t(out.bearings.size()));
  return out;
}

double GroundObjective::evaluate(const EventVector& events, const TrajectoryModel& model,
                                 const GroundPlane& plane) {
  return evaluate(prepare(events, model), model, plane);
}

double GroundObjective::evaluate(const GroundEvents& events, const TrajectoryModel& model,
                                 const GroundPlane& plane) {
  touched_.clear();
  const size_t W = size_t(grid_w_);
  const float umax = float(grid_w_ - 1), vmax = float(grid_h_ - 1);
  double pairs = 0.0;
  size_t votes = 0;
  for (size_t s = 0; s + 1 < events.slice_begin.size(); ++s) {
    // The camera at the slice's time, (R, o) in the reference frame. The plane there is
    // n_t . X + h_t = 0 with n_t = R^T n, h_t = n . o + h; its point on the bearing f is
    // X = lambda f, lambda = -h_t / (n_t . f) > 0, seen from the reference at
    // R X + o = lambda (R - o n_t^T / h_t) f = lambda H f: a homography (K folded in).
    const Pose3 T = model.T_Cr_Ct(events.slice_times[s]);
    const Mat3 R = T.linear();
    const Vec3 o = T.translation();
    const Vec3 n_t = R.transpose() * plane.n;
    const double h_t = plane.n.dot(o) + plane.h;
    if (!(h_t > 1e-6)) continue;  // the camera at or below the road
    Mat3 H = R - o * n_t.transpose() / h_t;
    const Mat3 K = (Mat3() << fx_, 0, cx_, 0, fy_, cy_, 0, 0, 1).finished();
    const Eigen::Matrix3f KH = (K * H).cast<float>();
    const Eigen::Vector3f nf = n_t.cast<float>();
    for (uint32_t k = events.slice_begin[s]; k < events.slice_begin[s + 1]; ++k) {
      const Eigen::Vector3f& f = events.bearings[k];
      if (!(nf.dot(f) < -1e-6f)) continue;  // the bearing misses the road
      const Eigen::Vector3f p = KH * f;
      if (!(p.z() > 1e-6f)) continue;  // behind the reference camera
      const float inv = 1.0f / p.z();
      const float u = p.x() * inv, v = p.y() * inv;
      if (!(u >= 0.0f && v >= 0.0f && u < umax && v < vmax)) continue;
      const int ix = int(u), iy = int(v);
      const float ax = u - float(ix), ay = v - float(iy);
      const size_t idx = size_t(iy) * W + size_t(ix);
      float* c0 = grid_.data() + idx;
      float* c1 = c0 + W;
      const float w00 = (1 - ax) * (1 - ay), w10 = ax * (1 - ay), w01 = (1 - ax) * ay,
                  w11 = ax * ay;
      // Adding w to a pixel holding V adds 2 w V to the pairs of votes (ProjectiveVolume).
      pairs += double(2 * (w00 * c0[0] + w10 * c0[1] + w01 * c1[0] + w11 * c1[1]));
      c0[0] += w00, c0[1] += w10, c1[0] += w01, c1[1] += w11;
      touched_.push_back(uint32_t(idx));
      ++votes;
    }
  }
  for (uint32_t idx : touched_) {
    float* c0 = grid_.data() + idx;
    c0[0] = c0[1] = c0[W] = c0[W + 1] = 0.0f;
  }
  return votes > 0 ? pairs / double(votes) : 0.0;
}

}  // namespace vwe_vo
