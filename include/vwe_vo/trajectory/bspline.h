// Planar B-spline trajectory of base_link in odom (the back-end's model): position c(t), heading
// tangent to the path, standstills held; its least-squares fit and its TrajectoryModel view.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "vwe_vo/common/math.h"
#include "vwe_vo/trajectory/trajectory_model.h"

namespace vwe_vo {

/// Highest supported spline degree (bounds the stack storage of the basis functions).
constexpr int kBSplineMaxDegree = 7;

/// Basis functions active at a spline time u and their derivatives.
struct BasisDerivatives {
  using Matrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor,
                               kBSplineMaxDegree + 1, kBSplineMaxDegree + 1>;
  int first = 0;  // index of the first active control point (span - degree)
  Matrix values;  // (num_derivs + 1) x (degree + 1): (k, j) = d^k N_{first+j,p} / du^k
};

/// Planar pose of base_link (heading psi, position c) and its derivatives w.r.t. the control
/// point coordinates (parameter index 2 i + coordinate), in fixed-size storage: filling one
/// allocates nothing on the heap. Each parameter index appears once.
struct PlanarPoseJacobian {
  static constexpr int kMaxParams = 4 * (kBSplineMaxDegree + 1);
  int size = 0;
  int index[kMaxParams];
  double dpsi[kMaxParams];  // d psi / d theta_k [rad]
  Vec2 dp[kMaxParams];      // d c / d theta_k [1]
};

/// c(u) = sum_i N_{i,p}(u) P_i, u = spline time [s] relative to the knot epoch (int64 ns).
/// The domain is [knots[p], knots[n+1]] (n + 1 control points); outside it the polynomial of
/// the first / last span is extrapolated. Parameters of the pose Jacobians are the control
/// points stacked [x0, y0, x1, y1, ...] (index 2 i + coordinate).
///
/// Heading psi(u) = atan2(c'_y, c'_x), never of a (near) zero tangent:
///  - inside a standstill interval [a, b] the position is held at c(a) and the heading at its
///    held value at a: the tangent at a if |c'(a)| >= minSpeed(), else the nearest usable
///    tangent looking back from a, else (a standstill at the start) looking ahead from b;
///  - elsewhere, if |c'(u)| < minSpeed(), the nearest usable tangent looking back from u
///    (steps 1e-4 s, doubling; behind is tried before ahead at each step), skipping standstills;
///  - if the whole spline has no usable tangent, defaultHeading().
/// A reversing vehicle therefore shows a heading flipped by pi (the tangent points backwards).
class BSpline {
 public:
  /// A standstill [from_s, to_s] in spline time.
  struct Interval {
    double from_s, to_s;
  };

  BSpline() = default;
  /// 1 <= degree <= kBSplineMaxDegree, knots_s non-decreasing with control_points.size() + degree +
  /// 1 entries and a non-empty domain; throws std::invalid_argument naming what is wrong.
  BSpline(int degree, std::vector<double> knots_s, std::vector<Vec2> control_points,
          int64_t epoch_ns);

  /// Clamped uniform knots on [from_s, to_s] for num_control_points >= degree + 1.
  static std::vector<double> clampedUniformKnots(int degree, int num_control_points, double from_s,
                                                 double to_s);

  int degree() const { return degree_; }
  int numControlPoints() const { return static_cast<int>(control_points_.size()); }
  const std::vector<double>& knots() const { return knots_; }
  const std::vector<Vec2>& controlPoints() const { return control_points_; }
  /// Setters keep the sizes (throw std::invalid_argument otherwise).
  void setControlPoints(const std::vector<Vec2>& control_points);
  void setControlPoint(int i, const Vec2& p);

  int64_t epochNs() const { return epoch_ns_; }
  /// Spline time [s] of a stamp.
  double toSplineTime(int64_t t_ns) const { return dtSec(t_ns, epoch_ns_); }
  /// Domain [validFrom(), validTo()] in spline time [s].
  double validFrom() const { return knots_[degree_]; }
  double validTo() const { return knots_[control_points_.size()]; }
  bool covers(int64_t t_ns) const;

  /// Piegl & Tiller A2.1: the knot span index s with knots[s] <= u < knots[s+1], clamped to
  /// [degree, n] (the last span for u >= validTo()).
  int findSpan(double u) const;
  /// Piegl & Tiller A2.3: the degree + 1 non-zero basis functions at u and their derivatives up
  /// to num_derivs (0 <= num_derivs <= kBSplineMaxDegree; those above the degree are zero).
  /// Allocates nothing on the heap.
  BasisDerivatives basis(double u, int num_derivs) const;

  /// d^order c / du^order at u.
  Vec2 derivative(double u, int order) const;
  Vec2 position(double u) const { return derivative(u, 0); }
  Vec2 velocity(double u) const { return derivative(u, 1); }
  Vec2 acceleration(double u) const { return derivative(u, 2); }

  /// Standstills: sorted, non-overlapping, from_s <= to_s (throws std::invalid_argument).
  void setStandstills(const std::vector<Interval>& standstills);
  const std::vector<Interval>& standstills() const { return standstills_; }
  /// The standstill containing u (its ends included), or null.
  const Interval* standstillAt(double u) const;
  /// Speed [m/s] below which the tangent is not trusted for the heading (> 0).
  void setMinSpeed(double min_speed_mps);
  double minSpeed() const { return min_speed_mps_; }
  /// Heading [rad] used when the spline has no usable tangent at all.
  void setDefaultHeading(double yaw) {
    default_heading_ = yaw;
    ++version_;
  }
  double defaultHeading() const { return default_heading_; }

  /// Heading psi(u) [rad] following the rules above; always finite.
  double heading(double u) const;
  /// Pose of base_link in odom at u: position (c, 0), rotation Rz(psi). If jac is not null it
  /// is filled w.r.t. the control points; each parameter index appears at most once.
  Pose3 T_odom_base(double u, PoseJacobian* jac = nullptr) const;
  /// The same pose as heading psi (returned) and position c, with its Jacobian (if not null) in
  /// fixed-size storage; one basis evaluation when the vehicle moves (no standstill, usable
  /// tangent at u).
  double planarPose(double u, Vec2* position, PlanarPoseJacobian* jac = nullptr) const;
  /// Incremented by every change of the control points, knots, standstills, minimum speed or
  /// default heading (lets views cache what they derive from the spline).
  uint64_t version() const { return version_; }
  /// T_odom_base(u) * T_base_cam, with the Jacobian likewise.
  Pose3 T_odom_cam(double u, const Pose3& T_base_cam, PoseJacobian* jac = nullptr) const;

 private:
  // Where a pose at u takes its position and its heading from.
  struct PoseSource {
    double u_position;
    double u_tangent;
    bool has_tangent;  // false: defaultHeading()
  };
  PoseSource poseSource(double u) const;
  bool usableTangent(double u) const;
  void validate() const;

  int degree_ = 3;
  std::vector<double> knots_;
  std::vector<Vec2> control_points_;
  int64_t epoch_ns_ = 0;
  std::vector<Interval> standstills_;
  double min_speed_mps_ = 1e-3;
  double default_heading_ = 0.0;
  uint64_t version_ = 0;
};

/// Options of the least-squares fit of a BSpline to timestamped positions.
struct BSplineFitOptions {
  enum class KnotPlacement { kPieglTiller, kUniform };
  int degree = 3;               // spline degree p, in [1, kBSplineMaxDegree]
  int num_control_points = 0;   // n + 1 (>= degree + 1); 0: chosen from knot_spacing_s
  double knot_spacing_s = 0.5;  // target knot span [s] when num_control_points == 0, > 0
  KnotPlacement knot_placement = KnotPlacement::kPieglTiller;
  /// Throws std::invalid_argument naming the bad field.
  void validate() const;
};

/// Piegl & Tiller eq. 9.68-9.69: clamped knots for parameters u (non-decreasing, spline time),
/// averaging the parameters so every span holds samples. Needs u.size() >= num_control_points.
std::vector<double> pieglTillerKnots(const std::vector<double>& u, int degree,
                                     int num_control_points);

/// Least-squares fit (Piegl & Tiller 9.4.1): the end control points equal the first and last
/// positions, the interior ones minimise the squared position error at the samples. Times are
/// strictly increasing; the epoch is t_ns.front(). Throws std::invalid_argument on bad input
/// (sizes, too few samples: the message gives the counts) and std::runtime_error if the
/// interior control points are not determined (a knot span without samples).
BSpline fitBSpline(const std::vector<int64_t>& t_ns, const std::vector<Vec2>& p_odom,
                   const BSplineFitOptions& options = BSplineFitOptions());
/// The same fit with given clamped knots_s (spline time relative to epoch_ns); the first and
/// last samples must lie at the ends of the domain.
BSpline fitBSplineWithKnots(const std::vector<int64_t>& t_ns, const std::vector<Vec2>& p_odom,
                            int degree, const std::vector<double>& knots_s, int64_t epoch_ns);

/// The spline seen from the camera: T_Cr_Ct(t) = T_cam_odom(t_ref) * T_odom_cam(t), with
/// theta = the control points stacked [x0, y0, x1, y1, ...] (numParams = 2 numControlPoints).
/// The Jacobian holds the control points active at t or at t_ref (and where their headings
/// come from); each parameter index appears once (contributions of t and t_ref are merged).
/// The spline is shared: changing its control points changes the model. The reference pose and
/// its Jacobian are computed once (construction) and reused while the spline's version() is
/// unchanged; T_Cr_Ct is const and safe to call from several threads.
class BSplineCameraModel : public TrajectoryModel {
 public:
  BSplineCameraModel(std::shared_ptr<const BSpline> spline, const Pose3& T_base_cam,
                     int64_t t_ref_ns);

  int numParams() const override { return 2 * spline_->numControlPoints(); }
  int64_t referenceTime() const override { return t_ref_ns_; }
  /// True if both t and t_ref are inside the spline's domain.
  bool covers(int64_t t_ns) const override;
  Pose3 T_Cr_Ct(int64_t t_ns, PoseJacobian* jac = nullptr) const override;
  /// The factored Jacobian (what the back-end's objective uses): the planar coordinates of
  /// T_Vr_Vt depend on the control points active at t and at t_ref; addPlanarGradient sums the
  /// reference's share over all rays first and applies it once.
  bool hasPlanarJacobian() const override { return true; }
  Pose3 T_Cr_CtPlanar(int64_t t_ns, PlanarLocalJacobian* jac) const override;
  void addPlanarGradient(const std::vector<int64_t>& t_ns, const std::vector<Vec3>& g,
                         Eigen::VectorXd* gradient) const override;

  const BSpline& spline() const { return *spline_; }
  const Pose3& T_base_cam() const { return T_base_cam_; }
  /// The body's tilt about base_link (a rotation) at a time: the camera then sits at
  /// T_odom_base(t) * tilt(t) * T_base_cam, so T_Cr_Ct = (tilt(t_ref) T_base_cam)^-1 T_Vr_Vt
  /// (tilt(t) T_base_cam). Held as given (no derivative); empty: no tilt.
  void setTilt(std::function<Mat3(int64_t)> tilt);

 private:
  struct Reference {
    uint64_t version = 0;
    double psi = 0.0;
    Vec2 position = Vec2::Zero();
    PlanarPoseJacobian jac;
  };
  void computeReference(Reference* ref) const;
  /// The cached reference, or (the spline changed since) *fresh computed anew.
  const Reference& reference(Reference* fresh) const;
  /// T_Vr_Vt at t: position R_r^T (p_t - p_r) returned, heading psi_t - psi_r in *dpsi, and the
  /// derivatives of (psi_t, p_t) in *jac_t if not null.
  Vec2 relativePose(const Reference& ref, int64_t t_ns, double* dpsi,
                    PlanarPoseJacobian* jac_t) const;

  /// The camera's mount at t with the tilt (at t_ref: mount_ref_).
  Pose3 tiltedMount(int64_t t_ns) const;

  std::shared_ptr<const BSpline> spline_;
  Pose3 T_base_cam_;
  std::function<Mat3(int64_t)> tilt_;
  int64_t t_ref_ns_;
  Pose3 mount_ref_;  // tiltedMount(t_ref), set by setTilt
  Reference ref_;    // cached at construction
};

}  // namespace vwe_vo
