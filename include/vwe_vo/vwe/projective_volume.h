// The projective voxel volume in front of a reference camera and the one voting kernel that both
// the Volume of Warped Events (front-end, back-end) and the EMVS disparity-space image (mapping)
// use. A ray o + lambda d (reference camera frame) meets the plane z = z_l at the virtual-pinhole
// pixel u_l = fx (d_x/d_z + rho_l (o_x - o_z d_x/d_z)) + cx with rho_l = 1/z_l: linear in the
// inverse depth, so with planes uniform in inverse depth a vote costs a multiply-add per plane.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "vwe_vo/common/math.h"
#include "vwe_vo/common/thread_pool.h"

namespace vwe_vo {

/// What the VWE objective measures of the votes (the DSI of the mapping ignores it).
///  - kVariance: the variance over all voxels (paper eq. 3), (sum V^2 - (sum V)^2 / N) / N. It
///    grows with every vote that lands in the grid, focused or not, so a trajectory that keeps
///    more rays inside the grid scores higher: with structure on one side of the view, a yaw
///    error that turns the rays of that side's image border into the grid is rewarded (on a street,
///    a left facade pulls the yaw rate left, a right one right).
///  - kDensityPerVote: (sum V^2 - sum_votes |w|^2) / sum V, the mean density of the other votes
///    a vote meets (at a vote, the value of the grid there without its own weights w): as sharp
///    as the variance for a fixed set of votes, but votes that leave or enter the grid do not
///    change it unless they are more or less focused than the rest. A vote's own share,
///    |w|^2 = ((1-ax)^2 + ax^2) ((1-ay)^2 + ay^2), says nothing of the trajectory: it is 1 on a
///    voxel centre and 1/4 between four, and about three quarters of sum V^2. At the planes
///    near infinity with a zero yaw rate every vote of the image's centre lands on its pixel's
///    own phase, so counted, it makes a spike of the objective at zero yaw rate one or two
///    deg/s wide that holds straight driving at exactly zero and pulls slow steering to it
///    (street_drive's front-end: 0.0-0.1 deg/s in 32 of 172 windows whose true rate was 2-6).
enum class Contrast { kVariance, kDensityPerVote };
/// The YAML name of a Contrast: "variance" or "density_per_vote".
const char* contrastName(Contrast contrast);

struct VolumeOptions {
  double grid_scale = 0.5;  // grid resolution relative to the sensor (0.5 = half resolution)
  Contrast contrast = Contrast::kDensityPerVote;  // the objective's measure (see Contrast)
  int margin_px = 8;     // grid padding around the image on each side [grid px]
  int num_planes = 30;   // depth planes, uniform in inverse depth
  double z_min_m = 0.4;  // nearest plane [m]
  // Farthest plane [m]. Negative: the planes run on through infinity (inverse depth 0) to
  // inverse depth 1 / z_max_m < 0, the continuation of the rays past their point at infinity.
  // For open scenes (a street that runs to the horizon): a finite far plane is a cliff, and a
  // yaw error that moves distant points of one side past infinity loses their votes while the
  // opposite error only brings them nearer, so each side's distant structure pulls the yaw
  // towards itself (street_drive, in the right lane: front-end yaw 0.76 x true + 0.6 deg/s).
  // Where every surface is nearer than z_max_m (a room), the finite cliff is true and helps.
  double z_max_m = 12.0;
  int num_threads = 2;  // threads for voting (split over planes)
  // The events of a slice of this many seconds (a fixed grid of absolute times) share the pose
  // at its middle (poseSliceTime in vwe/ray_builder.h), in the VWE and the EMVS DSI alike (0: a
  // pose per event). 0.5 ms moves the camera 3 mm at 6 m/s and turns it 0.5 mrad at 1 rad/s
  // (0.1 px), and saves most of the per-event trajectory work.
  double pose_slice_s = 0.0005;
  /// Throws std::invalid_argument naming the field by its key, section + "." + field.
  void validate(const std::string& section = "volume") const;
};

/// A ray in the reference camera frame as the voting kernel needs it: its pixel in the virtual
/// pinhole at inverse depth rho is (u0 + rho * du, v0 + rho * dv); valid for rho < rho_max.
/// Made from events and poses by VolumeRayBuilder (vwe/ray_builder.h).
struct VolumeRay {
  float u0, v0, du, dv;
  float rho_max;
};

class ProjectiveVolume {
 public:
  /// sensor_* describe the undistorted virtual pinhole of the full-resolution sensor.
  ProjectiveVolume(const VolumeOptions& options, int sensor_width, int sensor_height, double fx,
                   double fy, double cx, double cy);

  const VolumeOptions& options() const { return options_; }
  int width() const { return width_; }
  int height() const { return height_; }
  int numPlanes() const { return options_.num_planes; }
  size_t numVoxels() const { return size_t(width_) * height_ * options_.num_planes; }
  /// Depth of plane l [m]; infinity for the planes at and past infinity (inverse depth <= 0).
  double planeDepth(int l) const {
    return rho_[l] > 0 ? 1.0 / rho_[l] : std::numeric_limits<double>::infinity();
  }
  double planeInverseDepth(int l) const { return rho_[l]; }
  /// The volume's virtual pinhole (grid pixels).
  double fx() const { return fx_; }
  double fy() const { return fy_; }
  double cx() const { return cx_; }
  double cy() const { return cy_; }

  /// The optimisers' evaluation: the contrast (options().contrast) of the volume the rays vote,
  /// and (if sensitivities is not null) its gradient per ray, s = [S_u0, S_du, S_v0, S_dv] with
  /// dC/dray = s . d[u0,du,v0,dv]. Votes plane by plane into a scratch plane per thread that
  /// stays in cache; the grid is not touched, and the cost is bounded by the votes (votes cast
  /// into *votes if not null). A vote is cast where its bilinear footprint lies inside the grid:
  /// its weights always sum to one, so the derivative of sum V is zero and
  /// dC/dray = (2 / N or 2 / sum V) sum over its votes of the grid's gradient there.
  double contrastOfRays(const std::vector<VolumeRay>& rays, size_t* votes,
                        std::vector<Eigen::Vector4d>* sensitivities = nullptr);

  /// The grid, for what reads the voxels (images, the EMVS DSI): bilinear votes of every ray
  /// into every plane it meets (the grid must be clear). Returns the number of plane-votes cast;
  /// afterwards sum() is valid. for_contrast = false (the DSI) skips what only contrast() and
  /// clear() need of the density per vote, the votes' own squared weights: its contrast is then
  /// NaN until the grid is clear.
  size_t vote(const std::vector<VolumeRay>& rays, bool for_contrast = true);
  /// Sum of all voxels (every vote adds weights summing to one).
  double sum() const { return sum_; }
  /// Contrast (options().contrast) of what vote() put in the grid, by one pass over the grid.
  double contrast() const;
  /// Clears what vote() touched (cost bounded by the votes: whole planes only when the votes
  /// cover them anyway) and returns the contrast the votes gave the grid.
  double clear(const std::vector<VolumeRay>& rays);

  /// After vote(): the depth of the plane where the ray's bilinear footprint holds the most
  /// votes, i.e. where the rays around it meet (0 if it meets no plane; infinity for a plane at
  /// or past infinity). Costs one read per plane.
  double peakDepth(const VolumeRay& ray) const;

  /// Voxel value after vote() (for tests, EMVS argmax, images).
  float at(int x, int y, int l) const { return grid_[(size_t(l) * height_ + y) * width_ + x]; }
  const std::vector<float>& data() const { return grid_; }

 private:
  template <typename Fn>
  void forEachPlaneVote(const VolumeRay& r, float rho, Fn&& fn) const;
  template <typename Fn>
  void forEachVote(const VolumeRay& r, int l, Fn&& fn) const;
  /// Sum of squares of a plane's voxels, zeroing them: by a sweep over the plane (when the votes
  /// cover a quarter of it anyway), otherwise by visiting the votes of the rays in soa_.
  double takeSquares(float* plane, float rho, bool sweep) const;
  /// Zeroes a scratch plane after `votes` votes of the rays in soa_: by a fill when they are
  /// many, otherwise by revisiting them.
  void zeroPlane(float* plane, float rho, size_t votes) const;
  /// forEachPlaneVote() over the rays [begin, end) of soa_: fn(ray index, voxel index, ax, ay).
  template <typename Fn>
  void forEachPlaneVoteBatched(float rho, size_t begin, size_t end, Fn&& fn) const;
  /// The rays of contrastOfRays() and vote() by columns, for forEachPlaneVoteBatched().
  struct RayColumns {
    std::vector<float> u0, v0, du, dv, rho_max;
    size_t size = 0;
    void assign(const std::vector<VolumeRay>& rays);
  };
  RayColumns soa_;

  VolumeOptions options_;
  int width_, height_;
  double fx_, fy_, cx_, cy_;
  std::vector<double> rho_;
  std::vector<float> grid_;                  // allocated by the first vote()
  std::vector<std::vector<float>> scratch_;  // one plane per thread (contrastOfRays)
  std::vector<std::vector<Eigen::Vector4d>> chunk_sens_;
  /// The contrast of a grid with this sum of squares and sum (= votes) of its voxels, whose
  /// votes' own weights have squares summing to self_squares (see Contrast).
  double contrastOf(double sum_squares, double sum, double self_squares) const;

  double sum_ = 0.0;
  double self_ = 0.0;  // sum over the votes of vote() of their own weights' squares |w|^2
  size_t last_votes_ = 0;
  std::vector<size_t> plane_counts_;   // votes per plane (group)
  std::vector<double> plane_squares_;  // sum of squares per plane
  std::vector<double> plane_self_;     // sum of |w|^2 per plane (group)
  mutable ThreadPool pool_;
};

}  // namespace vwe_vo
