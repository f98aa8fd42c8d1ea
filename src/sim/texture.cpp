#include "vwe_vo/sim/texture.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <random>
#include <stdexcept>
#include <string>

namespace vwe_vo {
namespace sim {

namespace {
constexpr float kIndoorContrast =
    0.55f;  // log-contrast factor of the indoor texture styles but the floor [-]
constexpr int kFloorTexelsPerChip = 32;  // texture area per chip of the floor style [texels]
bool isPowerOfTwo(int n) {
  return n > 0 && (n & (n - 1)) == 0;
}
}  // namespace

Texture::Texture(int size, std::vector<float> image, float texel_size_m)
    : size_(size), texel_m_(texel_size_m), inv_texel_m_(1.0f / texel_size_m) {
  if (!isPowerOfTwo(size) || size < 2)
    throw std::invalid_argument("Texture: size must be a power of two, got " +
                                std::to_string(size));
  if (image.size() != static_cast<size_t>(size) * size)
    throw std::invalid_argument("Texture: image has " + std::to_string(image.size()) +
                                " texels, expected size^2");
  if (!(texel_size_m > 0)) throw std::invalid_argument("Texture: texel_size_m must be > 0");
  levels_.push_back(std::move(image));
  // Box-filtered pyramid down to 1x1; each level halves the resolution (the texture wraps).
  for (int s = size / 2; s >= 1; s /= 2) {
    const std::vector<float>& src = levels_.back();
    const int ss = s * 2;
    std::vector<float> dst(static_cast<size_t>(s) * s);
    for (int y = 0; y < s; ++y)
      for (int x = 0; x < s; ++x)
        dst[y * s + x] =
            0.25f * (src[(2 * y) * ss + 2 * x] + src[(2 * y) * ss + 2 * x + 1] +
                     src[(2 * y + 1) * ss + 2 * x] + src[(2 * y + 1) * ss + 2 * x + 1]);
    levels_.push_back(std::move(dst));
  }
}

namespace {

// Seamless (wrapping) band of noise: a random grid of `cells` x `cells` values, bicubically
// upsampled to size x size.
cv::Mat1f wrappedNoise(int size, int cells, std::mt19937_64& rng) {
  std::normal_distribution<float> n01(0.f, 1.f);
  cv::Mat1f grid(cells, cells);
  for (int y = 0; y < cells; ++y)
    for (int x = 0; x < cells; ++x) grid(y, x) = n01(rng);
  const int pad = 3;
  cv::Mat1f padded;
  cv::copyMakeBorder(grid, padded, pad, pad, pad, pad, cv::BORDER_WRAP);
  const int cell_px = size / cells;
  cv::Mat1f up;
  cv::resize(padded, up, cv::Size((cells + 2 * pad) * cell_px, (cells + 2 * pad) * cell_px), 0, 0,
             cv::INTER_CUBIC);
  // INTER_CUBIC samples the grid value at the centre of each upsampled cell: crop a whole period.
  return up(cv::Rect(pad * cell_px, pad * cell_px, size, size)).clone();
}

// Sum of octaves with amplitude ~ wavelength^beta (beta = 1 would be a 1/f amplitude spectrum
// for a 2-D image per octave band; a bit less keeps fine texture visible to the sensor).
cv::Mat1f multiScaleNoise(int size, int min_cells, float persistence, std::mt19937_64& rng) {
  cv::Mat1f sum = cv::Mat1f::zeros(size, size);
  float amp = 1.0f, total = 0.0f;
  for (int cells = min_cells; cells <= size / 2; cells *= 2) {
    sum += amp * wrappedNoise(size, cells, rng);
    total += amp * amp;
    amp *= persistence;
  }
  return sum / std::sqrt(total);  // unit standard deviation
}

/// The seams of an 8 x 8 grid of tiles (floor or ceiling), lines about 1/256 of the texture wide.
void drawTileSeams(cv::Mat1f& log2_img, int size, float level) {
  const int tile = size / 8, width = std::max(1, size / 256);
  for (int k = 0; k <= 8; ++k) {
    cv::line(log2_img, cv::Point(k * tile, 0), cv::Point(k * tile, size), cv::Scalar(level), width);
    cv::line(log2_img, cv::Point(0, k * tile), cv::Point(size, k * tile), cv::Scalar(level), width);
  }
}

void drawRandomShapes(cv::Mat1f& log2_img, int count, float level_lo, float level_hi,
                      float min_size, float max_size, std::mt19937_64& rng) {
  const int size = log2_img.rows;
  std::uniform_real_distribution<float> u01(0.f, 1.f);
  auto uni = [&](float a, float b) { return a + (b - a) * u01(rng); };
  for (int i = 0; i < count; ++i) {
    const float level = uni(level_lo, level_hi);
    const cv::Point2f c(uni(0, size), uni(0, size));
    // Sizes log-uniform: as many small shapes per octave as large ones (scale invariance).
    const float s = min_size * std::pow(max_size / min_size, u01(rng));
    const float angle = uni(0, 180);
    const int kind = static_cast<int>(u01(rng) * 4.0f);
    if (kind == 0 || kind == 3) {  // rotated rectangle
      cv::RotatedRect rr(c, cv::Size2f(s, s * uni(0.2f, 1.0f)), angle);
      cv::Point2f pts[4];
      rr.points(pts);
      std::vector<cv::Point> poly;
      for (auto& p : pts) poly.emplace_back(cvRound(p.x), cvRound(p.y));
      cv::fillConvexPoly(log2_img, poly, cv::Scalar(level));
    } else if (kind == 1) {  // line of random thickness
      const float a = angle * static_cast<float>(CV_PI / 180.0);
      const cv::Point2f d(std::cos(a) * s, std::sin(a) * s);
      cv::line(log2_img, c - d, c + d, cv::Scalar(level),
               std::max(1, static_cast<int>(s * uni(0.02f, 0.12f))));
    } else {  // blob (ellipse)
      cv::ellipse(
          log2_img, cv::Point(cvRound(c.x), cvRound(c.y)),
          cv::Size(std::max(1, cvRound(s * 0.5f)), std::max(1, cvRound(s * uni(0.15f, 0.5f)))),
          angle, 0, 360, cv::Scalar(level), cv::FILLED);
    }
  }
}

}  // namespace

Texture makeTexture(TextureStyle style, int size, float texel_size_m, uint64_t seed) {
  if (!isPowerOfTwo(size) || size < 16)
    throw std::invalid_argument("makeTexture: size must be a power of two >= 16");
  std::mt19937_64 rng(seed * 0x9E3779B97F4A7C15ULL + 12345);
  std::uniform_real_distribution<float> u01(0.f, 1.f);
  const float sz = static_cast<float>(size);
  // Work in log2 intensity (stops below white), then convert to linear.
  cv::Mat1f L(size, size, -1.0f);
  float noise_stops = 0.3f;
  switch (style) {
    case TextureStyle::kGeneric:
      L.setTo(-0.8f - 1.2f * u01(rng));
      drawRandomShapes(L, 150, -2.6f, -0.2f, sz * 0.015f, sz * 0.35f, rng);
      break;
    case TextureStyle::kPoster:
      L.setTo(-0.2f - 0.6f * u01(rng));
      drawRandomShapes(L, 120, -3.5f, 0.0f, sz * 0.02f, sz * 0.5f, rng);
      for (int i = 0; i < 40; ++i) {  // text-like horizontal bars
        const int x = static_cast<int>(u01(rng) * sz), y = static_cast<int>(u01(rng) * sz);
        cv::rectangle(L,
                      cv::Rect(x, y, static_cast<int>(sz * (0.05f + 0.25f * u01(rng))),
                               std::max(2, size / 80)),
                      cv::Scalar(-3.0f), cv::FILLED);
      }
      noise_stops = 0.25f;
      break;
    case TextureStyle::kFloor: {
      // One chip of 1-6 texels, dark or light, per kFloorTexelsPerChip texels: the fine,
      // high-contrast grain of a lab floor, which is what a low, forward-looking camera sees moving
      // fastest when driving straight.
      L.setTo(-1.4f);
      drawTileSeams(L, size, -2.3f);
      drawRandomShapes(L, 60, -2.3f, -0.8f, sz * 0.01f, sz * 0.1f, rng);  // scuffs and patches
      drawRandomShapes(L, size * size / kFloorTexelsPerChip, -3.0f, -0.3f, 1.0f, 6.0f, rng);
      noise_stops = 0.4f;
      break;
    }
    case TextureStyle::kCeiling: {
      L.setTo(-1.5f);
      drawTileSeams(L, size, -2.3f);
      drawRandomShapes(L, 80, -2.3f, -1.0f, sz * 0.005f, sz * 0.12f, rng);
      noise_stops = 0.3f;
      break;
    }
    case TextureStyle::kFacade: {
      L.setTo(-1.0f - 0.8f * u01(rng));
      drawRandomShapes(L, 60, -2.0f, -0.5f, sz * 0.01f, sz * 0.1f, rng);
      // Windows: bays of 3 m, storeys of 3 m, window 1.4 x 1.6 m with a light frame.
      const float bay = 3.0f / texel_size_m, storey = 3.0f / texel_size_m;
      for (float y = 0.5f * storey; y + storey * 0.5f <= sz; y += storey)
        for (float x = 0.3f * bay; x + bay * 0.5f <= sz; x += bay) {
          const int w = cvRound(1.4f / texel_size_m), h = cvRound(1.6f / texel_size_m);
          const int fr = std::max(1, cvRound(0.12f / texel_size_m));
          cv::rectangle(L, cv::Rect(cvRound(x) - fr, cvRound(y) - fr, w + 2 * fr, h + 2 * fr),
                        cv::Scalar(-0.3f), cv::FILLED);
          cv::rectangle(L, cv::Rect(cvRound(x), cvRound(y), w, h),
                        cv::Scalar(-2.8f - 0.8f * u01(rng)), cv::FILLED);
          cv::line(L, cv::Point(cvRound(x + w / 2), cvRound(y)),
                   cv::Point(cvRound(x + w / 2), cvRound(y + h)), cv::Scalar(-0.5f), fr);
        }
      noise_stops = 0.35f;
      break;
    }
    case TextureStyle::kAsphalt:
      L.setTo(-2.0f);
      drawRandomShapes(L, 80, -2.8f, -1.4f, sz * 0.01f, sz * 0.2f, rng);
      noise_stops = 0.4f;
      break;
  }
  L += noise_stops * multiScaleNoise(size, 4, 0.65f, rng);
  // Indoor surfaces (paint, paper, furniture, ceiling) under diffuse light: log contrast
  // compressed about the mean, which keeps the 1/f spectrum and every edge. The floor and the
  // street textures keep their full contrast.
  const bool full = style == TextureStyle::kFacade || style == TextureStyle::kAsphalt ||
                    style == TextureStyle::kFloor;
  const float contrast = full ? 1.0f : kIndoorContrast;
  if (contrast != 1.0f) {
    const float mean = static_cast<float>(cv::mean(L)[0]);
    L = mean + contrast * (L - mean);
  }
  std::vector<float> lin(static_cast<size_t>(size) * size);
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) lin[y * size + x] = std::clamp(std::exp2(L(y, x)), 0.03f, 1.0f);
  return Texture(size, std::move(lin), texel_size_m);
}

}  // namespace sim
}  // namespace vwe_vo
