#include "vwe_vo/sim/scene.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <stdexcept>

#include "vwe_vo/sim/vehicle_trajectory.h"

namespace vwe_vo {
namespace sim {

namespace {
// Surface axes (u, v) of a face with normal `axis`: v is z on vertical faces.
inline int uAxis(int axis) {
  return axis == 0 ? 1 : 0;
}
inline int vAxis(int axis) {
  return axis == 2 ? 1 : 2;
}
}  // namespace

size_t Scene::addRect(int axis, float plane, Eigen::Vector2f lo, Eigen::Vector2f hi, int texture,
                      float gain, uint64_t seed) {
  if (axis < 0 || axis > 2) throw std::invalid_argument("Scene::addRect: axis must be 0, 1 or 2");
  if (texture < 0 || texture >= static_cast<int>(textures.size()))
    throw std::invalid_argument("Scene::addRect: bad texture index");
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> off(0.f, 50.f);
  Face f;
  f.axis = axis;
  f.plane = plane;
  f.lo[0] = std::min(lo.x(), hi.x());
  f.lo[1] = std::min(lo.y(), hi.y());
  f.hi[0] = std::max(lo.x(), hi.x());
  f.hi[1] = std::max(lo.y(), hi.y());
  f.texture = texture;
  f.offset[0] = off(rng);
  f.offset[1] = off(rng);
  f.gain = gain;
  faces.push_back(f);
  return faces.size() - 1;
}

size_t Scene::addBox(const Eigen::Vector3f& mn, const Eigen::Vector3f& mx, int texture, float gain,
                     uint64_t seed) {
  const size_t first = faces.size();
  // Side faces get slightly different gains (light from above and one side).
  const float side_gain[2][3] = {{0.85f, 0.75f, 0.6f}, {0.95f, 0.9f, 1.0f}};
  for (int axis = 0; axis < 3; ++axis) {
    const int ua = uAxis(axis), va = vAxis(axis);
    for (int side = 0; side < 2; ++side) {
      if (axis == 2 && side == 0) continue;  // bottom never seen
      const float plane = side ? mx[axis] : mn[axis];
      const size_t f =
          addRect(axis, plane, Eigen::Vector2f(mn[ua], mn[va]), Eigen::Vector2f(mx[ua], mx[va]),
                  texture, gain * side_gain[side][axis], seed * 7 + axis * 2 + side);
      faces[f].facing = side ? 1 : -1;
    }
  }
  return first;
}

std::vector<std::string> sceneKinds() {
  return {"indoor", "corridor", "street"};
}

namespace {

struct PathSamples {
  std::vector<Vec3> xyyaw;
  Eigen::AlignedBox2d bbox;
  std::vector<Vec3> clear;  // samples of a vehicle path that the layout path does not follow
  explicit PathSamples(const VehicleTrajectory& path, const VehicleTrajectory* vehicle = nullptr) {
    const int64_t step = 20000000;  // 20 ms
    for (int64_t t = 0; t <= path.durationNs(); t += step) xyyaw.push_back(path.planar(t));
    xyyaw.push_back(path.planar(path.durationNs()));
    for (const auto& p : xyyaw) bbox.extend(p.head<2>());
    if (vehicle)
      for (int64_t t = 0; t <= vehicle->durationNs(); t += step)
        clear.push_back(vehicle->planar(t));
  }
  // Distance from the planar box [mn, mx] to the nearest sample of either path [m].
  double distance(const Eigen::Vector2d& mn, const Eigen::Vector2d& mx) const {
    double best = std::numeric_limits<double>::infinity();
    for (const auto* samples : {&xyyaw, &clear})
      for (const auto& p : *samples) {
        const double dx = std::max({mn.x() - p.x(), 0.0, p.x() - mx.x()});
        const double dy = std::max({mn.y() - p.y(), 0.0, p.y() - mx.y()});
        best = std::min(best, std::hypot(dx, dy));
      }
    return best;
  }
};

bool overlaps(const std::vector<Eigen::AlignedBox2d>& boxes, const Eigen::AlignedBox2d& b,
              double gap) {
  Eigen::AlignedBox2d g(b.min() - Eigen::Vector2d::Constant(gap),
                        b.max() + Eigen::Vector2d::Constant(gap));
  for (const auto& o : boxes)
    if (g.intersects(o)) return true;
  return false;
}

using V3 = Eigen::Vector3f;
using V2 = Eigen::Vector2f;

int addTexture(Scene& s, TextureStyle style, int size, float texel, uint64_t seed) {
  s.textures.push_back(std::make_shared<Texture>(makeTexture(style, size, texel, seed)));
  return static_cast<int>(s.textures.size()) - 1;
}

// Posters / doors / boards on a wall: rectangles 1 cm in front of wall `axis` = plane, facing
// `inward`.
void addWallDecor(Scene& s, std::mt19937_64& rng, int axis, float plane, float inward, float u0,
                  float u1, int count, const std::vector<int>& textures, float z_max) {
  std::uniform_real_distribution<float> u01(0.f, 1.f);
  for (int i = 0; i < count; ++i) {
    const float w = 0.5f + 1.3f * u01(rng), h = 0.5f + 1.0f * u01(rng);
    const float cu = u0 + 0.5f * w + (u1 - u0 - w) * u01(rng);
    const float cz = std::min(z_max - 0.5f * h - 0.1f, 0.9f + 1.2f * u01(rng));
    const int tex = textures[static_cast<size_t>(u01(rng) * textures.size()) % textures.size()];
    s.addRect(axis, plane + inward * 0.01f, V2(cu - 0.5f * w, cz - 0.5f * h),
              V2(cu + 0.5f * w, cz + 0.5f * h), tex, 0.8f + 0.3f * u01(rng), rng());
  }
}

Scene buildIndoor(uint64_t seed, const PathSamples& path) {
  Scene s;
  s.name = "indoor";
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u01(0.f, 1.f);
  const int t_wall = addTexture(s, TextureStyle::kGeneric, 512, 0.012f, rng());
  const int t_floor = addTexture(s, TextureStyle::kFloor, 512, 0.01f, rng());
  const int t_poster1 = addTexture(s, TextureStyle::kPoster, 256, 0.006f, rng());
  const int t_poster2 = addTexture(s, TextureStyle::kPoster, 256, 0.005f, rng());
  const int t_box1 = addTexture(s, TextureStyle::kGeneric, 256, 0.008f, rng());
  const int t_box2 = addTexture(s, TextureStyle::kGeneric, 256, 0.006f, rng());
  const int t_ceil = addTexture(s, TextureStyle::kCeiling, 256, 0.02f, rng());
  const Eigen::Vector2d c = path.bbox.center();
  const Eigen::Vector2d half_path = 0.5 * path.bbox.sizes();
  const float hx = static_cast<float>(std::max(5.0, half_path.x() + 3.5) + 0.4 * u01(rng));
  const float hy = static_cast<float>(std::max(4.0, half_path.y() + 3.5) + 0.4 * u01(rng));
  const float x0 = static_cast<float>(c.x()) - hx, x1 = static_cast<float>(c.x()) + hx;
  const float y0 = static_cast<float>(c.y()) - hy, y1 = static_cast<float>(c.y()) + hy;
  const float zc = 2.8f;
  s.addRect(2, 0.f, V2(x0, y0), V2(x1, y1), t_floor, 0.8f, rng());
  s.addRect(2, zc, V2(x0, y0), V2(x1, y1), t_ceil, 0.55f, rng());
  s.addRect(0, x0, V2(y0, 0), V2(y1, zc), t_wall, 0.9f, rng());
  s.addRect(0, x1, V2(y0, 0), V2(y1, zc), t_wall, 0.8f, rng());
  s.addRect(1, y0, V2(x0, 0), V2(x1, zc), t_wall, 0.95f, rng());
  s.addRect(1, y1, V2(x0, 0), V2(x1, zc), t_wall, 0.75f, rng());
  const std::vector<int> posters{t_poster1, t_poster2};
  addWallDecor(s, rng, 0, x0, +1, y0, y1, 5, posters, zc);
  addWallDecor(s, rng, 0, x1, -1, y0, y1, 5, posters, zc);
  addWallDecor(s, rng, 1, y0, +1, x0, x1, 6, posters, zc);
  addWallDecor(s, rng, 1, y1, -1, x0, x1, 6, posters, zc);
  // Furniture: boxes, cabinets, tables (as blocks), 0.5-5 m from the path.
  std::vector<Eigen::AlignedBox2d> placed;
  int n_ok = 0;
  for (int attempt = 0; attempt < 4000 && n_ok < 26; ++attempt) {
    const int kind = static_cast<int>(u01(rng) * 3);
    Eigen::Vector3f size;
    if (kind == 0)
      size = V3(0.3f + 0.6f * u01(rng), 0.3f + 0.6f * u01(rng), 0.25f + 0.6f * u01(rng));  // boxes
    else if (kind == 1)
      size =
          V3(0.4f + 0.8f * u01(rng), 0.4f + 1.2f * u01(rng), 1.2f + 0.9f * u01(rng));  // cabinets
    else
      size = V3(0.8f + 1.0f * u01(rng), 0.6f + 0.6f * u01(rng),
                0.7f + 0.1f * u01(rng));  // tables / desks
    const float px = x0 + 0.05f + (2 * hx - size.x() - 0.1f) * u01(rng);
    const float py = y0 + 0.05f + (2 * hy - size.y() - 0.1f) * u01(rng);
    const Eigen::AlignedBox2d b(Eigen::Vector2d(px, py),
                                Eigen::Vector2d(px + size.x(), py + size.y()));
    const double d = path.distance(b.min(), b.max());
    if (d < 0.5 || d > 5.0 || overlaps(placed, b, 0.1)) continue;
    placed.push_back(b);
    s.addBox(V3(px, py, 0), V3(px + size.x(), py + size.y(), size.z()),
             u01(rng) < 0.5f ? t_box1 : t_box2, 0.6f + 0.4f * u01(rng), rng());
    ++n_ok;
  }
  return s;
}

Scene buildCorridor(uint64_t seed, const PathSamples& path) {
  Scene s;
  s.name = "corridor";
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u01(0.f, 1.f);
  const int t_wall = addTexture(s, TextureStyle::kGeneric, 512, 0.012f, rng());
  const int t_floor = addTexture(s, TextureStyle::kFloor, 512, 0.01f, rng());
  const int t_poster = addTexture(s, TextureStyle::kPoster, 256, 0.006f, rng());
  const int t_door = addTexture(s, TextureStyle::kGeneric, 256, 0.004f, rng());
  const int t_box = addTexture(s, TextureStyle::kGeneric, 256, 0.008f, rng());
  const int t_ceil = addTexture(s, TextureStyle::kCeiling, 256, 0.02f, rng());
  // The corridor runs along x around the path's bounding box.
  const float x0 = static_cast<float>(path.bbox.min().x()) - 4.f,
              x1 = static_cast<float>(path.bbox.max().x()) + 4.f;
  const float yc = static_cast<float>(path.bbox.center().y());
  const float hw = static_cast<float>(std::max(1.2, 0.5 * path.bbox.sizes().y() + 1.0));
  const float y0 = yc - hw, y1 = yc + hw, zc = 2.6f;
  s.addRect(2, 0.f, V2(x0, y0), V2(x1, y1), t_floor, 0.8f, rng());
  s.addRect(2, zc, V2(x0, y0), V2(x1, y1), t_ceil, 0.55f, rng());
  s.addRect(1, y0, V2(x0, 0), V2(x1, zc), t_wall, 0.9f, rng());
  s.addRect(1, y1, V2(x0, 0), V2(x1, zc), t_wall, 0.75f, rng());
  s.addRect(0, x0, V2(y0, 0), V2(y1, zc), t_wall, 0.85f, rng());
  s.addRect(0, x1, V2(y0, 0), V2(y1, zc), t_wall, 0.85f, rng());
  const int n = static_cast<int>((x1 - x0) / 3.0f);
  for (int wall = 0; wall < 2; ++wall) {
    const float plane = wall ? y1 - 0.01f : y0 + 0.01f;
    for (int i = 0; i < n; ++i) {
      const float cx = x0 + 1.5f + 3.0f * i + 0.8f * (u01(rng) - 0.5f);
      if (u01(rng) < 0.4f)  // door
        s.addRect(1, plane, V2(cx - 0.45f, 0.f), V2(cx + 0.45f, 2.05f), t_door,
                  0.35f + 0.3f * u01(rng), rng());
      else if (u01(rng) < 0.7f) {  // poster
        const float w = 0.5f + 0.8f * u01(rng), h = 0.5f + 0.6f * u01(rng),
                    cz = 1.2f + 0.6f * u01(rng);
        s.addRect(1, plane, V2(cx - w / 2, cz - h / 2), V2(cx + w / 2, cz + h / 2), t_poster, 0.9f,
                  rng());
      }
    }
  }
  std::vector<Eigen::AlignedBox2d> placed;
  for (int attempt = 0, ok = 0; attempt < 2000 && ok < 8; ++attempt) {
    const V3 size(0.3f + 0.5f * u01(rng), 0.25f + 0.3f * u01(rng), 0.3f + 1.0f * u01(rng));
    const float px = x0 + (x1 - x0 - size.x()) * u01(rng);
    const float py = u01(rng) < 0.5f ? y0 + 0.02f : y1 - 0.02f - size.y();
    const Eigen::AlignedBox2d b(Eigen::Vector2d(px, py),
                                Eigen::Vector2d(px + size.x(), py + size.y()));
    if (path.distance(b.min(), b.max()) < 0.5 || overlaps(placed, b, 0.2)) continue;
    placed.push_back(b);
    s.addBox(V3(px, py, 0), V3(px + size.x(), py + size.y(), size.z()), t_box,
             0.6f + 0.4f * u01(rng), rng());
    ++ok;
  }
  return s;
}

Scene buildStreet(uint64_t seed, const PathSamples& path) {
  Scene s;
  s.name = "street";
  s.sky_intensity = 0.9f;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u01(0.f, 1.f);
  const int t_facade1 = addTexture(s, TextureStyle::kFacade, 512, 0.05f, rng());
  const int t_facade2 = addTexture(s, TextureStyle::kFacade, 512, 0.04f, rng());
  const int t_road = addTexture(s, TextureStyle::kAsphalt, 1024, 0.01f, rng());
  const int t_car = addTexture(s, TextureStyle::kGeneric, 256, 0.01f, rng());
  const int t_pole = addTexture(s, TextureStyle::kGeneric, 128, 0.01f, rng());
  const int t_mark = addTexture(s, TextureStyle::kCeiling, 64, 0.05f, rng());
  const Eigen::Vector2d bmin = path.bbox.min() - Eigen::Vector2d(60, 60),
                        bmax = path.bbox.max() + Eigen::Vector2d(60, 60);
  s.addRect(2, 0.f, V2(bmin.x(), bmin.y()), V2(bmax.x(), bmax.y()), t_road, 0.7f, rng());
  std::vector<Eigen::AlignedBox2d> buildings, small;
  double last_mark = -1e9;
  double along = 0.0;
  for (size_t i = 0; i < path.xyyaw.size(); ++i) {
    const Vec3& p = path.xyyaw[i];
    if (i > 0) along += (p - path.xyyaw[i - 1]).head<2>().norm();
    // Only along axis-aligned stretches (the scene is axis-aligned).
    const double q = p.z() / (kPi / 2);
    const double snapped = std::round(q);
    if (std::abs(q - snapped) > 0.03) continue;
    const double yaw = snapped * kPi / 2;
    const Eigen::Vector2d fwd(std::round(std::cos(yaw)), std::round(std::sin(yaw)));
    const Eigen::Vector2d left(-fwd.y(), fwd.x());
    auto footprint = [&](double a0, double a1, double l0, double l1) {
      Eigen::AlignedBox2d b;
      b.extend(p.head<2>() + a0 * fwd + l0 * left);
      b.extend(p.head<2>() + a1 * fwd + l1 * left);
      return b;
    };
    for (int side = -1; side <= 1; side += 2) {
      // Building: front 5-8 m from the road centre.
      const double d = 5.0 + 3.0 * u01(rng), len = 6.0 + 10.0 * u01(rng),
                   depth = 8.0 + 6.0 * u01(rng);
      const Eigen::AlignedBox2d b = footprint(-0.5 * len, 0.5 * len, side * d, side * (d + depth));
      if (path.distance(b.min(), b.max()) >= 4.8 && !overlaps(buildings, b, 0.3)) {
        buildings.push_back(b);
        const float h = 6.f + 16.f * u01(rng);
        s.addBox(V3(b.min().x(), b.min().y(), 0), V3(b.max().x(), b.max().y(), h),
                 u01(rng) < 0.5f ? t_facade1 : t_facade2, 0.6f + 0.4f * u01(rng), rng());
      }
      if (u01(rng) < 0.12f) {  // pole
        const double lat = 3.6 + 0.6 * u01(rng);
        const Eigen::AlignedBox2d pb = footprint(-0.07, 0.07, side * lat, side * (lat + 0.14));
        if (path.distance(pb.min(), pb.max()) >= 3.0 && !overlaps(small, pb, 1.0)) {
          small.push_back(pb);
          s.addBox(V3(pb.min().x(), pb.min().y(), 0),
                   V3(pb.max().x(), pb.max().y(), 4.f + 3.f * u01(rng)), t_pole,
                   0.4f + 0.4f * u01(rng), rng());
        }
      }
      if (u01(rng) < 0.1f) {  // parked car: body and cabin
        const double lat = 2.6 + 0.5 * u01(rng);
        const Eigen::AlignedBox2d cb = footprint(-2.1, 2.1, side * lat, side * (lat + 1.8));
        if (path.distance(cb.min(), cb.max()) >= 2.0 && !overlaps(small, cb, 0.8)) {
          small.push_back(cb);
          const float g = 0.3f + 0.7f * u01(rng);
          s.addBox(V3(cb.min().x(), cb.min().y(), 0.15f), V3(cb.max().x(), cb.max().y(), 0.9f),
                   t_car, g, rng());
          const Eigen::Vector2d shrink =
              0.5 *
              (cb.sizes() - Eigen::Vector2d(std::abs(fwd.x()) * 2.2 + std::abs(fwd.y()) * 1.5,
                                            std::abs(fwd.y()) * 2.2 + std::abs(fwd.x()) * 1.5));
          s.addBox(V3(cb.min().x() + shrink.x(), cb.min().y() + shrink.y(), 0.9f),
                   V3(cb.max().x() - shrink.x(), cb.max().y() - shrink.y(), 1.45f), t_car, 0.5f * g,
                   rng());
        }
      }
    }
    // Dashed centre line: 3 m dashes every 9 m.
    if (along - last_mark >= 9.0) {
      last_mark = along;
      const Eigen::AlignedBox2d m = footprint(0.0, 3.0, -0.07, 0.07);
      s.addRect(2, 0.005f, V2(m.min().x(), m.min().y()), V2(m.max().x(), m.max().y()), t_mark, 2.5f,
                rng());
    }
  }
  return s;
}

}  // namespace

Scene buildScene(const std::string& kind, uint64_t seed, const VehicleTrajectory& path,
                 const VehicleTrajectory* vehicle) {
  const PathSamples samples(path, vehicle);
  if (kind == "indoor") return buildIndoor(seed, samples);
  if (kind == "corridor") return buildCorridor(seed, samples);
  if (kind == "street") return buildStreet(seed, samples);
  std::string valid;
  for (const auto& k : sceneKinds()) valid += (valid.empty() ? "" : ", ") + k;
  throw std::invalid_argument("unknown scene kind '" + kind + "' (valid: " + valid + ")");
}

// ---------------------------------------------------------------------------------------------

SceneRenderer::SceneRenderer(const Scene& scene, const CameraModel& camera, int supersampling)
    : scene_(scene),
      camera_(camera),
      ss_(supersampling),
      width_(camera.width()),
      height_(camera.height()) {
  if (ss_ < 1 || ss_ > 4)
    throw std::invalid_argument("SceneRenderer: supersampling must be in [1, 4]");
  for (const auto& t : scene.textures)
    if (!t) throw std::invalid_argument("SceneRenderer: null texture");
  for (const auto& f : scene.faces)
    if (f.texture < 0 || f.texture >= static_cast<int>(scene.textures.size()))
      throw std::invalid_argument("SceneRenderer: face with bad texture index");
  tiles_x_ = (width_ + kTile - 1) / kTile;
  tiles_y_ = (height_ + kTile - 1) / kTile;
  pixel_angle_ =
      static_cast<float>(1.0 / std::max(camera.calibration().fx, camera.calibration().fy));
  const size_t n_rays = static_cast<size_t>(width_) * height_ * ss_ * ss_;
  ray_x_.resize(n_rays);
  ray_y_.resize(n_rays);
  ray_z_.resize(n_rays);
  tile_ray_begin_.resize(static_cast<size_t>(tiles_x_) * tiles_y_ + 1);
  tile_bounds_.assign(
      static_cast<size_t>(tiles_x_) * tiles_y_,
      Eigen::Vector4f(std::numeric_limits<float>::max(), -std::numeric_limits<float>::max(),
                      std::numeric_limits<float>::max(), -std::numeric_limits<float>::max()));
  size_t r = 0;
  for (int ty = 0; ty < tiles_y_; ++ty)
    for (int tx = 0; tx < tiles_x_; ++tx) {
      tile_ray_begin_[ty * tiles_x_ + tx] = r;
      Eigen::Vector4f& tb = tile_bounds_[ty * tiles_x_ + tx];
      for (int y = ty * kTile; y < std::min(height_, (ty + 1) * kTile); ++y)
        for (int x = tx * kTile; x < std::min(width_, (tx + 1) * kTile); ++x)
          for (int j = 0; j < ss_; ++j)
            for (int i = 0; i < ss_; ++i, ++r) {
              Eigen::Vector3f b;
              if (ss_ == 1) {
                b = camera.bearing(x, y);
              } else {
                b = camera.bearingAt(x + (i + 0.5) / ss_ - 0.5, y + (j + 0.5) / ss_ - 0.5)
                        .cast<float>();
              }
              ray_x_[r] = b.x();
              ray_y_[r] = b.y();
              ray_z_[r] = b.z();
              const float nx = b.x() / b.z(), ny = b.y() / b.z();
              tb[0] = std::min(tb[0], nx);
              tb[1] = std::max(tb[1], nx);
              tb[2] = std::min(tb[2], ny);
              tb[3] = std::max(tb[3], ny);
            }
    }
  tile_ray_begin_.back() = r;
  for (auto* v : {&ray_x_, &ray_y_, &ray_z_})
    v->resize(n_rays + 4, 0.f);  // a chunk's last vector may read past its end
  // Grow tile bounds by half a pixel so faces touching a tile's border are not missed.
  for (auto& tb : tile_bounds_)
    tb += Eigen::Vector4f(-pixel_angle_, pixel_angle_, -pixel_angle_, pixel_angle_);
  tile_faces_.resize(tile_bounds_.size());
  const float inf = std::numeric_limits<float>::max();
  col_bounds_.assign(tiles_x_, Eigen::Vector2f(inf, -inf));
  row_bounds_.assign(tiles_y_, Eigen::Vector2f(inf, -inf));
  for (int ty = 0; ty < tiles_y_; ++ty)
    for (int tx = 0; tx < tiles_x_; ++tx) {
      const Eigen::Vector4f& tb = tile_bounds_[ty * tiles_x_ + tx];
      col_bounds_[tx] =
          Eigen::Vector2f(std::min(col_bounds_[tx][0], tb[0]), std::max(col_bounds_[tx][1], tb[1]));
      row_bounds_[ty] =
          Eigen::Vector2f(std::min(row_bounds_[ty][0], tb[2]), std::max(row_bounds_[ty][1], tb[3]));
    }
  sensor_bounds_ = Eigen::Vector4f(inf, -inf, inf, -inf);
  for (const auto& tb : tile_bounds_)
    sensor_bounds_ =
        Eigen::Vector4f(std::min(sensor_bounds_[0], tb[0]), std::max(sensor_bounds_[1], tb[1]),
                        std::min(sensor_bounds_[2], tb[2]), std::max(sensor_bounds_[3], tb[3]));
}

void SceneRenderer::prepare(const Pose3& T_odom_cam) {
  R_odom_cam_ = T_odom_cam.linear().cast<float>();
  c_odom_ = T_odom_cam.translation().cast<float>();
  const Eigen::Matrix3f R_cam_odom = R_odom_cam_.transpose();
  for (auto& l : tile_faces_) l.clear();
  visible_.clear();
  face_bounds_.clear();
  constexpr float kNear = 0.01f;
  for (size_t fi = 0; fi < scene_.faces.size(); ++fi) {
    const Face& f = scene_.faces[fi];
    const float plane_rel = f.plane - c_odom_[f.axis];
    if (f.facing * plane_rel >= 0.f && f.facing != 0) continue;  // back face of a closed box
    const int ua = uAxis(f.axis), va = vAxis(f.axis);
    Eigen::Vector3f corners[4];
    for (int k = 0; k < 4; ++k) {
      Eigen::Vector3f p;
      p[f.axis] = f.plane;
      p[ua] = (k == 1 || k == 2) ? f.hi[0] : f.lo[0];
      p[va] = (k >= 2) ? f.hi[1] : f.lo[1];
      corners[k] = R_cam_odom * (p - c_odom_);
    }
    // Clip the quad against the near plane z >= kNear (Sutherland-Hodgman), then take the
    // bounding box of the projections in normalised coordinates.
    Eigen::Vector4f bb(std::numeric_limits<float>::max(), -std::numeric_limits<float>::max(),
                       std::numeric_limits<float>::max(), -std::numeric_limits<float>::max());
    int n_in = 0;
    auto add = [&](const Eigen::Vector3f& q) {
      const float nx = q.x() / q.z(), ny = q.y() / q.z();
      bb[0] = std::min(bb[0], nx);
      bb[1] = std::max(bb[1], nx);
      bb[2] = std::min(bb[2], ny);
      bb[3] = std::max(bb[3], ny);
      ++n_in;
    };
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector3f& a = corners[k];
      const Eigen::Vector3f& b = corners[(k + 1) % 4];
      if (a.z() >= kNear) add(a);
      if ((a.z() >= kNear) != (b.z() >= kNear)) {
        const float s = (kNear - a.z()) / (b.z() - a.z());
        add(a + s * (b - a));
      }
    }
    if (n_in == 0 || bb[1] < sensor_bounds_[0] || bb[0] > sensor_bounds_[1] ||
        bb[3] < sensor_bounds_[2] || bb[2] > sensor_bounds_[3])
      continue;
    FaceCam fc;
    fc.axis = f.axis;
    fc.ua = ua;
    fc.va = va;
    fc.plane_rel = plane_rel;
    fc.o_u = c_odom_[ua];
    fc.o_v = c_odom_[va];
    for (int k = 0; k < 2; ++k) {
      fc.lo[k] = f.lo[k];
      fc.hi[k] = f.hi[k];
      fc.offset[k] = f.offset[k];
    }
    fc.gain = f.gain;
    const float du = std::max({f.lo[0] - fc.o_u, 0.f, fc.o_u - f.hi[0]});
    const float dv = std::max({f.lo[1] - fc.o_v, 0.f, fc.o_v - f.hi[1]});
    fc.min_dist = std::sqrt(plane_rel * plane_rel + du * du + dv * dv);
    fc.tex = scene_.textures[f.texture].get();
    visible_.push_back(fc);
    face_bounds_.push_back(bb);
  }
  // Nearest first: a ray stops testing faces once the next one cannot be nearer than its hit.
  order_.resize(visible_.size());
  for (size_t i = 0; i < order_.size(); ++i) order_[i] = static_cast<int>(i);
  std::stable_sort(order_.begin(), order_.end(),
                   [&](int a, int b) { return visible_[a].min_dist < visible_[b].min_dist; });
  for (int vi : order_) {
    const Eigen::Vector4f& bb = face_bounds_[vi];
    // Test only the tiles of the candidate columns x rows.
    for (int ty = 0; ty < tiles_y_; ++ty) {
      if (bb[3] < row_bounds_[ty][0] || bb[2] > row_bounds_[ty][1]) continue;
      for (int tx = 0; tx < tiles_x_; ++tx) {
        if (bb[1] < col_bounds_[tx][0] || bb[0] > col_bounds_[tx][1]) continue;
        const int t = ty * tiles_x_ + tx;
        const Eigen::Vector4f& tb = tile_bounds_[t];
        if (bb[1] < tb[0] || bb[0] > tb[1] || bb[3] < tb[2] || bb[2] > tb[3]) continue;
        tile_faces_[t].push_back(vi);
      }
    }
  }
}

void SceneRenderer::renderTileRow(int tile_row, float* intensity, float* depth) const {
  for (int tx = 0; tx < tiles_x_; ++tx) renderTile(tx, tile_row, intensity, depth);
}

namespace {
// 4-wide float and int vectors (GCC / Clang vector extensions: SSE2 on x86-64, NEON on ARM):
// the ray-face tests below are branch-free selects that the compiler would not vectorise itself.
typedef float Vf4 __attribute__((vector_size(16)));
typedef int32_t Vi4 __attribute__((vector_size(16)));
inline Vf4 loadVf4(const float* p) {
  Vf4 v;
  std::memcpy(&v, p, sizeof(v));
  return v;
}
}  // namespace

void SceneRenderer::renderTile(int tx, int tile_row, float* intensity, float* depth) const {
  // Rays are processed in chunks of up to kChunk as vectors: ray directions, then one
  // branch-free pass over the chunk per candidate face, nearest face first, until no ray of the
  // chunk can still find a nearer hit (the same hits as testing each ray until the next face's
  // nearest point is farther than its hit); then one texture lookup per ray.
  constexpr int kChunk = 256, kV = kChunk / 4;
  const int nss = ss_ * ss_;
  const float inv_nss = 1.0f / static_cast<float>(nss);
  const float foot_scale = pixel_angle_ / static_cast<float>(ss_);
  const int tile = tile_row * tiles_x_ + tx;
  const std::vector<int>& faces = tile_faces_[tile];
  const int n_faces = static_cast<int>(faces.size());
  const int x0 = tx * kTile, x1 = std::min(width_, x0 + kTile);
  const int y0 = tile_row * kTile, y1 = std::min(height_, y0 + kTile);
  const int tile_w = x1 - x0;
  const int rows_per_chunk = std::max(1, kChunk / (tile_w * nss));
  const Eigen::Matrix3f& R = R_odom_cam_;
  Vf4 d[3][kV];    // ray directions in odom (unit)
  Vf4 inv[3][kV];  // their reciprocals (a zero component gives inf: no hit)
  Vf4 t_hit[kV], u_hit[kV], v_hit[kV],
      d_normal[kV];  // nearest hit: distance, (u, v), direction along the normal
  Vi4 face_hit[kV];  // index into faces, -1: sky
  constexpr float kFar = std::numeric_limits<float>::max();
  for (int cy0 = y0; cy0 < y1; cy0 += rows_per_chunk) {
    const int cy1 = std::min(y1, cy0 + rows_per_chunk);
    const int n = (cy1 - cy0) * tile_w * nss;
    const int nv = (n + 3) / 4;
    const size_t r0 = tile_ray_begin_[tile] + static_cast<size_t>(cy0 - y0) * tile_w * nss;
    const float* bx = ray_x_.data() + r0;
    const float* by = ray_y_.data() + r0;
    const float* bz = ray_z_.data() + r0;
    for (int i = 0; i < nv; ++i) {
      const Vf4 x = loadVf4(bx + 4 * i), y = loadVf4(by + 4 * i), z = loadVf4(bz + 4 * i);
      for (int a = 0; a < 3; ++a) {
        d[a][i] = R(a, 0) * x + R(a, 1) * y + R(a, 2) * z;
        inv[a][i] = 1.0f / d[a][i];
      }
      t_hit[i] = Vf4{kFar, kFar, kFar, kFar};
      u_hit[i] = v_hit[i] = d_normal[i] = Vf4{0, 0, 0, 0};
      face_hit[i] = Vi4{-1, -1, -1, -1};
    }
    for (int k = n; k < 4 * nv; ++k)
      t_hit[k / 4][k % 4] = 0.f;  // padding lanes: never hit, never open
    for (int k = 0; k < n_faces; ++k) {
      const FaceCam& f = visible_[faces[k]];
      const Vf4* inv_a = inv[f.axis];
      const Vf4* d_a = d[f.axis];
      const Vf4* d_u = d[f.ua];
      const Vf4* d_v = d[f.va];
      const float plane_rel = f.plane_rel, o_u = f.o_u, o_v = f.o_v;
      const float lo_u = f.lo[0], hi_u = f.hi[0], lo_v = f.lo[1], hi_v = f.hi[1];
      // Rays whose hit is still farther than the next face's nearest point (all later faces are
      // at least that far): when none is left, the chunk is done.
      const float next_min = k + 1 < n_faces ? visible_[faces[k + 1]].min_dist : -1.0f;
      Vi4 open = {0, 0, 0, 0};
      for (int i = 0; i < nv; ++i) {
        // Distance to the face's plane along the ray, and where it meets the plane.
        const Vf4 t = plane_rel * inv_a[i];
        const Vf4 u = o_u + t * d_u[i];
        const Vf4 v = o_v + t * d_v[i];
        const Vf4 t_old = t_hit[i];
        const Vi4 hit =
            (t > 1e-4f) & (t < t_old) & (u >= lo_u) & (u <= hi_u) & (v >= lo_v) & (v <= hi_v);
        const Vf4 t_new = hit ? t : t_old;
        t_hit[i] = t_new;
        u_hit[i] = hit ? u : u_hit[i];
        v_hit[i] = hit ? v : v_hit[i];
        d_normal[i] = hit ? d_a[i] : d_normal[i];
        face_hit[i] = hit ? k : face_hit[i];
        open -= t_new > next_min;
      }
      if (open[0] + open[1] + open[2] + open[3] == 0) break;
    }
    int i = 0;
    for (int y = cy0; y < cy1; ++y)
      for (int x = x0; x < x1; ++x) {
        const size_t pix = static_cast<size_t>(y) * width_ + x;
        float sum = 0.f, z_cam = 0.f;
        for (int s = 0; s < nss; ++s, ++i) {
          const int q = i / 4, l = i % 4;
          const int fk = face_hit[q][l];
          if (fk < 0) {
            // Sky: a little brighter upwards.
            sum += scene_.sky_intensity *
                   (0.85f + 0.15f * std::min(1.f, std::max(0.f, d[2][q][l] * 3.f)));
            continue;
          }
          const FaceCam& f = visible_[faces[fk]];
          // Pixel footprint on the surface: grows with distance and obliquity (isotropic filter
          // with a compromise between the two axes of the footprint ellipse).
          const float t = t_hit[q][l];
          const float footprint =
              t * foot_scale / std::sqrt(std::max(0.05f, std::abs(d_normal[q][l])));
          sum += f.gain *
                 f.tex->sample(u_hit[q][l] + f.offset[0], v_hit[q][l] + f.offset[1], footprint);
          if (s == 0) z_cam = t * bz[i];
        }
        if (intensity) intensity[pix] = sum * inv_nss;
        if (depth) depth[pix] = z_cam;
      }
  }
}

void SceneRenderer::render(const Pose3& T_odom_cam, float* intensity, float* depth,
                           ThreadPool* pool) {
  prepare(T_odom_cam);
  if (!pool) {
    for (int r = 0; r < tiles_y_; ++r) renderTileRow(r, intensity, depth);
    return;
  }
  pool->run(tiles_y_, [&](int r, int) { renderTileRow(r, intensity, depth); });
}

}  // namespace sim
}  // namespace vwe_vo
