// Procedural textures with natural-image statistics for the event simulator, precomputed once as
// images with a mip pyramid and sampled with (near-)trilinear filtering (so static edges do not
// flicker).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

namespace vwe_vo {
namespace sim {

/// What a texture looks like: the generator mixes ~1/f multi-scale noise with shapes.
enum class TextureStyle {
  kGeneric,  // noise + random rectangles, lines, blobs of many orientations and contrasts
  kPoster,   // high-contrast shapes and text-like bars (posters, whiteboards)
  kFloor,    // speckled vinyl / terrazzo: dense dark and light chips, tile seams, scuffs
  kCeiling,  // lower contrast noise with tile seams and scuffs (ceiling tiles, road markings)
  kFacade,   // brick-like noise with a grid of dark windows with frames
  kAsphalt,  // fine grain, cracks and patches
};

/// A square, power-of-two texture of *linear* intensity (reflectance, 1 = bright white) with its
/// mip pyramid. Coordinates are metres on the surface; the texture repeats.
class Texture {
 public:
  /// `image` is size x size (power of two) row-major linear intensity; texel_size_m its scale.
  Texture(int size, std::vector<float> image, float texel_size_m);

  /// Filtered lookup at surface position (u, v) [m] with a filter footprint [m] (the size of one
  /// sensor pixel on the surface): bilinear on the mip level of that footprint, blended with the
  /// next level only in the middle half of each octave (a continuous, cheaper trilinear filter).
  /// Footprints below one texel use the full-resolution level.
  inline float sample(float u_m, float v_m, float footprint_m) const;

  int size() const { return size_; }
  float texelSize() const { return texel_m_; }
  /// Level 0 (full resolution), row-major size x size.
  const std::vector<float>& level0() const { return levels_[0]; }

 private:
  // Bilinear lookup at level `level`, (u, v) in texels of that level (any sign: the texture wraps).
  inline float bilinear(int level, float u_texel, float v_texel) const;
  int size_;
  float texel_m_;
  float inv_texel_m_;
  std::vector<std::vector<float>> levels_;  // level l is (size >> l)^2
};

inline float Texture::bilinear(int level, float u_texel, float v_texel) const {
  const int s = size_ >> level;
  const int mask = s - 1;
  // Texel centres at +0.5. Floor by truncation and a correction (no libm call); the mask wraps
  // negative indices too (two's complement). Float keeps ~1e-3 texel at 2^14 texels from the
  // origin, far below what a sensor pixel resolves.
  const float fu = u_texel - 0.5f, fv = v_texel - 0.5f;
  int xi = static_cast<int>(fu), yi = static_cast<int>(fv);
  xi -= fu < static_cast<float>(xi);
  yi -= fv < static_cast<float>(yi);
  const float ax = fu - static_cast<float>(xi), ay = fv - static_cast<float>(yi);
  const int x0 = xi & mask, y0 = yi & mask;
  const int x1 = (x0 + 1) & mask, y1 = (y0 + 1) & mask;
  const float* r0 = levels_[level].data() + y0 * s;
  const float* r1 = levels_[level].data() + y1 * s;
  const float a = r0[x0] + ax * (r0[x1] - r0[x0]);
  const float b = r1[x0] + ax * (r1[x1] - r1[x0]);
  return a + ay * (b - a);
}

inline float Texture::sample(float u_m, float v_m, float footprint_m) const {
  const float ut = u_m * inv_texel_m_, vt = v_m * inv_texel_m_;
  const float ratio = footprint_m * inv_texel_m_;
  if (ratio <= 1.0f) return bilinear(0, ut, vt);
  // Fast log2: exponent plus a linear mantissa (continuous and monotonic, enough to blend levels).
  uint32_t bits;
  std::memcpy(&bits, &ratio, sizeof(bits));
  const int l0 = static_cast<int>((bits >> 23) & 0xff) - 127;
  uint32_t mbits = (bits & 0x007fffffu) | 0x3f800000u;
  float m;
  std::memcpy(&m, &mbits, sizeof(m));
  const int max_level = static_cast<int>(levels_.size()) - 1;
  if (l0 >= max_level) return levels_[max_level][0];
  // Blend weight 0 in the first quarter of the octave, 1 in the last: one bilinear lookup for
  // half of all footprints, still continuous in the footprint (no popping as depth changes).
  const float w = std::min(1.0f, std::max(0.0f, 2.0f * (m - 1.0f) - 0.5f));
  const float s0 = 1.0f / static_cast<float>(1 << l0);
  if (w <= 0.0f) return bilinear(l0, ut * s0, vt * s0);
  if (w >= 1.0f) return bilinear(l0 + 1, ut * (0.5f * s0), vt * (0.5f * s0));
  const float a = bilinear(l0, ut * s0, vt * s0);
  const float b = bilinear(l0 + 1, ut * (0.5f * s0), vt * (0.5f * s0));
  return a + w * (b - a);
}

/// Generates a texture of `size` x `size` texels (power of two) with natural-image statistics:
/// a sum of noise octaves with a ~1/f amplitude spectrum plus edges of many orientations and
/// contrasts. Linear intensity in about [0.04, 1] (a few stops), deterministic given the seed.
Texture makeTexture(TextureStyle style, int size, float texel_size_m, uint64_t seed);

}  // namespace sim
}  // namespace vwe_vo
