// Events of random 3D points seen by a camera moving along a known TrajectoryModel: an
// independent, exact source of events for tests and benchmarks of the VWE (header-only, not core).
#pragma once

#include <algorithm>
#include <random>

#include "vwe_vo/core/camera.h"
#include "vwe_vo/core/events.h"
#include "vwe_vo/core/trajectory_model.h"

namespace vwe_vo {
namespace synthetic {

/// n events of `num_points` random points (depth 1-8 m, inside the field of view of the
/// reference camera) at uniform times in [t_ref - half_span, t_ref + half_span], sorted.
inline EventVector randomPointEvents(const CameraModel& cam, const TrajectoryModel& truth, int n,
                                     unsigned seed, double half_span_s = 0.15, int num_points = 400) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(-1, 1), uz(0, 1), ut(-half_span_s, half_span_s);
  std::vector<Vec3> points;
  for (int i = 0; i < num_points; ++i) {
    const double z = 1.0 + 7.0 * uz(rng);
    points.emplace_back(ux(rng) * 0.6 * z, ux(rng) * 0.45 * z, z);
  }
  EventVector events;
  int attempts = 0;
  while (int(events.size()) < n && ++attempts < 100 * n) {
    const int64_t t = truth.referenceTime() + secToNs(ut(rng));
    const Vec3 p_Ct = truth.T_Cr_Ct(t, nullptr).inverse() * points[rng() % points.size()];
    Vec2 uv;
    if (!cam.project(p_Ct, &uv)) continue;
    const int x = int(std::lround(uv.x())), y = int(std::lround(uv.y()));
    if (!cam.inside(x, y)) continue;
    PixelEvent e;
    e.t_ns = t;
    e.x = uint16_t(x);
    e.y = uint16_t(y);
    e.polarity = (rng() & 1) ? 1 : -1;
    events.push_back(e);
  }
  std::sort(events.begin(), events.end(), [](const PixelEvent& a, const PixelEvent& b) { return a.t_ns < b.t_ns; });
  return events;
}

}  // namespace synthetic
}  // namespace vwe_vo
