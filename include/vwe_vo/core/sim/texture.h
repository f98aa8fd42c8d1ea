// Procedural textures with natural-image statistics for the event simulator, precomputed once as
// images with a mip pyramid and sampled with trilinear filtering (so static edges do not flicker).
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

namespace vwe_vo {
namespace sim {

/// What a texture looks like: the generator mixes ~1/f multi-scale noise with shapes.
enum class TextureStyle {
  kGeneric,   // noise + random rectangles, lines, blobs of many orientations and contrasts
  kPoster,    // high-contrast shapes and text-like bars (posters, whiteboards)
  kFloor,     // lower contrast noise with tile seams and scuffs
  kFacade,    // brick-like noise with a grid of dark windows with frames
  kAsphalt,   // fine grain, cracks and patches
};

/// A square, power-of-two texture of *linear* intensity (reflectance, 1 = bright white) with its
/// mip pyramid. Coordinates are metres on the surface; the texture repeats.
class Texture {
 public:
  /// `image` is size x size (power of two) row-major linear intensity; texel_size_m its scale.
  Texture(int size, std::vector<float> image, float texel_size_m);

  /// Trilinear lookup at surface position (u, v) [m] with a filter footprint [m] (the size of one
  /// sensor pixel on the surface). Footprints below one texel use the full-resolution level.
  inline float sample(float u_m, float v_m, float footprint_m) const;

  int size() const { return size_; }
  float texelSize() const { return texel_m_; }
  /// Level 0 (full resolution), row-major size x size.
  const std::vector<float>& level0() const { return levels_[0]; }

 private:
  // Bilinear lookup at level `level`, (u, v) in texels of that level, non-negative.
  inline float bilinear(int level, double u_texel, double v_texel) const;
  int size_;
  float texel_m_;
  float inv_texel_m_;
  std::vector<std::vector<float>> levels_;  // level l is (size >> l)^2
};

inline float Texture::bilinear(int level, double u_texel, double v_texel) const {
  const int s = size_ >> level;
  const int mask = s - 1;
  // Texel centres at +0.5; coordinates are kept positive by the caller so truncation is floor.
  const double fu = u_texel - 0.5 + s, fv = v_texel - 0.5 + s;
  const int64_t xi = static_cast<int64_t>(fu), yi = static_cast<int64_t>(fv);
  const float ax = static_cast<float>(fu - static_cast<double>(xi)), ay = static_cast<float>(fv - static_cast<double>(yi));
  const int x0 = static_cast<int>(xi) & mask, y0 = static_cast<int>(yi) & mask;
  const int x1 = (x0 + 1) & mask, y1 = (y0 + 1) & mask;
  const float* d = levels_[level].data();
  const float a = d[y0 * s + x0] + ax * (d[y0 * s + x1] - d[y0 * s + x0]);
  const float b = d[y1 * s + x0] + ax * (d[y1 * s + x1] - d[y1 * s + x0]);
  return a + ay * (b - a);
}

inline float Texture::sample(float u_m, float v_m, float footprint_m) const {
  // Level-0 texel coordinates, wrapped into [0, size) in double (world coordinates can be large
  // or negative; float would lose the sub-texel precision that keeps static edges still).
  const double period = static_cast<double>(size_);
  double ut = static_cast<double>(u_m) * inv_texel_m_, vt = static_cast<double>(v_m) * inv_texel_m_;
  ut -= period * std::floor(ut * (1.0 / period));
  vt -= period * std::floor(vt * (1.0 / period));
  const float ratio = footprint_m * inv_texel_m_;
  if (ratio <= 1.0f) return bilinear(0, ut, vt);
  // Fast log2: exponent plus a linear mantissa (continuous and monotonic, enough to blend levels).
  uint32_t bits;
  std::memcpy(&bits, &ratio, sizeof(bits));
  const int e = static_cast<int>((bits >> 23) & 0xff) - 127;
  uint32_t mbits = (bits & 0x007fffffu) | 0x3f800000u;
  float m;
  std::memcpy(&m, &mbits, sizeof(m));
  const int max_level = static_cast<int>(levels_.size()) - 1;
  const int l0 = e;
  if (l0 >= max_level) return levels_[max_level][0];
  const float f = m - 1.0f;
  const double s0 = 1.0 / static_cast<double>(1 << l0);
  const float a = bilinear(l0, ut * s0, vt * s0);
  const float b = bilinear(l0 + 1, ut * s0 * 0.5, vt * s0 * 0.5);
  return a + f * (b - a);
}

/// Generates a texture of `size` x `size` texels (power of two) with natural-image statistics:
/// a sum of noise octaves with a ~1/f amplitude spectrum plus edges of many orientations and
/// contrasts. Linear intensity in about [0.04, 1] (a few stops), deterministic given the seed.
Texture makeTexture(TextureStyle style, int size, float texel_size_m, uint64_t seed);

}  // namespace sim
}  // namespace vwe_vo
