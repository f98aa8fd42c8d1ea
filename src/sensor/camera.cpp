#include "vwe_vo/sensor/camera.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <stdexcept>

namespace vwe_vo {
namespace {

void require(bool ok, const std::string& msg) {
  if (!ok) throw std::invalid_argument("camera calibration: " + msg);
}

std::vector<double> readMatrixData(const YAML::Node& root, const std::string& key,
                                   const std::string& path) {
  const YAML::Node n = root[key];
  if (!n) throw std::runtime_error(path + ": missing field '" + key + "'");
  const YAML::Node data = n.IsMap() ? n["data"] : n;
  if (!data || !data.IsSequence())
    throw std::runtime_error(path + ": field '" + key + "' has no data list");
  std::vector<double> v;
  for (const auto& e : data) v.push_back(e.as<double>());
  return v;
}

}  // namespace

void CameraCalibration::validate() const {
  require(width > 0 && height > 0 && width <= 4096 && height <= 4096,
          "image size " + std::to_string(width) + "x" + std::to_string(height) +
              " is invalid (image_width/image_height)");
  require(std::isfinite(fx) && fx > 0,
          "focal length fx = " + std::to_string(fx) + " must be finite and positive");
  require(std::isfinite(fy) && fy > 0,
          "focal length fy = " + std::to_string(fy) + " must be finite and positive");
  require(std::isfinite(cx) && cx >= 0 && cx <= width,
          "principal point cx = " + std::to_string(cx) + " is outside the image");
  require(std::isfinite(cy) && cy >= 0 && cy <= height,
          "principal point cy = " + std::to_string(cy) + " is outside the image");
  const char* names[5] = {"k1", "k2", "p1", "p2", "k3"};
  for (int i = 0; i < 5; ++i)
    require(std::isfinite(distortion[i]) && std::abs(distortion[i]) < 100.0,
            std::string("distortion coefficient ") + names[i] + " = " +
                std::to_string(distortion[i]) + " is not finite");
}

CameraCalibration loadCameraCalibrationYaml(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(path + ": cannot read camera calibration: " + e.what());
  }
  CameraCalibration c;
  try {
    if (!root["image_width"] || !root["image_height"])
      throw std::runtime_error(path + ": missing field 'image_width' or 'image_height'");
    c.width = root["image_width"].as<int>();
    c.height = root["image_height"].as<int>();
    if (root["camera_name"]) c.camera_name = root["camera_name"].as<std::string>();
    const auto K = readMatrixData(root, "camera_matrix", path);
    if (K.size() != 9)
      throw std::runtime_error(path + ": camera_matrix must have 9 values, has " +
                               std::to_string(K.size()));
    c.fx = K[0];
    c.cx = K[2];
    c.fy = K[4];
    c.cy = K[5];
    const std::string model =
        root["distortion_model"] ? root["distortion_model"].as<std::string>() : "plumb_bob";
    if (model != "plumb_bob" && model != "radtan")
      throw std::runtime_error(path + ": distortion_model '" + model +
                               "' is not supported (use plumb_bob)");
    if (root["distortion_coefficients"]) {
      const auto D = readMatrixData(root, "distortion_coefficients", path);
      if (D.size() > 5)
        throw std::runtime_error(path + ": distortion_coefficients has more than 5 values");
      for (size_t i = 0; i < D.size(); ++i) c.distortion[i] = D[i];
    }
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(path + ": malformed camera calibration: " + e.what());
  }
  try {
    c.validate();
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(path + ": " + e.what());
  }
  return c;
}

CameraModel::CameraModel(const CameraCalibration& calibration) : calib_(calibration) {
  calib_.validate();
  const int n = calib_.width * calib_.height;
  std::vector<cv::Point2f> pixels(n), undistorted;
  for (int y = 0; y < calib_.height; ++y)
    for (int x = 0; x < calib_.width; ++x)
      pixels[y * calib_.width + x] = cv::Point2f(float(x), float(y));
  const cv::Matx33d K(calib_.fx, 0, calib_.cx, 0, calib_.fy, calib_.cy, 0, 0, 1);
  const std::vector<double> D(calib_.distortion.begin(), calib_.distortion.end());
  // More iterations than OpenCV's default 5 so that strong lens corners round-trip to 1e-3 px.
  cv::undistortPoints(pixels, undistorted, K, D, cv::noArray(), cv::noArray(),
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-12));
  bearings_.resize(n);
  for (int i = 0; i < n; ++i)
    bearings_[i] = Eigen::Vector3f(undistorted[i].x, undistorted[i].y, 1.0f).normalized();
}

Vec2 CameraModel::distortNormalized(const Vec2& xn) const {
  const auto& d = calib_.distortion;
  const double x = xn.x(), y = xn.y(), r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (d[0] + r2 * (d[1] + r2 * d[4]));
  return Vec2(x * radial + 2.0 * d[2] * x * y + d[3] * (r2 + 2.0 * x * x),
              y * radial + d[2] * (r2 + 2.0 * y * y) + 2.0 * d[3] * x * y);
}

Vec2 CameraModel::undistortNormalized(const Vec2& xd) const {
  // Fixed-point iteration x <- xd - (distort(x) - x), refined with Gauss-Newton steps on a
  // numerically differentiated distortion: robust for the mild lenses of event cameras.
  Vec2 x = xd;
  for (int it = 0; it < 20; ++it) {
    const Vec2 r = distortNormalized(x) - xd;
    if (r.norm() < 1e-14) break;
    const double h = 1e-7;
    Eigen::Matrix2d J;
    J.col(0) = (distortNormalized(x + Vec2(h, 0)) - distortNormalized(x - Vec2(h, 0))) / (2 * h);
    J.col(1) = (distortNormalized(x + Vec2(0, h)) - distortNormalized(x - Vec2(0, h))) / (2 * h);
    x -= J.inverse() * r;
  }
  return x;
}

Vec3 CameraModel::bearingAt(double u, double v) const {
  const Vec2 xd((u - calib_.cx) / calib_.fx, (v - calib_.cy) / calib_.fy);
  const Vec2 xn = undistortNormalized(xd);
  return Vec3(xn.x(), xn.y(), 1.0).normalized();
}

bool CameraModel::project(const Vec3& p_C, Vec2* uv) const {
  if (!(p_C.z() > 0)) return false;
  const Vec2 xd = distortNormalized(Vec2(p_C.x() / p_C.z(), p_C.y() / p_C.z()));
  *uv = Vec2(calib_.fx * xd.x() + calib_.cx, calib_.fy * xd.y() + calib_.cy);
  return true;
}

}  // namespace vwe_vo
