// EMVS mapping (Rebecq et al., IJCV 2018) on a known trajectory: per keyframe, the events since
// the keyframe vote their rays into a disparity-space image (the ProjectiveVolume, the same
// voting kernel as the VWE); depth = argmax along each pixel's depth ray refined in inverse
// depth, kept where the confidence passes an adaptive Gaussian threshold; a median filter and a
// radius outlier removal clean the semi-dense map. GlobalMap fuses keyframe clouds into a
// bounded voxel-downsampled cloud (io/ply.h writes it).
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <unordered_map>
#include <vector>

#include "vwe_vo/common/math.h"
#include "vwe_vo/common/thread_pool.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sensor/events.h"
#include "vwe_vo/trajectory/trajectory_model.h"
#include "vwe_vo/vwe/projective_volume.h"

namespace vwe_vo {

struct EmvsOptions {
  EmvsOptions();
  VolumeOptions volume;  // the DSI (defaults: full resolution, 100 planes, 0.5-8 m) and
                         // its pose slices (volume.pose_slice_s, as the VWE)
  bool per_camera_min_depth =
      true;  // a ray votes only from volume.z_min_m in front of its own camera (along the
             // reference view's axis), not only of the reference view: driving forward, the
             // rays of the cameras ahead of the reference meet its nearest planes close to their
             // own centres and pile up around the focus of expansion there
  int adaptive_kernel_size = 5;    // adaptive threshold: Gaussian window [grid px], odd >= 3
  double adaptive_sigma_px = 0.0;  // its sigma [grid px]; 0: from the window as in OpenCV
  double adaptive_c =
      5.0;  // keep confidence > local Gaussian mean + C [1/255 of the max confidence]
  double min_confidence = 0.0;  // and confidence >= this [votes]
  double min_ray_contrast =
      0.0;  // and peak >= this x the mean along the pixel's depth ray; 0 = off
  int nms_radius_px =
      0;  // and the voxel is the maximum of its (2r+1)^2 pixels x nms_planes [grid px]; 0 = off
  int nms_planes = 0;  // ... over the planes within this many of its own; 0 = all planes
  double local_max_ratio =
      0.3;  // and confidence >= this fraction of the maximum in the window below; 0 = off
  int local_max_window_px = 15;  // ... window [grid px], odd
  int median_filter_size = 7;    // masked median of the depth map [grid px], odd; 1 = off
  bool subpixel = true;      // refine the argmax between planes (peak centroid in inverse depth)
  double max_depth_m = 8.0;  // drop points deeper than this [m]
  double outlier_radius_m = 0.2;   // radius outlier removal: neighbourhood radius [m] (the cloud is
                                   // sparse after NMS); 0 = off
  int outlier_min_neighbours = 3;  // ... points needed within the radius (not counting itself)
  double kf_distance_m = 0.3;      // close a keyframe after this much translation [m]
  double kf_rotation_deg = 15.0;   // ... or this much rotation [deg]
  size_t max_events_per_keyframe = 2000000;  // ... or this many events (bounds time and memory)
  size_t max_pending_events =
      8000000;  // events waiting for the trajectory; beyond, they are thinned to every second one
  double max_event_rate_hz = 500000.0;  // vote at most this many events per second (evenly over
                                        // time, the others counted as thinned); 0 = all
  bool rate_limit_whole_keyframes =
      true;  // keep max_event_rate_hz by leaving out whole keyframes (their events counted as
             // thinned) instead of thinning every keyframe's events: each DSI voted keeps all
             // its events, so its depth is as good as unlimited; the map has fewer keyframes
  /// Throws std::invalid_argument naming the field by its YAML key, section + "." + key.
  void validate(const std::string& section = "mapping") const;
};

/// One point of a cloud: position and confidence (the DSI maximum, in votes).
struct MapPoint {
  Eigen::Vector3f p;
  float confidence = 0.0f;
};

struct EmvsCounts {
  size_t events = 0;           // events handed to the keyframe
  size_t voted = 0;            // events whose ray was voted
  size_t skipped_time = 0;     // events the trajectory does not cover (not extrapolated)
  size_t skipped_nan = 0;      // events whose pose is not finite
  size_t skipped_behind = 0;   // rays not pointing in front of the keyframe camera
  size_t skipped_outside = 0;  // events outside the sensor
  size_t votes = 0;            // plane votes cast
  size_t selected = 0;         // pixels passing the thresholds (before outlier removal)
  size_t outliers = 0;         // points removed by the radius outlier removal
  size_t points = 0;           // points in the result
  /// Adds every count of `other` (totals over keyframes).
  EmvsCounts& operator+=(const EmvsCounts& other);
};

/// The depth of one DSI: maps at the grid resolution of the volume (float, 0 = none).
struct DepthExtraction {
  cv::Mat depth_m;      // depth z along the optical axis [m] of the selected pixels, 0 elsewhere
  cv::Mat confidence;   // DSI maximum per pixel [votes], every pixel
  cv::Mat mask;         // CV_8U, 1 where a depth was kept
  size_t selected = 0;  // pixels with a depth
};

/// Argmax, refinement, adaptive threshold and masked median of the DSI held by `volume`.
DepthExtraction extractDepth(const ProjectiveVolume& volume, const EmvsOptions& options);

struct EmvsKeyframe {
  int64_t t_kf_ns = 0;     // reference time of the DSI (pose T_odom_cam)
  int64_t t_begin_ns = 0;  // first event voted
  int64_t t_end_ns = 0;    // last event voted
  Pose3 T_odom_cam = Pose3::Identity();
  cv::Mat depth_m;  // see DepthExtraction
  cv::Mat confidence;
  std::vector<MapPoint> points_cam;   // in the keyframe camera frame
  std::vector<MapPoint> points_odom;  // the same points in odom
  EmvsCounts counts;
};

/// Keyframe cloud from a DSI: depth extraction, points through the volume's virtual pinhole,
/// max depth, radius outlier removal, transform to odom. Fills everything but times/event counts.
void extractKeyframe(const ProjectiveVolume& volume, const EmvsOptions& options,
                     const Pose3& T_odom_cam, EmvsKeyframe* keyframe);

/// Radius outlier removal with a voxel hash of cell = radius: keeps points with at least
/// min_neighbours others within radius_m. Cost O(points x neighbours). Returns how many it removed.
size_t removeRadiusOutliers(std::vector<MapPoint>* points, double radius_m, int min_neighbours);

/// The incremental mapper, the one EMVS entry point: events are buffered until the trajectory
/// covers them, then gathered (with the pose of their slice, poseSliceTime of
/// volume.pose_slice_s) into the current keyframe; a keyframe is closed when the
/// camera has moved kf_distance_m or turned kf_rotation_deg since its first event, or it holds
/// max_events_per_keyframe events. Closing builds the DSI with its reference view at the
/// keyframe's median event (half the events on each side: the rays spread symmetrically around
/// the true depth), votes it on the volume's threads and extracts depth map and cloud.
/// Not thread-safe: one worker calls it.
class EmvsMapper {
 public:
  /// T_odom_cam at t; false if the trajectory does not cover t.
  using PoseFunction = std::function<bool(int64_t t_ns, Pose3* T_odom_cam)>;

  EmvsMapper(const EmvsOptions& options, const CameraModel& camera);

  /// Buffers events (time-ordered; events older than the newest held are dropped and counted).
  void addEvents(const EventVector& events);
  /// Gathers every buffered event with t <= t_final_ns (the time up to which the trajectory is
  /// final; the pose of a slice is asked at its middle, up to half a slice later): events it
  /// does not cover are skipped and counted, later events stay buffered.
  /// Returns the keyframes closed meanwhile.
  std::vector<EmvsKeyframe> process(const PoseFunction& T_odom_cam, int64_t t_final_ns);
  /// Closes the current keyframe (end of data); false if there is none (or the rate limit of
  /// rate_limit_whole_keyframes left it out).
  bool finish(EmvsKeyframe* keyframe);
  /// Forgets the buffer and the current keyframe (e.g. a looped bag); totals are kept.
  void reset();

  bool hasKeyframe() const { return active_; }
  size_t pendingEvents() const { return pending_.size(); }
  size_t droppedOutOfOrder() const { return dropped_out_of_order_; }
  /// Events thinned out of the buffer that waits for the trajectory (max_pending_events).
  size_t thinnedPending() const { return thinned_pending_; }
  /// Events left out to stay within max_event_rate_hz (also those of keyframes left out).
  size_t thinned() const { return thinned_; }
  /// Keyframes left out whole to stay within max_event_rate_hz (rate_limit_whole_keyframes).
  size_t keyframesSkipped() const { return keyframes_skipped_; }
  size_t numKeyframes() const { return num_keyframes_; }
  const ProjectiveVolume& volume() const { return *volume_; }

 private:
  /// An event of the current keyframe: pixel and the pose slice it uses.
  struct KeyframeEvent {
    uint16_t x, y;
    uint32_t slice;
  };
  struct PoseSlice {
    int64_t t_ns;
    Pose3 T_odom_cam;
  };
  /// Votes the keyframe's DSI and extracts its cloud; false (nothing voted, the events counted
  /// as thinned) when rate_limit_whole_keyframes leaves it out.
  bool closeKeyframe(EmvsKeyframe* keyframe);
  void startKeyframe(int64_t t_ns, const Pose3& T_odom_cam);
  /// Forgets the keyframe being gathered (after it was voted, or left out).
  void dropKeyframe();
  void addToKeyframe(const PixelEvent& e, int64_t t_pose_ns, const Pose3& T_odom_cam);

  EmvsOptions options_;
  const CameraModel& camera_;
  std::unique_ptr<ProjectiveVolume> volume_;
  ThreadPool pool_;  // ray building
  std::deque<PixelEvent> pending_;
  size_t dropped_out_of_order_ = 0, thinned_pending_ = 0, num_keyframes_ = 0, thinned_ = 0;
  size_t keyframes_skipped_ = 0;
  // Token bucket of max_event_rate_hz: events earn a vote as time passes (at most 10 ms worth;
  // with rate_limit_whole_keyframes at most 1 s worth, spent a keyframe at a time).
  double tokens_ = 0.0;
  int64_t t_tokens_ns_ = INT64_MIN;
  // The keyframe being gathered.
  bool active_ = false;
  int64_t t_kf_ns_ = 0, t_last_ns_ = 0;
  Pose3 T_kf_odom_ = Pose3::Identity();  // inverse pose of the keyframe's first event
  EmvsCounts counts_;
  std::vector<KeyframeEvent> kf_events_;
  std::vector<PoseSlice> kf_slices_;
  std::vector<VolumeRay> rays_;  // the rays of the last DSI (to clear it)
};

struct GlobalMapOptions {
  double voxel_size_m = 0.05;  // voxel edge of the downsampled cloud [m]
  size_t max_points = 500000;  // voxels kept; beyond, the oldest, then least-supported, are dropped
  /// Throws std::invalid_argument naming the field by its YAML key, section + "." + key.
  void validate(const std::string& section = "mapping.global_map") const;
};

/// Keyframe clouds fused into one voxel-downsampled cloud in odom (centroid per voxel). Memory is
/// bounded by max_points (plus one keyframe while it is inserted).
class GlobalMap {
 public:
  explicit GlobalMap(const GlobalMapOptions& options = GlobalMapOptions());
  /// Adds a cloud (odom frame); then drops voxels beyond max_points, oldest keyframe first and
  /// among equals those with the fewest points. Non-finite points are skipped.
  void insert(const std::vector<MapPoint>& points_odom);
  /// Centroids, confidence = mean confidence of the points in the voxel.
  std::vector<MapPoint> points() const;
  size_t size() const { return voxels_.size(); }
  size_t dropped() const { return dropped_; }
  void clear();

 private:
  struct Voxel {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    double confidence_sum = 0.0;
    uint32_t count = 0;
    uint64_t last_insert = 0;
  };
  GlobalMapOptions options_;
  std::unordered_map<uint64_t, Voxel> voxels_;
  uint64_t inserts_ = 0;
  size_t dropped_ = 0;
};

/// Colour-coded depth (BGR8, inverse-depth jet: near red, far blue; black where depth is 0).
cv::Mat colorizeDepth(const cv::Mat& depth_m, double z_min_m, double z_max_m);

}  // namespace vwe_vo
