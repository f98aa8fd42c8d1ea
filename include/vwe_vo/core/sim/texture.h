// Procedural textures with natural-image statistics for the event simulator, precomputed once as
// images with a mip pyramid and sampled with trilinear filtering (so static edges do not flicker).
#pragma once

#include <cstdint>
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
  float sample(float u_m, float v_m, float footprint_m) const;

  int size() const { return size_; }
  float texelSize() const { return texel_m_; }
  /// Level 0 (full resolution), row-major size x size.
  const std::vector<float>& level0() const { return levels_[0]; }

 private:
  float bilinear(int level, float u_texel, float v_texel) const;
  int size_;
  float texel_m_;
  float inv_texel_m_;
  std::vector<std::vector<float>> levels_;  // level l is (size >> l)^2
};

/// Generates a texture of `size` x `size` texels (power of two) with natural-image statistics:
/// a sum of noise octaves with a ~1/f amplitude spectrum plus edges of many orientations and
/// contrasts. Linear intensity in about [0.04, 1] (a few stops), deterministic given the seed.
Texture makeTexture(TextureStyle style, int size, float texel_size_m, uint64_t seed);

}  // namespace sim
}  // namespace vwe_vo
