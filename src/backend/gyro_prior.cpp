#include "vwe_vo/backend/gyro_prior.h"

#include <algorithm>
#include <cmath>

namespace vwe_vo {

GyroRatePrior::GyroRatePrior(std::shared_ptr<const BSpline> spline, int first_free,
                             const std::vector<Bin>& bins, double weight, double noise_density,
                             double bias0, double bias_sigma, double min_speed_mps,
                             double model_sigma)
    : spline_(std::move(spline)),
      first_free_(first_free),
      weight_(weight),
      bias0_(bias0),
      bias_inv_var_(1.0 / (bias_sigma * bias_sigma)) {
  for (const Bin& b : bins) {
    const double dt = b.u_end - b.u_start;
    if (!(dt >= 1e-3) || !std::isfinite(b.rate)) continue;
    if (spline_->basis(b.u_end, 0).first + spline_->degree() < first_free_) continue;
    auto slow = [&](double u) {
      return !spline_->standstillAt(u) && !(spline_->velocity(u).norm() >= min_speed_mps);
    };
    if (slow(b.u_start) || slow(b.u_end)) continue;
    bins_.push_back(b);
    inv_var_.push_back(1.0 / (noise_density * noise_density / dt + model_sigma * model_sigma));
    standstill_.push_back(spline_->standstillAt(b.u_start) && spline_->standstillAt(b.u_end));
    still_.push_back(spline_->standstillAt(b.u_start - kStillMargin_s) &&
                     spline_->standstillAt(b.u_end + kStillMargin_s));
  }
}

double GyroRatePrior::meanRate(const Bin& bin, PlanarPoseJacobian* ja,
                               PlanarPoseJacobian* jb) const {
  Vec2 c;
  const double psi_a = spline_->planarPose(bin.u_start, &c, ja);
  const double psi_b = spline_->planarPose(bin.u_end, &c, jb);
  return wrapAngle(psi_b - psi_a) / (bin.u_end - bin.u_start);
}

size_t GyroRatePrior::numStandstillBins() const {
  return size_t(std::count(standstill_.begin(), standstill_.end(), true));
}

size_t GyroRatePrior::numStillBins() const {
  return size_t(std::count(still_.begin(), still_.end(), true));
}

size_t GyroRatePrior::measuredBiasBins(size_t min_standstill_bins) const {
  return measuresStandstill(min_standstill_bins) ? numStillBins() : bins_.size();
}

double GyroRatePrior::measuredBias(size_t min_standstill_bins) const {
  const bool still = measuresStandstill(min_standstill_bins);
  std::vector<double> r;
  for (size_t k = 0; k < bins_.size(); ++k)
    if (still && still_[k]) r.push_back(bins_[k].rate);
  if (r.empty())
    for (const Bin& b : bins_) r.push_back(b.rate - meanRate(b, nullptr, nullptr));
  if (r.empty()) return 0.0;
  const size_t h = r.size() / 2;
  std::nth_element(r.begin(), r.begin() + long(h), r.end());
  if (r.size() % 2) return r[h];
  return 0.5 * (r[h] + *std::max_element(r.begin(), r.begin() + long(h)));
}

double GyroRatePrior::bias() const {
  double num = bias_inv_var_ * bias0_, den = bias_inv_var_;
  for (size_t k = 0; k < bins_.size(); ++k) {
    num += inv_var_[k] * (bins_[k].rate - meanRate(bins_[k], nullptr, nullptr));
    den += inv_var_[k];
  }
  return num / den;
}

double GyroRatePrior::evaluate(Eigen::VectorXd* gradient) const {
  const int num_free = 2 * (spline_->numControlPoints() - first_free_);
  if (gradient) gradient->setZero(num_free);
  if (bins_.empty() || weight_ == 0.0) return 0.0;
  const size_t n = bins_.size();
  std::vector<double> d(n);
  std::vector<PlanarPoseJacobian> ja(gradient ? n : 0), jb(gradient ? n : 0);
  double num = bias_inv_var_ * bias0_, den = bias_inv_var_;
  for (size_t k = 0; k < n; ++k) {
    d[k] = meanRate(bins_[k], gradient ? &ja[k] : nullptr, gradient ? &jb[k] : nullptr);
    num += inv_var_[k] * (bins_[k].rate - d[k]);
    den += inv_var_[k];
  }
  const double b = num / den;
  const double w = weight_ / double(n);
  double f = w * bias_inv_var_ * (b - bias0_) * (b - bias0_);
  for (size_t k = 0; k < n; ++k) {
    const double r = d[k] - bins_[k].rate + b;
    f += w * inv_var_[k] * r * r;
    if (!gradient) continue;
    // dJ/dtheta at the optimal b (dJ/db = 0 there).
    const double g = 2 * w * inv_var_[k] * r / (bins_[k].u_end - bins_[k].u_start);
    auto add = [&](const PlanarPoseJacobian& j, double sign) {
      for (int i = 0; i < j.size; ++i) {
        const int p = j.index[i] - 2 * first_free_;
        if (p >= 0) (*gradient)[p] += sign * g * j.dpsi[i];
      }
    };
    add(jb[k], 1.0);
    add(ja[k], -1.0);
  }
  return f;
}

bool GyroBiasFilter::add(double measured_bias, double dt_s, double sigma_m) {
  if (!std::isfinite(measured_bias) || !(sigma_m > 0) ||
      (n_ >= 3 && std::abs(measured_bias - bias_) > max_jump_)) {
    ++refused_;
    return false;
  }
  ++n_;
  const double r = std::abs(measured_bias - bias_);
  const double spread = std::sqrt(sigma_m * sigma_m + 1.0 / info_);
  info_ *= std::exp(-std::max(0.0, dt_s) / tau_s_);
  double w = 1.0 / (sigma_m * sigma_m);
  if (huber_k_ > 0 && r > huber_k_ * spread) w *= huber_k_ * spread / r;
  info_ += w;
  bias_ += w / info_ * (measured_bias - bias_);
  return true;
}

double GyroBiasFilter::sigma() const {
  return std::max(sigma_min_, 1.0 / std::sqrt(info_));
}

}  // namespace vwe_vo
