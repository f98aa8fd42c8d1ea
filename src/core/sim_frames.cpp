#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "vwe_vo/core/sim/frame_simulator.h"

namespace vwe_vo {
namespace sim {

void FrameSimulatorOptions::validate() const {
  auto fail = [](const std::string& m) { throw std::invalid_argument("FrameSimulatorOptions." + m); };
  if (!(rate_hz > 0 && rate_hz <= 1000)) fail("rate_hz must be in (0, 1000] [Hz]");
  if (!(exposure_min_s > 0)) fail("exposure_min_s must be positive [s]");
  if (!(exposure_max_s >= exposure_min_s)) fail("exposure_max_s must be >= exposure_min_s [s]");
  if (!(exposure_max_s <= 1.0 / rate_hz)) fail("exposure_max_s must not exceed the frame period [s]");
  if (!(exposure_s >= exposure_min_s && exposure_s <= exposure_max_s))
    fail("exposure_s must be in [exposure_min_s, exposure_max_s] [s]");
  if (!(ae_target > 0 && ae_target < 1)) fail("ae_target must be in (0, 1)");
  if (!(ae_time_constant_s >= 0)) fail("ae_time_constant_s must be >= 0 [s]");
  if (!(saturation_exposure_s > 0)) fail("saturation_exposure_s must be positive [s]");
  if (!(full_well_e >= 1)) fail("full_well_e must be >= 1 [e-]");
  if (!(read_noise_dn >= 0)) fail("read_noise_dn must be >= 0 [DN]");
  if (!(fpn_dn >= 0)) fail("fpn_dn must be >= 0 [DN]");
  if (!(black_level_dn >= 0 && black_level_dn < 255)) fail("black_level_dn must be in [0, 255) [DN]");
  if (!(blur_step_s > 0)) fail("blur_step_s must be positive [s]");
  if (max_blur_renders < 1) fail("max_blur_renders must be >= 1");
}

FrameSimulator::FrameSimulator(EventSimulator* simulator, const FrameSimulatorOptions& options)
    : sim_(simulator), options_(options), exposure_s_(options.exposure_s), rng_(options.seed * 7919 + 3) {
  if (!sim_) throw std::invalid_argument("FrameSimulator: simulator is null");
  options_.validate();
  const CameraModel& cam = sim_->camera();
  fpn_.create(cam.height(), cam.width());
  std::normal_distribution<float> n01(0.f, 1.f);
  for (int y = 0; y < fpn_.rows; ++y)
    for (int x = 0; x < fpn_.cols; ++x) fpn_(y, x) = static_cast<float>(options_.fpn_dn) * n01(rng_);
}

SimulatedFrame FrameSimulator::renderWithExposure(int64_t t_ns, double exposure_s) {
  const CameraModel& cam = sim_->camera();
  const int64_t end_ns = sim_->trajectory().durationNs();
  // Exposure window centred on the stamp, kept inside the sequence.
  int64_t e0 = t_ns - secToNs(0.5 * exposure_s);
  int64_t e1 = t_ns + secToNs(0.5 * exposure_s);
  if (e0 < 0) e1 -= e0, e0 = 0;
  if (e1 > end_ns) e0 = std::max<int64_t>(0, e0 - (e1 - end_ns)), e1 = end_ns;
  const int n = std::clamp(static_cast<int>(std::ceil(exposure_s / options_.blur_step_s)), 1,
                           options_.max_blur_renders);
  cv::Mat1f irradiance = cv::Mat1f::zeros(cam.height(), cam.width());
  for (int k = 0; k < n; ++k) {
    const int64_t tk = e0 + static_cast<int64_t>((k + 0.5) / n * static_cast<double>(e1 - e0));
    irradiance += sim_->intensityImage(tk);  // includes the global illumination factor
  }
  irradiance *= 1.0 / n;

  SimulatedFrame f;
  f.t_ns = t_ns;
  f.exposure_s = exposure_s;
  f.image.create(cam.height(), cam.width());
  const double electrons_per_unit = exposure_s / options_.saturation_exposure_s * options_.full_well_e;
  const double dn_per_electron = 255.0 / options_.full_well_e;
  std::normal_distribution<double> n01(0.0, 1.0);
  size_t saturated = 0;
  for (int y = 0; y < f.image.rows; ++y)
    for (int x = 0; x < f.image.cols; ++x) {
      const double e = std::max(0.0, static_cast<double>(irradiance(y, x))) * electrons_per_unit;
      const double e_noisy = e + std::sqrt(e) * n01(rng_);  // shot noise (Gaussian approximation)
      const double dn = options_.black_level_dn + fpn_(y, x) + std::min(e_noisy, options_.full_well_e) * dn_per_electron +
                        options_.read_noise_dn * n01(rng_);
      const long q = std::lround(std::clamp(dn, 0.0, 255.0));
      f.image(y, x) = static_cast<uint8_t>(q);
      if (q >= 255) ++saturated;
    }
  f.saturated_fraction = static_cast<double>(saturated) / f.image.total();
  return f;
}

SimulatedFrame FrameSimulator::render(int64_t t_ns) { return renderWithExposure(t_ns, exposure_s_); }

std::vector<SimulatedFrame> FrameSimulator::simulateUntil(int64_t t_end_ns) {
  std::vector<SimulatedFrame> out;
  const double period_s = 1.0 / options_.rate_hz;
  while (true) {
    const int64_t t = secToNs(next_frame_index_ * period_s);
    if (t > t_end_ns || t > sim_->trajectory().durationNs()) break;
    out.push_back(renderWithExposure(t, exposure_s_));
    ++next_frame_index_;
    if (options_.auto_exposure) {
      // First-order lag in log exposure towards the exposure that would hit the target mean.
      const double mean = std::max(cv::mean(out.back().image)[0] - options_.black_level_dn, 0.5) / 255.0;
      const double wanted = exposure_s_ * options_.ae_target / mean;
      const double a = options_.ae_time_constant_s > 0 ? 1.0 - std::exp(-period_s / options_.ae_time_constant_s) : 1.0;
      exposure_s_ = std::exp(std::log(exposure_s_) + a * (std::log(wanted) - std::log(exposure_s_)));
      exposure_s_ = std::clamp(exposure_s_, options_.exposure_min_s, options_.exposure_max_s);
    }
  }
  return out;
}

}  // namespace sim
}  // namespace vwe_vo
