#include "vwe_vo/trajectory/bspline.h"

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "vwe_vo/trajectory/ackermann_arc.h"

namespace vwe_vo {

namespace {

// First step of the search for a usable tangent around a slow or held pose [s]; doubles.
constexpr double kTangentSearchStep_s = 1e-4;

void checkStampsAndSizes(const char* who, const std::vector<int64_t>& t_ns,
                         const std::vector<Vec2>& p_odom) {
  if (t_ns.size() != p_odom.size()) {
    throw std::invalid_argument(std::string(who) + ": " + std::to_string(t_ns.size()) +
                                " stamps but " + std::to_string(p_odom.size()) + " positions");
  }
  for (size_t k = 1; k < t_ns.size(); ++k) {
    if (t_ns[k] <= t_ns[k - 1]) {
      throw std::invalid_argument(std::string(who) + ": stamps must increase strictly, but t_ns[" +
                                  std::to_string(k) + "] = " + std::to_string(t_ns[k]) +
                                  " <= t_ns[" + std::to_string(k - 1) +
                                  "] = " + std::to_string(t_ns[k - 1]));
    }
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// BSpline

BSpline::BSpline(int degree, std::vector<double> knots_s, std::vector<Vec2> control_points,
                 int64_t epoch_ns)
    : degree_(degree),
      knots_(std::move(knots_s)),
      control_points_(std::move(control_points)),
      epoch_ns_(epoch_ns) {
  validate();
}

void BSpline::validate() const {
  const int p = degree_;
  const int ncp = numControlPoints();
  if (p < 1 || p > kBSplineMaxDegree) {
    throw std::invalid_argument("BSpline: degree must be in [1, " +
                                std::to_string(kBSplineMaxDegree) + "], got " + std::to_string(p));
  }
  if (ncp < p + 1) {
    throw std::invalid_argument("BSpline: " + std::to_string(ncp) +
                                " control points are too few for degree " + std::to_string(p) +
                                " (need >= " + std::to_string(p + 1) + ")");
  }
  if (static_cast<int>(knots_.size()) != ncp + p + 1) {
    throw std::invalid_argument(
        "BSpline: knots has " + std::to_string(knots_.size()) +
        " entries, need control points + degree + 1 = " + std::to_string(ncp + p + 1));
  }
  for (size_t i = 0; i < knots_.size(); ++i) {
    if (!std::isfinite(knots_[i])) {
      throw std::invalid_argument("BSpline: knots[" + std::to_string(i) + "] is not finite");
    }
    if (i > 0 && knots_[i] < knots_[i - 1]) {
      throw std::invalid_argument("BSpline: knots must be non-decreasing, but knots[" +
                                  std::to_string(i) + "] < knots[" + std::to_string(i - 1) + "]");
    }
    if (i + p + 1 < knots_.size() && !(knots_[i] < knots_[i + p + 1])) {
      throw std::invalid_argument("BSpline: knot multiplicity exceeds degree + 1 at knots[" +
                                  std::to_string(i) + "]");
    }
  }
  if (!(validFrom() < validTo())) {
    throw std::invalid_argument("BSpline: empty domain [knots[degree], knots[n+1]]");
  }
}

std::vector<double> BSpline::clampedUniformKnots(int degree, int num_control_points, double from_s,
                                                 double to_s) {
  if (degree < 1 || num_control_points < degree + 1 || !(from_s < to_s)) {
    throw std::invalid_argument("clampedUniformKnots: need degree >= 1 (got " +
                                std::to_string(degree) +
                                "), num_control_points >= degree + 1 (got " +
                                std::to_string(num_control_points) + ") and from_s < to_s");
  }
  const int spans = num_control_points - degree;
  std::vector<double> knots(num_control_points + degree + 1);
  for (int i = 0; i <= degree; ++i) {
    knots[i] = from_s;
    knots[knots.size() - 1 - i] = to_s;
  }
  for (int j = 1; j < spans; ++j) {
    knots[degree + j] = from_s + (to_s - from_s) * static_cast<double>(j) / spans;
  }
  return knots;
}

void BSpline::setControlPoints(const std::vector<Vec2>& control_points) {
  if (control_points.size() != control_points_.size()) {
    throw std::invalid_argument("BSpline::setControlPoints: got " +
                                std::to_string(control_points.size()) + " control points, need " +
                                std::to_string(control_points_.size()));
  }
  control_points_ = control_points;
  ++version_;
}

void BSpline::setControlPoint(int i, const Vec2& p) {
  if (i < 0 || i >= numControlPoints()) {
    throw std::invalid_argument("BSpline::setControlPoint: index " + std::to_string(i) +
                                " outside [0, " + std::to_string(numControlPoints()) + ")");
  }
  control_points_[i] = p;
  ++version_;
}

bool BSpline::covers(int64_t t_ns) const {
  const double u = toSplineTime(t_ns);
  return u >= validFrom() && u <= validTo();
}

int BSpline::findSpan(double u) const {
  const int p = degree_;
  const int n = numControlPoints() - 1;
  // Outside the domain: the first / last non-empty span (extrapolation).
  if (!(u > knots_[p])) {
    int s = p;
    while (!(knots_[s] < knots_[s + 1])) ++s;
    return s;
  }
  if (u >= knots_[n + 1]) {
    int s = n;
    while (!(knots_[s] < knots_[s + 1])) --s;
    return s;
  }
  int low = p, high = n + 1;  // invariant: knots[low] <= u < knots[high]
  while (high - low > 1) {
    const int mid = (low + high) / 2;
    if (u < knots_[mid]) {
      high = mid;
    } else {
      low = mid;
    }
  }
  return low;
}

BasisDerivatives BSpline::basis(double u, int num_derivs) const {
  const int p = degree_;
  const int i = findSpan(u);
  if (num_derivs < 0 || num_derivs > kBSplineMaxDegree) {
    throw std::invalid_argument("BSpline::basis: num_derivs must be in [0, " +
                                std::to_string(kBSplineMaxDegree) + "], got " +
                                std::to_string(num_derivs));
  }
  const int nd = std::min(num_derivs, p);
  BasisDerivatives out;
  out.first = i - p;
  out.values.setZero(num_derivs + 1, p + 1);

  // ndu: upper triangle basis functions of increasing degree, lower triangle knot differences
  // (all > 0 because knots[i] < knots[i+1]).
  constexpr int kMax = kBSplineMaxDegree + 1;
  Eigen::Matrix<double, kMax, kMax> ndu;
  Eigen::Matrix<double, kMax, 1> left, right;
  ndu(0, 0) = 1.0;
  for (int j = 1; j <= p; ++j) {
    left(j) = u - knots_[i + 1 - j];
    right(j) = knots_[i + j] - u;
    double saved = 0.0;
    for (int r = 0; r < j; ++r) {
      ndu(j, r) = right(r + 1) + left(j - r);
      const double temp = ndu(r, j - 1) / ndu(j, r);
      ndu(r, j) = saved + right(r + 1) * temp;
      saved = left(j - r) * temp;
    }
    ndu(j, j) = saved;
  }
  for (int j = 0; j <= p; ++j) out.values(0, j) = ndu(j, p);

  Eigen::Matrix<double, 2, kMax> a;
  for (int r = 0; r <= p; ++r) {
    int s1 = 0, s2 = 1;
    a(0, 0) = 1.0;
    for (int k = 1; k <= nd; ++k) {
      double d = 0.0;
      const int rk = r - k, pk = p - k;
      if (r >= k) {
        a(s2, 0) = a(s1, 0) / ndu(pk + 1, rk);
        d = a(s2, 0) * ndu(rk, pk);
      }
      const int j1 = rk >= -1 ? 1 : -rk;
      const int j2 = r - 1 <= pk ? k - 1 : p - r;
      for (int j = j1; j <= j2; ++j) {
        a(s2, j) = (a(s1, j) - a(s1, j - 1)) / ndu(pk + 1, rk + j);
        d += a(s2, j) * ndu(rk + j, pk);
      }
      if (r <= pk) {
        a(s2, k) = -a(s1, k - 1) / ndu(pk + 1, r);
        d += a(s2, k) * ndu(r, pk);
      }
      out.values(k, r) = d;
      std::swap(s1, s2);
    }
  }
  double factor = p;  // p! / (p - k)!
  for (int k = 1; k <= nd; ++k) {
    out.values.row(k) *= factor;
    factor *= (p - k);
  }
  return out;
}

Vec2 BSpline::derivative(double u, int order) const {
  if (order < 0) throw std::invalid_argument("BSpline::derivative: negative order");
  if (order > degree_) return Vec2::Zero();  // also keeps order within basis()'s bound
  const BasisDerivatives b = basis(u, order);
  Vec2 c = Vec2::Zero();
  for (int j = 0; j <= degree_; ++j) c += b.values(order, j) * control_points_[b.first + j];
  return c;
}

void BSpline::setStandstills(const std::vector<Interval>& standstills) {
  for (size_t k = 0; k < standstills.size(); ++k) {
    const Interval& s = standstills[k];
    if (!(s.from_s <= s.to_s)) {
      throw std::invalid_argument("BSpline::setStandstills: standstill " + std::to_string(k) +
                                  " has from_s > to_s (or NaN)");
    }
    if (k > 0 && !(standstills[k - 1].to_s < s.from_s)) {
      throw std::invalid_argument("BSpline::setStandstills: standstill " + std::to_string(k) +
                                  " is not after standstill " + std::to_string(k - 1));
    }
  }
  standstills_ = standstills;
  ++version_;
}

void BSpline::setMinSpeed(double min_speed_mps) {
  if (!(min_speed_mps > 0.0) || !std::isfinite(min_speed_mps)) {
    throw std::invalid_argument("BSpline::setMinSpeed: min_speed_mps must be > 0, got " +
                                std::to_string(min_speed_mps));
  }
  min_speed_mps_ = min_speed_mps;
  ++version_;
}

const BSpline::Interval* BSpline::standstillAt(double u) const {
  for (const Interval& s : standstills_) {
    if (u >= s.from_s && u <= s.to_s) return &s;
  }
  return nullptr;
}

bool BSpline::usableTangent(double u) const {
  const double speed = velocity(u).norm();
  return std::isfinite(speed) && speed >= min_speed_mps_;
}

BSpline::PoseSource BSpline::poseSource(double u) const {
  PoseSource src{u, u, true};
  double behind = u, ahead = u;  // the search starts here, looking back from behind first
  if (const Interval* s = standstillAt(u)) {
    src.u_position = s->from_s;
    behind = s->from_s;
    ahead = s->to_s;
    src.u_tangent = s->from_s;
    if (usableTangent(s->from_s)) return src;
  } else if (usableTangent(u)) {
    return src;
  }
  const double lo = validFrom(), hi = validTo();
  bool behind_open = behind > lo, ahead_open = ahead < hi;  // false for NaN too
  // Doubling steps reach any finite domain end within ~1100 iterations; the cap is a guard.
  double h = kTangentSearchStep_s;
  for (int iter = 0; (behind_open || ahead_open) && iter < 2000; ++iter, h *= 2.0) {
    if (behind_open) {
      double ub = behind - h;
      if (ub <= lo) {
        ub = lo;
        behind_open = false;
      }
      if (!standstillAt(ub) && usableTangent(ub)) {
        src.u_tangent = ub;
        return src;
      }
    }
    if (ahead_open) {
      double ua = ahead + h;
      if (ua >= hi) {
        ua = hi;
        ahead_open = false;
      }
      if (!standstillAt(ua) && usableTangent(ua)) {
        src.u_tangent = ua;
        return src;
      }
    }
  }
  src.has_tangent = false;
  return src;
}

double BSpline::heading(double u) const {
  const PoseSource src = poseSource(u);
  if (!src.has_tangent) return default_heading_;
  const Vec2 d = velocity(src.u_tangent);
  return std::atan2(d.y(), d.x());
}

double BSpline::planarPose(double u, Vec2* position, PlanarPoseJacobian* jac) const {
  const int p = degree_;
  // Fast path (a moving vehicle): position and tangent from one basis evaluation at u.
  if (!standstillAt(u)) {
    const BasisDerivatives b = basis(u, 1);
    Vec2 c = Vec2::Zero(), dc = Vec2::Zero();
    for (int j = 0; j <= p; ++j) {
      c += b.values(0, j) * control_points_[b.first + j];
      dc += b.values(1, j) * control_points_[b.first + j];
    }
    const double speed = dc.norm();
    if (std::isfinite(speed) && speed >= min_speed_mps_) {
      *position = c;
      if (jac) {
        // d psi / d c' = (-c'_y, c'_x) / |c'|^2.
        const Vec2 dpsi_ddc = Vec2(-dc.y(), dc.x()) / dc.squaredNorm();
        jac->size = 0;
        for (int j = 0; j <= p; ++j) {
          const int i = b.first + j;
          for (int coord = 0; coord < 2; ++coord) {
            const int s = jac->size++;
            jac->index[s] = 2 * i + coord;
            jac->dpsi[s] = dpsi_ddc(coord) * b.values(1, j);
            jac->dp[s] = Vec2::Zero();
            jac->dp[s](coord) = b.values(0, j);
          }
        }
      }
      return std::atan2(dc.y(), dc.x());
    }
  }
  // Held or slow: position and heading from where poseSource() says.
  const PoseSource src = poseSource(u);
  const BasisDerivatives bp = basis(src.u_position, 0);
  Vec2 c = Vec2::Zero();
  for (int j = 0; j <= p; ++j) c += bp.values(0, j) * control_points_[bp.first + j];
  *position = c;
  double psi = default_heading_;
  BasisDerivatives bt;
  Vec2 dc = Vec2::Zero();
  if (src.has_tangent) {
    bt = basis(src.u_tangent, 1);
    for (int j = 0; j <= p; ++j) dc += bt.values(1, j) * control_points_[bt.first + j];
    psi = std::atan2(dc.y(), dc.x());
  }
  if (jac) {
    // |c'| >= minSpeed() whenever has_tangent.
    const Vec2 dpsi_ddc =
        src.has_tangent ? Vec2(Vec2(-dc.y(), dc.x()) / dc.squaredNorm()) : Vec2(Vec2::Zero());
    // Active control points: the union of the two spans, in increasing order.
    const int lo = src.has_tangent ? std::min(bp.first, bt.first) : bp.first;
    const int hi = src.has_tangent ? std::max(bp.first, bt.first) + p : bp.first + p;
    jac->size = 0;
    for (int i = lo; i <= hi; ++i) {
      const int jp = i - bp.first, jt = i - bt.first;
      const bool in_p = jp >= 0 && jp <= p, in_t = src.has_tangent && jt >= 0 && jt <= p;
      if (!in_p && !in_t) continue;
      const double n0 = in_p ? bp.values(0, jp) : 0.0;
      const double n1 = in_t ? bt.values(1, jt) : 0.0;
      for (int coord = 0; coord < 2; ++coord) {
        const int s = jac->size++;
        jac->index[s] = 2 * i + coord;
        jac->dpsi[s] = dpsi_ddc(coord) * n1;
        jac->dp[s] = Vec2::Zero();
        jac->dp[s](coord) = n0;
      }
    }
  }
  return psi;
}

Pose3 BSpline::T_odom_base(double u, PoseJacobian* jac) const {
  Vec2 c;
  PlanarPoseJacobian pj;
  const double psi = planarPose(u, &c, jac ? &pj : nullptr);
  const Mat3 R = rotZ(psi);
  if (jac) {
    jac->clear();
    const Mat3 dR_dpsi = skew(Vec3::UnitZ()) * R;
    for (int s = 0; s < pj.size; ++s)
      jac->add(pj.index[s], dR_dpsi * pj.dpsi[s], Vec3(pj.dp[s].x(), pj.dp[s].y(), 0.0));
  }
  return makePose(R, Vec3(c.x(), c.y(), 0.0));
}

Pose3 BSpline::T_odom_cam(double u, const Pose3& T_base_cam, PoseJacobian* jac) const {
  const Pose3 T_odom_base_u = T_odom_base(u, jac);
  if (jac) {
    for (size_t k = 0; k < jac->param_index.size(); ++k) {
      jac->dt[k] += jac->dR[k] * T_base_cam.translation();
      jac->dR[k] = jac->dR[k] * T_base_cam.linear();
    }
  }
  return T_odom_base_u * T_base_cam;
}

// ---------------------------------------------------------------------------------------------
// Fitting

void BSplineFitOptions::validate() const {
  if (degree < 1 || degree > kBSplineMaxDegree) {
    throw std::invalid_argument("BSplineFitOptions.degree must be in [1, " +
                                std::to_string(kBSplineMaxDegree) + "], got " +
                                std::to_string(degree));
  }
  if (num_control_points != 0 && num_control_points < degree + 1) {
    throw std::invalid_argument(
        "BSplineFitOptions.num_control_points must be 0 or >= degree + 1 = " +
        std::to_string(degree + 1) + ", got " + std::to_string(num_control_points));
  }
  if (!(knot_spacing_s > 0.0) || !std::isfinite(knot_spacing_s)) {
    throw std::invalid_argument("BSplineFitOptions.knot_spacing_s must be > 0, got " +
                                std::to_string(knot_spacing_s));
  }
  if (knot_placement != KnotPlacement::kPieglTiller && knot_placement != KnotPlacement::kUniform) {
    throw std::invalid_argument("BSplineFitOptions.knot_placement has an unknown value " +
                                std::to_string(static_cast<int>(knot_placement)));
  }
}

std::vector<double> pieglTillerKnots(const std::vector<double>& u, int degree,
                                     int num_control_points) {
  const int p = degree;
  const int n = num_control_points - 1;
  const int m = static_cast<int>(u.size()) - 1;
  if (p < 1 || n < p) {
    throw std::invalid_argument(
        "pieglTillerKnots: need degree >= 1 and num_control_points >= "
        "degree + 1, got degree " +
        std::to_string(p) + " and " + std::to_string(num_control_points) + " control points");
  }
  if (m < n) {
    throw std::invalid_argument("pieglTillerKnots: " + std::to_string(m + 1) +
                                " parameters are too few for " +
                                std::to_string(num_control_points) + " control points");
  }
  std::vector<double> knots(n + p + 2);
  for (int i = 0; i <= p; ++i) {
    knots[i] = u.front();
    knots[n + 1 + i] = u.back();
  }
  const double d = static_cast<double>(m + 1) / (n - p + 1);  // eq. 9.68
  for (int j = 1; j <= n - p; ++j) {                          // eq. 9.69
    const int i = static_cast<int>(j * d);
    const double alpha = j * d - i;
    knots[p + j] = (1.0 - alpha) * u[i - 1] + alpha * u[i];
  }
  return knots;
}

BSpline fitBSplineWithKnots(const std::vector<int64_t>& t_ns, const std::vector<Vec2>& p_odom,
                            int degree, const std::vector<double>& knots_s, int64_t epoch_ns) {
  checkStampsAndSizes("fitBSplineWithKnots", t_ns, p_odom);
  const int ncp = static_cast<int>(knots_s.size()) - degree - 1;
  BSpline spline(degree, knots_s, std::vector<Vec2>(std::max(ncp, 0), Vec2::Zero()), epoch_ns);
  const int n = ncp - 1;
  const int m = static_cast<int>(t_ns.size()) - 1;
  if (m + 1 < ncp || m < 1) {
    throw std::invalid_argument("fitBSplineWithKnots: " + std::to_string(m + 1) +
                                " samples are too few for " + std::to_string(ncp) +
                                " control points of degree " + std::to_string(degree) +
                                " (need at least " + std::to_string(std::max(ncp, 2)) + ")");
  }
  std::vector<double> u(m + 1);
  for (int k = 0; k <= m; ++k) u[k] = spline.toSplineTime(t_ns[k]);
  constexpr double kEndTolerance_s = 1e-9;
  if (std::abs(u.front() - spline.validFrom()) > kEndTolerance_s ||
      std::abs(u.back() - spline.validTo()) > kEndTolerance_s) {
    throw std::invalid_argument("fitBSplineWithKnots: samples span [" + std::to_string(u.front()) +
                                ", " + std::to_string(u.back()) + "] s but the spline domain is [" +
                                std::to_string(spline.validFrom()) + ", " +
                                std::to_string(spline.validTo()) + "] s");
  }

  std::vector<Vec2> P(ncp);
  P.front() = p_odom.front();
  P.back() = p_odom.back();
  if (n >= 2) {
    // Rows: interior samples; columns: interior control points 1..n-1.
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(m - 1, n - 1);
    Eigen::MatrixXd rhs(m - 1, 2);
    for (int k = 1; k < m; ++k) {
      const BasisDerivatives b = spline.basis(u[k], 0);
      Vec2 r = p_odom[k];
      for (int j = 0; j <= degree; ++j) {
        const int i = b.first + j;
        const double N = b.values(0, j);
        if (i == 0) {
          r -= N * p_odom.front();
        } else if (i == n) {
          r -= N * p_odom.back();
        } else {
          A(k - 1, i - 1) = N;
        }
      }
      rhs.row(k - 1) = r.transpose();
    }
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(A);
    if (qr.rank() < n - 1) {
      throw std::runtime_error(
          "fitBSplineWithKnots: the interior control points are not "
          "determined (rank " +
          std::to_string(qr.rank()) + " of " + std::to_string(n - 1) +
          "): some knot spans hold too few samples");
    }
    const Eigen::MatrixXd X = qr.solve(rhs);
    for (int i = 1; i < n; ++i) P[i] = X.row(i - 1).transpose();
  }
  spline.setControlPoints(P);
  return spline;
}

BSpline fitBSpline(const std::vector<int64_t>& t_ns, const std::vector<Vec2>& p_odom,
                   const BSplineFitOptions& options) {
  options.validate();
  checkStampsAndSizes("fitBSpline", t_ns, p_odom);
  if (t_ns.size() < 2) {
    throw std::invalid_argument("fitBSpline: " + std::to_string(t_ns.size()) +
                                " samples are too few (need at least 2)");
  }
  const int p = options.degree;
  std::vector<double> u(t_ns.size());
  for (size_t k = 0; k < t_ns.size(); ++k) u[k] = dtSec(t_ns[k], t_ns.front());
  int ncp = options.num_control_points;
  if (ncp == 0) {
    const int spans =
        std::max(1, static_cast<int>(std::ceil(u.back() / options.knot_spacing_s - 1e-9)));
    ncp = spans + p;
  }
  if (static_cast<int>(t_ns.size()) < ncp) {
    throw std::invalid_argument("fitBSpline: " + std::to_string(t_ns.size()) +
                                " samples are too few for " + std::to_string(ncp) +
                                " control points of degree " + std::to_string(p) +
                                " (need at least " + std::to_string(ncp) + ")");
  }
  const std::vector<double> knots =
      options.knot_placement == BSplineFitOptions::KnotPlacement::kPieglTiller
          ? pieglTillerKnots(u, p, ncp)
          : BSpline::clampedUniformKnots(p, ncp, u.front(), u.back());
  return fitBSplineWithKnots(t_ns, p_odom, p, knots, t_ns.front());
}

// ---------------------------------------------------------------------------------------------
// BSplineCameraModel

BSplineCameraModel::BSplineCameraModel(std::shared_ptr<const BSpline> spline,
                                       const Pose3& T_base_cam, int64_t t_ref_ns)
    : spline_(std::move(spline)), T_base_cam_(T_base_cam), t_ref_ns_(t_ref_ns) {
  if (!spline_) throw std::invalid_argument("BSplineCameraModel: spline is null");
  computeReference(&ref_);
}

void BSplineCameraModel::computeReference(Reference* ref) const {
  ref->version = spline_->version();
  ref->psi = spline_->planarPose(spline_->toSplineTime(t_ref_ns_), &ref->position, &ref->jac);
}

bool BSplineCameraModel::covers(int64_t t_ns) const {
  return spline_->covers(t_ns) && spline_->covers(t_ref_ns_);
}

const BSplineCameraModel::Reference& BSplineCameraModel::reference(Reference* fresh) const {
  if (ref_.version == spline_->version()) return ref_;
  computeReference(fresh);
  return *fresh;
}

Vec2 BSplineCameraModel::relativePose(const Reference& ref, int64_t t_ns, double* dpsi,
                                      PlanarPoseJacobian* jac_t) const {
  Vec2 p_t;
  *dpsi = spline_->planarPose(spline_->toSplineTime(t_ns), &p_t, jac_t) - ref.psi;
  return Eigen::Rotation2Dd(-ref.psi) * (p_t - ref.position);
}

namespace {
// d T_Cr_Ct / d(psi, x, y) of T_Cr_Ct = A^-1 T_Vr_Vt B with heading R_V (A, B: the camera's mounts
// at t_ref and t; both T_base_cam without a tilt): dR_C = R_A^T [z]x R_V R_B d psi,
// dp_C = R_A^T ([z]x R_V p_B d psi + (dx, dy, 0)).
PlanarLocalJacobian planarLocalJacobian(const Mat3& R_V, const Pose3& A, const Pose3& B) {
  const Mat3 R_at = A.linear().transpose();
  const Mat3 zR_V = skew(Vec3::UnitZ()) * R_V;
  PlanarLocalJacobian j;
  j.dR_dpsi = R_at * zR_V * B.linear();
  j.dt_dpsi = R_at * (zR_V * B.translation());
  j.dt_dx = R_at.col(0);
  j.dt_dy = R_at.col(1);
  return j;
}
}  // namespace

void BSplineCameraModel::setTilt(std::function<Mat3(int64_t)> tilt) {
  tilt_ = std::move(tilt);
  if (tilt_) mount_ref_ = tiltedMount(t_ref_ns_);
}

Pose3 BSplineCameraModel::tiltedMount(int64_t t_ns) const {
  const Mat3 R = tilt_(t_ns);
  return makePose(R * T_base_cam_.linear(), R * T_base_cam_.translation());
}

Pose3 BSplineCameraModel::T_Cr_Ct(int64_t t_ns, PoseJacobian* jac) const {
  Reference fresh;
  const Reference* ref = &reference(&fresh);
  PlanarPoseJacobian jac_t;
  double dpsi = 0.0;
  const Vec2 p_rel = relativePose(*ref, t_ns, &dpsi, jac ? &jac_t : nullptr);
  const Eigen::Rotation2Dd R_rT(-ref->psi);
  const Mat3 R_V = rotZ(dpsi);
  const Pose3 T_Vr_Vt = makePose(R_V, Vec3(p_rel.x(), p_rel.y(), 0.0));
  if (jac) {
    // d psi_rel = dpsi_t - dpsi_r,  d p_rel = R_r^T (dp_t - dp_r) - dpsi_r J p_rel (J: +90 deg).
    constexpr int kMax = 2 * PlanarPoseJacobian::kMaxParams;
    int index[kMax];
    double a[kMax];
    Vec2 b[kMax];
    int n = 0;
    auto slot = [&](int k) {
      for (int s = 0; s < n; ++s)
        if (index[s] == k) return s;
      index[n] = k;
      a[n] = 0.0;
      b[n] = Vec2::Zero();
      return n++;
    };
    for (int s = 0; s < jac_t.size; ++s) {
      const int q = slot(jac_t.index[s]);
      a[q] += jac_t.dpsi[s];
      b[q] += R_rT * jac_t.dp[s];
    }
    const Vec2 J_p_rel(-p_rel.y(), p_rel.x());
    for (int s = 0; s < ref->jac.size; ++s) {
      const int q = slot(ref->jac.index[s]);
      a[q] -= ref->jac.dpsi[s];
      b[q] -= R_rT * ref->jac.dp[s] + ref->jac.dpsi[s] * J_p_rel;
    }
    const PlanarLocalJacobian lj = tilt_ ? planarLocalJacobian(R_V, mount_ref_, tiltedMount(t_ns))
                                         : planarLocalJacobian(R_V, T_base_cam_, T_base_cam_);
    jac->clear();
    for (int s = 0; s < n; ++s)
      jac->add(index[s], a[s] * lj.dR_dpsi,
               a[s] * lj.dt_dpsi + lj.dt_dx * b[s].x() + lj.dt_dy * b[s].y());
  }
  if (tilt_) return Pose3(mount_ref_.inverse(Eigen::Isometry) * T_Vr_Vt * tiltedMount(t_ns));
  return vehicleToCamera(T_Vr_Vt, T_base_cam_);
}

Pose3 BSplineCameraModel::T_Cr_CtPlanar(int64_t t_ns, PlanarLocalJacobian* jac) const {
  Reference fresh;
  double dpsi = 0.0;
  const Vec2 p_rel = relativePose(reference(&fresh), t_ns, &dpsi, nullptr);
  const Mat3 R_V = rotZ(dpsi);
  const Pose3 T_V = makePose(R_V, Vec3(p_rel.x(), p_rel.y(), 0.0));
  if (tilt_) {
    const Pose3 B = tiltedMount(t_ns);
    if (jac) *jac = planarLocalJacobian(R_V, mount_ref_, B);
    return Pose3(mount_ref_.inverse(Eigen::Isometry) * T_V * B);
  }
  if (jac) *jac = planarLocalJacobian(R_V, T_base_cam_, T_base_cam_);
  return vehicleToCamera(T_V, T_base_cam_);
}

void BSplineCameraModel::addPlanarGradient(const std::vector<int64_t>& t_ns,
                                           const std::vector<Vec3>& g,
                                           Eigen::VectorXd* gradient) const {
  if (t_ns.size() != g.size())
    throw std::invalid_argument(
        "BSplineCameraModel::addPlanarGradient: " + std::to_string(t_ns.size()) + " times but " +
        std::to_string(g.size()) + " derivatives");
  if (gradient->size() != numParams())
    throw std::invalid_argument("BSplineCameraModel::addPlanarGradient: gradient of size " +
                                std::to_string(gradient->size()) + ", expected " +
                                std::to_string(numParams()));
  Reference fresh;
  const Reference& ref = reference(&fresh);
  // psi_rel = psi_t - psi_r and p_rel = R_r^T (p_t - p_r): the control points at t enter through
  // (psi_t, p_t); the reference's through -psi_r, -R_r^T p_r and -psi_r J p_rel, summed over rays.
  const Eigen::Rotation2Dd R_r(ref.psi);
  double G_psi = 0.0, H = 0.0;
  Vec2 G_p = Vec2::Zero();
  PlanarPoseJacobian jac_t;
  for (size_t i = 0; i < t_ns.size();) {
    // Rays of one time (a pose slice of the objective) share the pose: their sum is chained once.
    double g_psi = 0.0;
    Vec2 g_p = Vec2::Zero();
    const int64_t t = t_ns[i];
    for (; i < t_ns.size() && t_ns[i] == t; ++i) g_psi += g[i].x(), g_p += g[i].tail<2>();
    double dpsi = 0.0;
    const Vec2 p_rel = relativePose(ref, t, &dpsi, &jac_t);
    const Vec2 g_odom = R_r * g_p;  // g_p . (R_r^T dp) = (R_r g_p) . dp
    for (int s = 0; s < jac_t.size; ++s)
      (*gradient)[jac_t.index[s]] += g_psi * jac_t.dpsi[s] + g_odom.dot(jac_t.dp[s]);
    G_psi += g_psi;
    G_p += g_p;
    H += g_p.dot(Vec2(-p_rel.y(), p_rel.x()));
  }
  const Vec2 G_odom = R_r * G_p;
  for (int s = 0; s < ref.jac.size; ++s)
    (*gradient)[ref.jac.index[s]] -= ref.jac.dpsi[s] * (G_psi + H) + G_odom.dot(ref.jac.dp[s]);
}

}  // namespace vwe_vo
