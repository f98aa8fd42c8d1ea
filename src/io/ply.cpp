#include "vwe_vo/io/ply.h"

#include <cstring>
#include <fstream>
#include <stdexcept>

namespace vwe_vo {

PlyCloud toPlyCloud(const std::vector<MapPoint>& points) {
  PlyCloud c;
  c.xyz.reserve(points.size());
  c.confidence.reserve(points.size());
  for (const MapPoint& p : points) {
    c.xyz.push_back(p.p);
    c.confidence.push_back(p.confidence);
  }
  return c;
}

namespace {
void appendFloatLe(std::vector<char>* buf, float f) {
  uint32_t u;
  std::memcpy(&u, &f, 4);
  for (int b = 0; b < 4; ++b) buf->push_back(char((u >> (8 * b)) & 0xff));
}
}  // namespace

void writePly(const std::string& path, const PlyCloud& cloud) {
  const size_t n = cloud.xyz.size();
  if (!cloud.rgb.empty() && cloud.rgb.size() != n)
    throw std::invalid_argument("writePly: " + std::to_string(cloud.rgb.size()) + " colours for " +
                                std::to_string(n) + " points");
  if (!cloud.confidence.empty() && cloud.confidence.size() != n)
    throw std::invalid_argument("writePly: " + std::to_string(cloud.confidence.size()) +
                                " confidences for " + std::to_string(n) + " points");
  std::ofstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error("writePly: cannot open " + path);
  f << "ply\nformat binary_little_endian 1.0\ncomment vwe_vo EMVS map\nelement vertex " << n
    << "\nproperty float x\nproperty float y\nproperty float z\n";
  if (!cloud.rgb.empty()) f << "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  if (!cloud.confidence.empty()) f << "property float confidence\n";
  f << "end_header\n";
  std::vector<char> buf;
  buf.reserve(n * 19);
  for (size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) appendFloatLe(&buf, cloud.xyz[i][k]);
    if (!cloud.rgb.empty())
      for (int k = 0; k < 3; ++k) buf.push_back(char(cloud.rgb[i][k]));
    if (!cloud.confidence.empty()) appendFloatLe(&buf, cloud.confidence[i]);
  }
  f.write(buf.data(), std::streamsize(buf.size()));
  if (!f) throw std::runtime_error("writePly: write failed for " + path);
}

}  // namespace vwe_vo
