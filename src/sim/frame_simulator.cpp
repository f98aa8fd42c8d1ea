#include "vwe_vo/sim/frame_simulator.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

namespace vwe_vo {
namespace sim {

void FrameSimulatorOptions::validate() const {
  auto fail = [](const std::string& m) {
    throw std::invalid_argument("FrameSimulatorOptions." + m);
  };
  if (!(rate_hz > 0 && rate_hz <= 1000)) fail("rate_hz must be in (0, 1000] [Hz]");
  if (!(exposure_min_s > 0)) fail("exposure_min_s must be positive [s]");
  if (!(exposure_max_s >= exposure_min_s)) fail("exposure_max_s must be >= exposure_min_s [s]");
  if (!(exposure_max_s <= 1.0 / rate_hz))
    fail("exposure_max_s must not exceed the frame period [s]");
  if (!(exposure_s >= exposure_min_s && exposure_s <= exposure_max_s))
    fail("exposure_s must be in [exposure_min_s, exposure_max_s] [s]");
  if (!(ae_target > 0 && ae_target < 1)) fail("ae_target must be in (0, 1)");
  if (!(ae_trim_fraction >= 0 && ae_trim_fraction < 0.5))
    fail("ae_trim_fraction must be in [0, 0.5)");
  if (!(ae_time_constant_s >= 0)) fail("ae_time_constant_s must be >= 0 [s]");
  if (ae_delay_frames < 0 || ae_delay_frames > 10) fail("ae_delay_frames must be in [0, 10]");
  if (!(saturation_exposure_s > 0)) fail("saturation_exposure_s must be positive [s]");
  if (!(full_well_e >= 1)) fail("full_well_e must be >= 1 [e-]");
  if (!(read_noise_e >= 0)) fail("read_noise_e must be >= 0 [e-]");
  if (!(prnu >= 0 && prnu < 0.5)) fail("prnu must be in [0, 0.5)");
  if (!(dsnu_dn >= 0)) fail("dsnu_dn must be >= 0 [DN]");
  if (!(black_level_dn >= 0 && black_level_dn < 255))
    fail("black_level_dn must be in [0, 255) [DN]");
  if (!(blur_step_s > 0)) fail("blur_step_s must be positive [s]");
  if (max_blur_renders < 1) fail("max_blur_renders must be >= 1");
}

double FrameSimulatorOptions::dynamicRangeDb() const {
  return read_noise_e > 0 ? 20.0 * std::log10(full_well_e / read_noise_e) : INFINITY;
}

FrameSimulator::FrameSimulator(EventSimulator* simulator, const FrameSimulatorOptions& options)
    : sim_(simulator), options_(options), rng_(options.seed * 7919 + 3) {
  if (!sim_) throw std::invalid_argument("FrameSimulator: simulator is null");
  options_.validate();
  pending_exposures_.assign(options_.ae_delay_frames + 1, options_.exposure_s);
  const CameraModel& cam = sim_->camera();
  gain_.create(cam.height(), cam.width());
  offset_.create(cam.height(), cam.width());
  std::normal_distribution<float> n01(0.f, 1.f);
  for (int y = 0; y < gain_.rows; ++y)
    for (int x = 0; x < gain_.cols; ++x) {
      gain_(y, x) = std::max(0.f, 1.f + static_cast<float>(options_.prnu) * n01(rng_));
      offset_(y, x) = static_cast<float>(options_.black_level_dn + options_.dsnu_dn * n01(rng_));
    }
}

double FrameSimulator::meteredLevel(const cv::Mat1b& image) const {
  std::array<size_t, 256> hist{};
  for (int y = 0; y < image.rows; ++y) {
    const uint8_t* row = image.ptr<uint8_t>(y);
    for (int x = 0; x < image.cols; ++x) ++hist[row[x]];
  }
  const double n = static_cast<double>(image.total());
  const double lo = options_.ae_trim_fraction * n, hi = n - lo;  // keep ranks in [lo, hi)
  double rank = 0, sum = 0, kept = 0;
  for (int v = 0; v < 256; ++v) {
    const double a = std::max(rank, lo), b = std::min(rank + static_cast<double>(hist[v]), hi);
    if (b > a) sum += (b - a) * v, kept += b - a;
    rank += static_cast<double>(hist[v]);
  }
  const double mean = kept > 0 ? sum / kept : 0.0;
  return std::max(0.0, mean - options_.black_level_dn) / 255.0;
}

SimulatedFrame FrameSimulator::renderWithExposure(int64_t t_ns, double exposure_s) {
  const CameraModel& cam = sim_->camera();
  const int64_t end_ns = sim_->trajectory().durationNs();
  // Global shutter: the exposure window is centred on the stamp, kept inside the sequence, and
  // the irradiance (with the illumination of each instant) is averaged over it.
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
  // Electrons: white at full light fills the well in saturation_exposure_s. Output: the well maps
  // to 255 DN above the black level's offset, 8 bits, clipped.
  const double electrons_per_unit =
      exposure_s / options_.saturation_exposure_s * options_.full_well_e;
  const double dn_per_electron = 255.0 / options_.full_well_e;
  const double read_dn = options_.read_noise_e * dn_per_electron;
  std::normal_distribution<double> n01(0.0, 1.0);
  size_t saturated = 0;
  for (int y = 0; y < f.image.rows; ++y)
    for (int x = 0; x < f.image.cols; ++x) {
      const double e =
          std::max(0.0, static_cast<double>(irradiance(y, x) * gain_(y, x))) * electrons_per_unit;
      // Shot noise (Gaussian approximation of Poisson), then the well clips.
      const double e_noisy = std::clamp(e + std::sqrt(e) * n01(rng_), 0.0, options_.full_well_e);
      const double dn = offset_(y, x) + e_noisy * dn_per_electron + read_dn * n01(rng_);
      const long q = std::lround(std::clamp(dn, 0.0, 255.0));
      f.image(y, x) = static_cast<uint8_t>(q);
      if (q >= 255) ++saturated;
    }
  f.saturated_fraction = static_cast<double>(saturated) / f.image.total();
  return f;
}

SimulatedFrame FrameSimulator::render(int64_t t_ns) {
  return renderWithExposure(t_ns, exposure());
}

std::vector<SimulatedFrame> FrameSimulator::simulateUntil(int64_t t_end_ns) {
  std::vector<SimulatedFrame> out;
  const double period_s = 1.0 / options_.rate_hz;
  while (true) {
    const int64_t t = secToNs(next_frame_index_ * period_s);
    if (t > t_end_ns || t > sim_->trajectory().durationNs()) break;
    const double exposure_s = pending_exposures_.front();
    pending_exposures_.pop_front();
    out.push_back(renderWithExposure(t, exposure_s));
    ++next_frame_index_;
    double next = pending_exposures_.empty() ? exposure_s : pending_exposures_.back();
    if (options_.auto_exposure) {
      // The exposure that would have put this frame's metered level on target (saturation hides
      // how far off an over-exposed frame is, so recovery from it is slower), approached by a
      // first-order lag in log exposure from the latest setting; it takes effect
      // ae_delay_frames frames later (the next exposure has already started).
      const double level = std::max(meteredLevel(out.back().image), 0.5 / 255.0);
      const double wanted = exposure_s * options_.ae_target / level;
      const double a = options_.ae_time_constant_s > 0
                           ? 1.0 - std::exp(-period_s / options_.ae_time_constant_s)
                           : 1.0;
      next = std::exp(std::log(next) + a * (std::log(wanted) - std::log(next)));
      next = std::clamp(next, options_.exposure_min_s, options_.exposure_max_s);
    }
    pending_exposures_.push_back(next);
  }
  return out;
}

}  // namespace sim
}  // namespace vwe_vo
