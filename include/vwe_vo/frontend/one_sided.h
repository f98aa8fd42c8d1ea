// Structure on one side of the street only. Under fast forward motion a yaw error is partly
// absorbed by refocusing that side's rays in nearer planes, which biases the VWE's peak.
// A volume whose events above the horizon are one-sided is therefore voted into deeper planes,
// but only if that side's structure is deep enough for them: a facade nearer than the planes
// cannot focus at the true yaw rate either. Used by the front-end's windows only: the
// back-end's 1 s volumes are rarely one-sided (docs/method.md).
#pragma once

#include <string>
#include <vector>

#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sensor/events.h"
#include "vwe_vo/trajectory/trajectory_model.h"
#include "vwe_vo/vwe/projective_volume.h"
#include "vwe_vo/vwe/vwe_objective.h"

namespace vwe_vo {

struct OneSidedOptions {
  double balance = 0.0;   // events above the horizon this unbalanced (fewer / more) are one-sided;
                          // 0: off [1], in [0, 1)
  double z_min_m = 10.0;  // nearest plane of the deeper planes [m], in (normal z_min, z_max)
  double min_depth_m = 11.0;  // that side's structure must measure this deep for them [m], > 0
  /// Throws std::invalid_argument naming the field by its key, section + ".one_sided_" + field;
  /// `normal` is the normal planes.
  void validate(const VolumeOptions& normal, const std::string& section) const;
};

/// Raw (distorted) sensor pixel, as the events', where the direction straight ahead of
/// base_link (its x axis) appears: the focus of expansion of straight driving, on the horizon.
/// False if the camera does not look forward.
bool forwardPixel(const CameraModel& camera, const Pose3& T_base_cam, Vec2* pixel);
/// Events above the horizon row (y < pixel.y) on the side of pixel.x with fewer of them, divided
/// by those on the other side: 1 balanced, 0 all on one side; 1 if none is above the horizon.
double sideBalance(const EventVector& events, const Vec2& pixel);
/// Median, over the rays whose direction (u0, v0) lies above pixel.y() on the side of pixel.x()
/// with more of them, of volume.peakDepth() (the volume holding the rays' votes); 0 if none.
double oneSidedDepth(const ProjectiveVolume& volume, const std::vector<VolumeRay>& rays,
                     const Vec2& pixel);

/// The decision for one volume of events.
class OneSidedRule {
 public:
  OneSidedRule(const OneSidedOptions& options, const CameraModel& camera, const Pose3& T_base_cam);
  /// balance > 0 and the camera looks forward.
  bool enabled() const { return enabled_; }
  /// The deeper planes: `normal` from options.z_min_m.
  VolumeOptions deeperPlanes(const VolumeOptions& normal) const;
  /// Whether `events` are one-sided (sideBalance below options.balance; false if not enabled).
  bool oneSided(const EventVector& events) const;
  /// Whether that side's structure measures at least min_depth_m: the median depth where its
  /// rays meet when `normal` (an objective on the normal planes) votes `events` warped by
  /// `model`, a prediction of the motion. The VWE measures depth short, so min_depth_m is
  /// below the depth of the facades the deeper planes suit. Leaves the volume clear.
  bool deepEnough(VweObjective& normal, const EventVector& events,
                  const TrajectoryModel& model) const;

 private:
  OneSidedOptions options_;
  Pose3 T_base_cam_;
  Vec2 forward_pixel_ = Vec2::Zero();  // sensor pixels
  bool enabled_ = false;
};

}  // namespace vwe_vo
