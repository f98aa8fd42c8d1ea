#include "vwe_vo/vwe/ground_objective.h"

#include <limits>
#include <stdexcept>

#include "vwe_vo/sensor/ground_mask.h"
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
  ground_.assign(size_t(width_) * height_, 0);
  for (int y = 0; y < height_; ++y)
    for (int x = 0; x < width_; ++x) {
      const double depth = groundDepthAlongAxis(camera.bearing(x, y).cast<double>(), T_base_cam);
      if (!(depth >= options_.min_depth_m && depth <= options_.max_depth_m)) continue;
      ground_[size_t(y) * width_ + x] = 1;
      ++ground_pixels_;
    }
  grid_.assign(size_t(grid_w_) * grid_h_, 0.0f);
}

void GroundObjective::groundEvents(const EventVector& events, EventVector* out) const {
  out->clear();
  for (const PixelEvent& e : events)
    if (seesGround(e.x, e.y)) out->push_back(e);
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
  if (votes_.size() < events.size()) votes_.resize(events.size());
  Vote* const votes = votes_.data();  // written in place: no push_back in the loop
  size_t num_votes = 0;
  const size_t W = size_t(grid_w_);
  const float umax = float(grid_w_ - 1), vmax = float(grid_h_ - 1);
  // The pairs of votes that meet: adding w to a pixel holding V adds 2 w V, so over a pixel's
  // votes they sum to V^2 - sum w^2, the squares summed as the image is cleared. Projecting,
  // voting and clearing are three passes: none reads what another just wrote.
  const Mat3 K = (Mat3() << fx_, 0, cx_, 0, fy_, cy_, 0, 0, 1).finished();
  double own = 0.0;
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
    const Eigen::Matrix3f KH = (K * H).cast<float>();
    const Eigen::Vector3f nf = n_t.cast<float>();
    float slice_own = 0.0f;
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
      // The four weights' squares: ((1 - ax)^2 + ax^2) ((1 - ay)^2 + ay^2).
      slice_own += ((1 - ax) * (1 - ax) + ax * ax) * ((1 - ay) * (1 - ay) + ay * ay);
      Vote& b = votes[num_votes++];
      b.idx = uint32_t(size_t(iy) * W + size_t(ix)), b.ax = ax, b.ay = ay;
    }
    own += double(slice_own);
  }
  for (const Vote* b = votes; b != votes + num_votes; ++b) {
    float* c0 = grid_.data() + b->idx;
    float* c1 = c0 + W;
    c0[0] += (1 - b->ax) * (1 - b->ay), c0[1] += b->ax * (1 - b->ay);
    c1[0] += (1 - b->ax) * b->ay, c1[1] += b->ax * b->ay;
  }
  // Each pixel's V^2 once: a pixel touched again reads the zero it was left.
  double squares = 0.0;
  for (const Vote* b = votes; b != votes + num_votes; ++b) {
    float* c0 = grid_.data() + b->idx;
    float* c1 = c0 + W;
    const Eigen::Vector4d c(c0[0], c0[1], c1[0], c1[1]);
    squares += c.squaredNorm();
    c0[0] = c0[1] = c1[0] = c1[1] = 0.0f;
  }
  return num_votes > 0 ? (squares - own) / double(num_votes) : 0.0;
}

}  // namespace vwe_vo
