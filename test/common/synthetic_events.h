// Events of known 3D points seen by a camera moving along a known TrajectoryModel: an
// independent, exact source of events for tests and benchmarks of the VWE and the EMVS mapper
// (header-only, not core).
#pragma once

#include <algorithm>
#include <random>
#include <vector>

#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sensor/events.h"
#include "vwe_vo/trajectory/trajectory_model.h"

namespace vwe_vo {
namespace synthetic {

/// n events of the given points (reference camera frame) at uniform times in
/// [t_ref - half_span, t_ref + half_span], sorted: each event is a random point projected at a
/// random time and rounded to the nearest pixel. If point_index is not null it receives, per
/// event, the index of the point that made it.
inline EventVector pointEvents(const CameraModel& cam, const TrajectoryModel& truth,
                               const std::vector<Vec3>& points, int n, std::mt19937* rng,
                               double half_span_s, std::vector<int>* point_index = nullptr) {
  std::uniform_real_distribution<double> ut(-half_span_s, half_span_s);
  std::vector<std::pair<PixelEvent, int>> made;
  int attempts = 0;
  while (int(made.size()) < n && ++attempts < 100 * n) {
    const int64_t t = truth.referenceTime() + secToNs(ut(*rng));
    const int k = int((*rng)() % points.size());
    const Vec3 p_Ct = truth.T_Cr_Ct(t, nullptr).inverse() * points[k];
    Vec2 uv;
    if (!cam.project(p_Ct, &uv)) continue;
    const int x = int(std::lround(uv.x())), y = int(std::lround(uv.y()));
    if (!cam.inside(x, y)) continue;
    PixelEvent e;
    e.t_ns = t;
    e.x = uint16_t(x);
    e.y = uint16_t(y);
    e.polarity = ((*rng)() & 1) ? 1 : -1;
    made.emplace_back(e, k);
  }
  std::stable_sort(made.begin(), made.end(),
                   [](const auto& a, const auto& b) { return a.first.t_ns < b.first.t_ns; });
  EventVector events;
  events.reserve(made.size());
  if (point_index) point_index->clear();
  for (const auto& m : made) {
    events.push_back(m.first);
    if (point_index) point_index->push_back(m.second);
  }
  return events;
}

/// num_points random points (depth 1-8 m, inside the field of view of the reference camera).
inline std::vector<Vec3> randomPoints(std::mt19937* rng, int num_points) {
  std::uniform_real_distribution<double> ux(-1, 1), uz(0, 1);
  std::vector<Vec3> points;
  for (int i = 0; i < num_points; ++i) {
    const double z = 1.0 + 7.0 * uz(*rng);
    points.emplace_back(ux(*rng) * 0.6 * z, ux(*rng) * 0.45 * z, z);
  }
  return points;
}

/// n events of `num_points` random points (depth 1-8 m, inside the field of view of the
/// reference camera) at uniform times in [t_ref - half_span, t_ref + half_span], sorted.
/// If points_out is not null it receives the points (reference camera frame).
inline EventVector randomPointEvents(const CameraModel& cam, const TrajectoryModel& truth, int n,
                                     unsigned seed, double half_span_s = 0.15, int num_points = 400,
                                     std::vector<Vec3>* points_out = nullptr,
                                     std::vector<int>* point_index = nullptr) {
  std::mt19937 rng(seed);
  const std::vector<Vec3> points = randomPoints(&rng, num_points);
  if (points_out) *points_out = points;
  return pointEvents(cam, truth, points, n, &rng, half_span_s, point_index);
}

/// num_points random points on the plane z = depth_m of the reference camera, spread over
/// x in [-half_width, half_width], y in [-half_height, half_height] [m] (a textured frontal wall).
inline std::vector<Vec3> frontalWallPoints(std::mt19937* rng, int num_points, double depth_m,
                                           double half_width_m, double half_height_m) {
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Vec3> points;
  for (int i = 0; i < num_points; ++i)
    points.emplace_back(u(*rng) * half_width_m, u(*rng) * half_height_m, depth_m);
  return points;
}

}  // namespace synthetic
}  // namespace vwe_vo
