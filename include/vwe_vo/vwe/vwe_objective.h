// The Volume of Warped Events objective (paper eq. 2-5): the events of a window become rays
// o_k + lambda d_k through the reference camera, with o_k = t_Cr_Ct(t_k), d_k = R_Cr_Ct(t_k) f(x_k)
// from any TrajectoryModel; the contrast of their ray density in a ProjectiveVolume (the variance
// of the paper, or the density per vote: VolumeOptions::contrast) and its analytic gradient
// w.r.t. the model parameters drive the optimisers.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "vwe_vo/common/thread_pool.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sensor/events.h"
#include "vwe_vo/trajectory/trajectory_model.h"
#include "vwe_vo/vwe/projective_volume.h"

namespace vwe_vo {

struct VweEvaluation {
  double contrast = 0.0;      // VolumeOptions::contrast of the volume the rays vote
  size_t rays = 0;            // events turned into rays
  size_t skipped_time = 0;    // events the model does not cover (not extrapolated)
  size_t skipped_behind = 0;  // rays pointing away from the reference camera
  size_t votes = 0;           // plane votes cast
};

/// Rays (and their Jacobians) are built in parallel on the volume's num_threads threads, in
/// chunks whose boundaries depend only on the number of events: the result does not depend on
/// the thread count. The model's T_Cr_Ct must therefore be safe to call concurrently (const).
class VweObjective {
 public:
  /// The volume is shared (one grid, reused for every evaluation); both must outlive this.
  VweObjective(const CameraModel& camera, ProjectiveVolume* volume);

  /// Contrast of the VWE of `events` warped by `model`. If gradient is not null it is resized to
  /// model.numParams() and set to dContrast/dtheta. Leaves the volume clear.
  VweEvaluation evaluate(const EventVector& events, const TrajectoryModel& model,
                         Eigen::VectorXd* gradient = nullptr);

  /// As evaluate(), but leaves the votes in the volume (for images / depth extraction);
  /// call volume->clear(lastRays()) afterwards.
  VweEvaluation voteOnly(const EventVector& events, const TrajectoryModel& model);
  const std::vector<VolumeRay>& lastRays() const { return rays_; }
  ProjectiveVolume& volume() const { return *volume_; }
  /// Rays vote only from the volume's z_min_m in front of their own camera (along the reference
  /// view's axis), not only of the reference view (RayPose's min_depth; off by default).
  void setPerCameraMinDepth(bool on) { per_camera_min_depth_ = on; }

 private:
  VweEvaluation buildRays(const EventVector& events, const TrajectoryModel& model,
                          bool with_jacobian);

  // What one chunk of events produced (kept between calls: no allocation once warmed up).
  struct Chunk {
    std::vector<VolumeRay> rays;
    std::vector<int> jac_count;
    std::vector<int> jac_param;
    std::vector<Eigen::Vector4d> jac_value;
    std::vector<int64_t> times;  // of the rays (planar Jacobian only)
    size_t skipped_time = 0, skipped_behind = 0;
    PoseJacobian pose_jac;
  };
  void buildChunk(const EventVector& events, size_t begin, size_t end, const TrajectoryModel& model,
                  bool with_jacobian, Chunk* out) const;

  const CameraModel& camera_;
  ProjectiveVolume* volume_;
  bool per_camera_min_depth_ = false;
  ThreadPool pool_;
  std::vector<Chunk> chunks_;
  std::vector<VolumeRay> rays_;
  // Per ray: derivatives of [u0, du, v0, dv] w.r.t. the parameters that move it; for a model
  // with a planar Jacobian, w.r.t. (psi, x, y) (three per ray), with the rays' times.
  std::vector<int> jac_begin_;
  std::vector<int> jac_param_;
  std::vector<Eigen::Vector4d> jac_value_;
  std::vector<int64_t> ray_times_;
  std::vector<Vec3> planar_g_;
  std::vector<Eigen::Vector4d> sensitivities_;
};

/// One VweObjective per thread, each with its own single-threaded volume (options.num_threads
/// of them): many volumes are evaluated at once, one per thread, with no synchronisation inside a
/// volume (the back-end's multi-volume objective). Volumes left over from whole rounds go to one
/// more objective whose volume uses all threads. Results do not depend on which objective runs
/// a volume (the VWE's sums do not depend on its thread count).
class VweObjectivePool {
 public:
  VweObjectivePool(const CameraModel& camera, const VolumeOptions& options);
  int numThreads() const { return pool_.numThreads(); }
  /// The geometry every evaluator's volume shares.
  const ProjectiveVolume& volume() const { return *volumes_.front(); }
  /// Runs fn(i, objective) for i in [0, n) and returns when all are done: n - n % numThreads()
  /// calls at once, each with the objective of the thread running it, then the rest one by one
  /// with the all-threads objective.
  void run(int n, const std::function<void(int i, VweObjective& objective)>& fn);
  /// VweObjective::setPerCameraMinDepth of every evaluator.
  void setPerCameraMinDepth(bool on);

 private:
  ThreadPool pool_;
  std::vector<std::unique_ptr<ProjectiveVolume>> volumes_;
  std::vector<std::unique_ptr<VweObjective>> objectives_;
  std::unique_ptr<ProjectiveVolume> wide_volume_;  // options.num_threads threads (null for 1)
  std::unique_ptr<VweObjective> wide_objective_;
};

}  // namespace vwe_vo
