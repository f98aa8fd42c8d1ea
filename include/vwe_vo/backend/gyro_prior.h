// The gyro's yaw rate as a back-end measurement: a SplinePrior with the yaw-rate bias estimated
// in the solve (profiled out in closed form under a Gaussian prior from the slow filter of the
// previous refinements), and that slow filter.
#pragma once

#include <algorithm>
#include <cstdint>
#include <memory>
#include <vector>

#include "vwe_vo/backend/backend.h"
#include "vwe_vo/trajectory/bspline.h"

namespace vwe_vo {

/// Over bins [a_k, b_k] of the window, the spline's mean yaw rate d_k = (psi(b_k) - psi(a_k)) /
/// (b_k - a_k) against the gyro's mean yaw rate m_k over the same bin less a bias b:
///   J = weight / K * [ sum_k ((d_k - m_k + b) / sigma_k)^2 + ((b - b0) / sigma_b)^2 ]
/// with sigma_k^2 = noise_density^2 / (b_k - a_k) + model_sigma^2 (white rate noise averaged over
/// the bin, and what the spline cannot follow within it) and b
/// minimising J for the current spline (closed form; by the envelope theorem the gradient is that
/// of J at the optimal b). Where the spline holds a standstill, d_k = 0 and the bin measures the
/// bias alone. A constant yaw-rate offset of the spline trades against b: what fixes it is the
/// VWE and the bias prior (b0, sigma_b).
class GyroRatePrior : public SplinePrior {
 public:
  struct Bin {
    double u_start, u_end;  // spline time [s]
    double rate;            // the gyro's mean yaw rate over the bin, bias not removed [rad/s]
  };
  /// Bins whose end the free control points do not reach, shorter than 1 ms, or with an end
  /// where the spline moves slower than min_speed_mps outside a standstill (the tangent's heading
  /// is not determined there; it flips by pi where the spline reverses) are left out.
  /// noise_density [rad/s/sqrt(Hz)], bias0, bias_sigma and model_sigma [rad/s].
  GyroRatePrior(std::shared_ptr<const BSpline> spline, int first_free, const std::vector<Bin>& bins,
                double weight, double noise_density, double bias0, double bias_sigma,
                double min_speed_mps = 0.05, double model_sigma = 0.0);
  double evaluate(Eigen::VectorXd* gradient) const override;
  size_t numBins() const { return bins_.size(); }
  /// The bias minimising J at the spline's current control points [rad/s].
  double bias() const;
  /// The bias the bins measure without the prior, robustly: where at least min_standstill_bins
  /// bins lie kStillMargin_s inside a held standstill, the median gyro rate there (the gyro alone
  /// measures the bias); otherwise the median of m_k - d_k [rad/s] (0 if none).
  double measuredBias(size_t min_standstill_bins = 4) const;
  /// Whether measuredBias() is a standstill's (the gyro alone).
  bool measuresStandstill(size_t min_standstill_bins = 4) const {
    return numStillBins() >= std::max<size_t>(1, min_standstill_bins);
  }
  /// The bins of measuredBias() [1].
  size_t measuredBiasBins(size_t min_standstill_bins = 4) const;
  /// The bins inside a held standstill.
  size_t numStandstillBins() const;
  /// The bins kStillMargin_s inside a held standstill: the held interval is made of whole
  /// front-end windows whose event rate fell, and its first and last may still move (one of
  /// indoor_drive's stops measured the bias 0.57 deg/s off in its first 0.2 s).
  size_t numStillBins() const;
  static constexpr double kStillMargin_s = 0.3;

 private:
  double meanRate(const Bin& bin, PlanarPoseJacobian* ja, PlanarPoseJacobian* jb) const;
  std::shared_ptr<const BSpline> spline_;
  int first_free_;
  std::vector<Bin> bins_;
  std::vector<double> inv_var_;   // 1 / sigma_k^2 [(rad/s)^-2]
  std::vector<bool> standstill_;  // the bin lies in a held standstill (d_k = 0)
  std::vector<bool> still_;       // ... by kStillMargin_s (measuredBias)
  double weight_, bias0_, bias_inv_var_;
};

/// Slow filter of the yaw-rate bias measured on each refined window (GyroRatePrior::
/// measuredBias), weighted by information: it starts from a prior at 0 with spread sigma0, its
/// information decays with time constant tau (exp(-dt / tau)) and each measurement adds
/// 1 / sigma_m^2. Its spread for the next solve's bias prior is 1 / sqrt(information), at least
/// sigma_min. After the first three, a measurement further than max_jump from the estimate is
/// refused (a refinement gone wrong) and counted. A measurement whose innovation r exceeds
/// huber_k times its spread sqrt(sigma_m^2 + sigma()^2) keeps only huber_k * spread / |r| of
/// its weight (Huber; 0: off): the street's facades pull runs of windows by 1-2 deg/s one way,
/// and refusing them (a max_jump of one window spread) biased the mean by 0.2 deg/s.
class GyroBiasFilter {
 public:
  GyroBiasFilter(double tau_s, double sigma0, double sigma_min, double max_jump,
                 double huber_k = 0.0)
      : tau_s_(tau_s),
        sigma_min_(sigma_min),
        max_jump_(max_jump),
        huber_k_(huber_k),
        info_(1.0 / (sigma0 * sigma0)) {}
  /// sigma_m: the measurement's spread [rad/s]. False if refused.
  bool add(double measured_bias, double dt_s, double sigma_m);
  size_t refused() const { return refused_; }
  double bias() const { return bias_; }
  double sigma() const;
  size_t count() const { return n_; }

 private:
  double tau_s_, sigma_min_, max_jump_, huber_k_;
  double info_;  // [(rad/s)^-2]
  double bias_ = 0.0;
  size_t n_ = 0, refused_ = 0;
};

}  // namespace vwe_vo
