// Textured scenes for the event simulator (axis-aligned boxes and planes: rooms, corridors,
// streets) and a ray caster that renders linear intensity and depth for every sensor pixel from
// the camera's per-pixel bearing table (so images are on the distorted sensor).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "vwe_vo/common/math.h"
#include "vwe_vo/common/thread_pool.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sim/texture.h"

namespace vwe_vo {
namespace sim {

class VehicleTrajectory;

/// An axis-aligned rectangle in odom, seen from both sides unless `facing` says otherwise. Surface
/// coordinates (u, v) [m]: normal x -> (y, z), normal y -> (x, z), normal z -> (x, y) (v is the
/// height on walls).
struct Face {
  int axis = 2;              // index of the normal axis (0 x, 1 y, 2 z)
  float plane = 0.f;         // coordinate along the normal [m]
  float lo[2] = {0, 0};      // lower bounds of (u, v) [m]
  float hi[2] = {0, 0};      // upper bounds of (u, v) [m]
  int texture = 0;           // index into Scene::textures
  float offset[2] = {0, 0};  // texture offset added to (u, v) [m]
  float gain = 1.f;          // reflectance x illumination factor of the face [-]
  int facing = 0;  // +1 / -1: seen only from the + / - side of its normal axis (a closed box's
                   // outside); 0: both
};

struct Scene {
  std::string name;
  std::vector<std::shared_ptr<const Texture>> textures;
  std::vector<Face> faces;
  float sky_intensity = 0.8f;  // linear intensity of rays that hit nothing (at the horizon) [-]

  /// Adds the faces of the box [min, max] (without the bottom face), each seen from outside only;
  /// returns the first index.
  size_t addBox(const Eigen::Vector3f& min, const Eigen::Vector3f& max, int texture, float gain,
                uint64_t seed);
  /// Adds one rectangle with normal `axis` at `plane` spanning [lo, hi] in its (u, v).
  size_t addRect(int axis, float plane, Eigen::Vector2f lo, Eigen::Vector2f hi, int texture,
                 float gain, uint64_t seed);
};

/// Scene kinds: "indoor" (a lab room with furniture and posters), "corridor", "street"
/// (facades with windows, poles, parked cars). The layout follows `path` (the street's axis);
/// obstacles keep clear of it and of `vehicle`'s path when given (a car weaving around the axis).
/// Throws std::invalid_argument naming the valid kinds for an unknown one.
Scene buildScene(const std::string& kind, uint64_t seed, const VehicleTrajectory& path,
                 const VehicleTrajectory* vehicle = nullptr);
std::vector<std::string> sceneKinds();

/// Ray caster over a scene. prepare() culls faces per 16x16 pixel tile for one camera pose;
/// renderTileRow() may then be called concurrently for different tile rows.
class SceneRenderer {
 public:
  /// supersampling: s x s rays per pixel (1 relies on the filtered texture lookup alone).
  SceneRenderer(const Scene& scene, const CameraModel& camera, int supersampling = 1);

  void prepare(const Pose3& T_odom_cam);
  int numTileRows() const { return tiles_y_; }
  int numTileCols() const { return tiles_x_; }
  static constexpr int kTile = 16;
  /// Renders the pixels of one tile: linear intensity (scene radiance before the global
  /// illumination factor) and depth z in the camera frame [m] (0 where nothing was hit).
  /// Output arrays are full images (width * height), row-major; either may be null.
  void renderTile(int tile_col, int tile_row, float* intensity, float* depth) const;
  /// All tiles of one tile row.
  void renderTileRow(int tile_row, float* intensity, float* depth) const;
  /// Convenience: prepare + all tile rows, on `pool` if given.
  void render(const Pose3& T_odom_cam, float* intensity, float* depth, ThreadPool* pool = nullptr);

 private:
  // A face that may be visible from the prepared pose, with what the ray loop needs inline.
  struct FaceCam {
    int axis, ua, va;    // normal axis and surface axes
    float plane_rel;     // plane - camera centre along the normal [m]
    float o_u, o_v;      // camera centre along the surface axes [m]
    float lo[2], hi[2];  // bounds in (u, v) [m]
    float offset[2];     // texture offset [m]
    float gain;
    float min_dist;  // distance from the camera centre to the nearest point of the face [m]
    const Texture* tex;
  };
  const Scene& scene_;
  const CameraModel& camera_;
  int ss_;
  int width_, height_, tiles_x_, tiles_y_;
  float pixel_angle_;  // approximate angle of one pixel [rad]
  // Unit bearings (camera frame) of every ray, structure of arrays in tile order: the rays of
  // tile t start at tile_ray_begin_[t], pixel row-major inside the tile, ss^2 rays per pixel.
  std::vector<float> ray_x_, ray_y_, ray_z_;
  std::vector<size_t> tile_ray_begin_;
  std::vector<Eigen::Vector4f> tile_bounds_;  // normalised (x/z, y/z) min/max per tile
  std::vector<Eigen::Vector2f> col_bounds_,
      row_bounds_;                 // union of tile bounds per tile column / row
  Eigen::Vector4f sensor_bounds_;  // union of all tile bounds
  // Per prepared pose:
  Eigen::Matrix3f R_odom_cam_;
  Eigen::Vector3f c_odom_;
  std::vector<FaceCam> visible_;              // faces that may be visible, nearest (min_dist) first
  std::vector<Eigen::Vector4f> face_bounds_;  // per visible face: normalised bounding box
  std::vector<int> order_;                    // visible faces by min_dist
  std::vector<std::vector<int>> tile_faces_;  // indices into visible_, nearest first
};

}  // namespace sim
}  // namespace vwe_vo
