#include "vwe_vo/ros/conversions.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>

namespace vwe_vo {

int64_t toNs(const ros::Time& t) {
  return int64_t(t.sec) * kNsPerSec + int64_t(t.nsec);
}

ros::Time toRosTime(int64_t t_ns) {
  if (t_ns < 0)
    throw std::invalid_argument("toRosTime: negative time " + std::to_string(t_ns) + " ns");
  ros::Time t;
  t.fromNSec(uint64_t(t_ns));
  return t;
}

void eventsFromMsg(const EventArray& msg, EventVector* events, EventConversionStats* stats) {
  events->clear();
  events->reserve(msg.events.size());
  size_t dropped = 0;
  for (const vwe_vo::Event& m : msg.events) {
    if (m.x >= msg.width || m.y >= msg.height) {
      ++dropped;
      continue;
    }
    PixelEvent e;
    e.t_ns = toNs(m.ts);
    e.x = m.x;
    e.y = m.y;
    e.polarity = m.polarity ? 1 : -1;
    events->push_back(e);
  }
  if (stats) {
    stats->converted += events->size();
    stats->dropped += dropped;
  }
}

void eventsToMsg(const EventVector& events, EventArray* msg) {
  msg->events.resize(events.size());
  for (size_t i = 0; i < events.size(); ++i) {
    msg->events[i].x = events[i].x;
    msg->events[i].y = events[i].y;
    msg->events[i].ts = toRosTime(events[i].t_ns);
    msg->events[i].polarity = events[i].polarity > 0;
  }
}

EventArray eventsToMsg(const EventVector& events, size_t begin, size_t end, int width, int height,
                       const std::string& frame_id, int64_t epoch_ns, int64_t stamp_ns) {
  if (begin > end || end > events.size())
    throw std::invalid_argument("eventsToMsg: range [" + std::to_string(begin) + ", " +
                                std::to_string(end) + ") outside " + std::to_string(events.size()) +
                                " events");
  EventArray msg;
  msg.header.frame_id = frame_id;
  msg.width = uint32_t(width);
  msg.height = uint32_t(height);
  msg.events.resize(end - begin);
  for (size_t i = begin; i < end; ++i) {
    auto& m = msg.events[i - begin];
    m.x = events[i].x;
    m.y = events[i].y;
    m.ts = toRosTime(events[i].t_ns + epoch_ns);
    m.polarity = events[i].polarity > 0;
  }
  const int64_t stamp = stamp_ns >= 0 ? stamp_ns : (end > begin ? events[end - 1].t_ns : 0);
  msg.header.stamp = toRosTime(stamp + epoch_ns);
  return msg;
}

CameraCalibration calibrationFromMsg(const sensor_msgs::CameraInfo& msg) {
  CameraCalibration c;
  c.width = int(msg.width);
  c.height = int(msg.height);
  c.fx = msg.K[0];
  c.cx = msg.K[2];
  c.fy = msg.K[4];
  c.cy = msg.K[5];
  if (!msg.D.empty() && msg.distortion_model != "plumb_bob" && msg.distortion_model != "radtan")
    throw std::invalid_argument("CameraInfo: distortion_model '" + msg.distortion_model +
                                "' is not supported (plumb_bob)");
  if (msg.D.size() > 5)
    throw std::invalid_argument("CameraInfo: D has " + std::to_string(msg.D.size()) +
                                " values, plumb_bob has 5");
  for (size_t i = 0; i < msg.D.size(); ++i) c.distortion[i] = msg.D[i];
  c.validate();
  return c;
}

sensor_msgs::CameraInfo calibrationToMsg(const CameraCalibration& c, const std::string& frame_id) {
  sensor_msgs::CameraInfo m;
  m.header.frame_id = frame_id;
  m.width = uint32_t(c.width);
  m.height = uint32_t(c.height);
  m.distortion_model = "plumb_bob";
  m.D.assign(c.distortion.begin(), c.distortion.end());
  m.K = {c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1};
  m.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  m.P = {c.fx, 0, c.cx, 0, 0, c.fy, c.cy, 0, 0, 0, 1, 0};
  return m;
}

geometry_msgs::Point pointToMsg(const Vec3& p) {
  geometry_msgs::Point m;
  m.x = p.x();
  m.y = p.y();
  m.z = p.z();
  return m;
}

geometry_msgs::Vector3 vectorToMsg(const Vec3& v) {
  geometry_msgs::Vector3 m;
  m.x = v.x();
  m.y = v.y();
  m.z = v.z();
  return m;
}

geometry_msgs::Quaternion quaternionToMsg(const Quat& q_in) {
  const Quat q = q_in.normalized();
  geometry_msgs::Quaternion m;
  m.x = q.x();
  m.y = q.y();
  m.z = q.z();
  m.w = q.w();
  return m;
}

geometry_msgs::Pose poseToMsg(const Pose3& T) {
  geometry_msgs::Pose p;
  p.position = pointToMsg(T.translation());
  p.orientation = quaternionToMsg(Quat(T.linear()));
  return p;
}

Pose3 poseFromMsg(const geometry_msgs::Pose& m) {
  const Quat q(m.orientation.w, m.orientation.x, m.orientation.y, m.orientation.z);
  if (!(q.norm() > 1e-9)) throw std::invalid_argument("Pose message: zero quaternion");
  return makePose(q, Vec3(m.position.x, m.position.y, m.position.z));
}

geometry_msgs::Transform transformToMsg(const Pose3& T) {
  geometry_msgs::Transform m;
  m.translation = vectorToMsg(T.translation());
  m.rotation = quaternionToMsg(Quat(T.linear()));
  return m;
}

OdometrySample odometryFromMsg(const nav_msgs::Odometry& msg) {
  OdometrySample o;
  o.t_ns = toNs(msg.header.stamp);
  o.v_mps = msg.twist.twist.linear.x;
  o.yaw_rate_rad_s = msg.twist.twist.angular.z;
  return o;
}

GyroSample gyroFromMsg(const sensor_msgs::Imu& msg, const Pose3& T_base_cam) {
  const Vec3 w_cam(msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z);
  GyroSample g;
  g.t_ns = toNs(msg.header.stamp);
  g.yaw_rate_rad_s = (T_base_cam.linear() * w_cam).z();
  return g;
}

ImuSample imuFromMsg(const sensor_msgs::Imu& msg) {
  ImuSample s;
  s.t_ns = toNs(msg.header.stamp);
  s.gyro = Vec3(msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z);
  s.accel = Vec3(msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z);
  return s;
}

AckermannArc arcToMsg(const ArcEstimate& a, const std::string& frame_id) {
  AckermannArc m;
  m.header.stamp = toRosTime(a.t_ref_ns);
  m.header.frame_id = frame_id;
  m.t_start = toRosTime(a.t_start_ns);
  m.t_end = toRosTime(a.t_end_ns);
  m.omega = a.omega;
  m.roll_rate = a.roll_rate;
  m.omega_without_roll = a.omegaWithoutRoll();
  m.v = a.v;
  m.contrast = a.contrast;
  m.confidence = a.confidence;
  m.num_events = a.num_events;
  m.status = uint8_t(a.status);
  return m;
}

ArcEstimate arcFromMsg(const AckermannArc& m) {
  ArcEstimate a;
  a.t_ref_ns = toNs(m.header.stamp);
  a.t_start_ns = toNs(m.t_start);
  a.t_end_ns = toNs(m.t_end);
  a.omega = m.omega;
  a.roll_rate = m.roll_rate;
  // A sender that leaves the roll at 0 (an older recording, another front-end) has only omega.
  if (m.roll_rate != 0.0 && std::isfinite(m.omega_without_roll))
    a.roll_omega_shift = m.omega - m.omega_without_roll;
  a.v = m.v;
  a.contrast = m.contrast;
  a.confidence = m.confidence;
  a.num_events = m.num_events;
  a.status = m.status <= 3 ? ArcStatus(m.status) : ArcStatus::kLost;
  return a;
}

cv::Mat imageFromMsg(const sensor_msgs::Image& msg) {
  if (msg.encoding != "mono8" && msg.encoding != "8UC1")
    throw std::invalid_argument("image encoding '" + msg.encoding + "' is not mono8");
  if (msg.step < msg.width || msg.data.size() < static_cast<size_t>(msg.step) * msg.height)
    throw std::invalid_argument(
        "image " + std::to_string(msg.width) + "x" + std::to_string(msg.height) + " with step " +
        std::to_string(msg.step) + " has only " + std::to_string(msg.data.size()) + " bytes");
  const cv::Mat view(msg.height, msg.width, CV_8UC1, const_cast<uint8_t*>(msg.data.data()),
                     msg.step);
  return view.clone();
}

sensor_msgs::Image imageToMsg(const cv::Mat& image, int64_t t_ns, const std::string& frame_id) {
  if (image.type() != CV_8UC1 && image.type() != CV_8UC3)
    throw std::invalid_argument("imageToMsg: only 8-bit mono or BGR images (type " +
                                std::to_string(image.type()) + ")");
  sensor_msgs::Image m;
  m.header.stamp = toRosTime(t_ns);
  m.header.frame_id = frame_id;
  m.height = image.rows;
  m.width = image.cols;
  m.encoding = image.channels() == 1 ? "mono8" : "bgr8";
  m.step = image.cols * image.channels();
  m.data.resize(static_cast<size_t>(m.step) * image.rows);
  for (int y = 0; y < image.rows; ++y) std::memcpy(&m.data[y * m.step], image.ptr(y), m.step);
  return m;
}

SplineTrajectory splineToMsg(const BSpline& spline, int first_free, const std::string& frame_id) {
  SplineTrajectory m;
  const int64_t epoch = spline.epochNs();
  m.header.stamp = toRosTime(epoch + secToNs(spline.validTo()));
  m.header.frame_id = frame_id;
  m.degree = uint8_t(spline.degree());
  m.knot_epoch = toRosTime(epoch);
  m.knots = spline.knots();
  for (const Vec2& p : spline.controlPoints()) {
    m.control_x.push_back(p.x());
    m.control_y.push_back(p.y());
  }
  m.valid_from = toRosTime(epoch + secToNs(spline.validFrom()));
  m.valid_to = toRosTime(epoch + secToNs(spline.validTo()));
  m.first_free_control_point = uint32_t(std::max(0, first_free));
  for (const BSpline::Interval& s : spline.standstills()) {
    m.standstill_from.push_back(s.from_s);
    m.standstill_to.push_back(s.to_s);
  }
  m.min_speed = spline.minSpeed();
  return m;
}

void addTiltToMsg(int64_t t_ns, const Tilt& tilt, SplineTrajectory* msg) {
  msg->tilt_t.push_back(dtSec(t_ns, toNs(msg->knot_epoch)));
  msg->tilt_roll.push_back(tilt.roll);
  msg->tilt_pitch.push_back(tilt.pitch);
}

TiltHistory tiltFromMsg(const SplineTrajectory& msg) {
  constexpr double kMaxTiltOffset_s = 1e8;  // ~3 years: any stamp of a drive, and no overflow
  auto fail = [](const std::string& m) { throw std::invalid_argument("SplineTrajectory: " + m); };
  const size_t n = msg.tilt_t.size();
  if (msg.tilt_roll.size() != n || msg.tilt_pitch.size() != n)
    fail(std::to_string(n) + " tilt_t but " + std::to_string(msg.tilt_roll.size()) +
         " tilt_roll and " + std::to_string(msg.tilt_pitch.size()) + " tilt_pitch");
  TiltHistory history(1, std::numeric_limits<int64_t>::max() / 2);
  const int64_t epoch = toNs(msg.knot_epoch);
  int64_t previous = 0;
  for (size_t k = 0; k < n; ++k) {
    if (!std::isfinite(msg.tilt_t[k]) || !std::isfinite(msg.tilt_roll[k]) ||
        !std::isfinite(msg.tilt_pitch[k]))
      fail("tilt sample " + std::to_string(k) + " is not finite");
    if (!(std::abs(msg.tilt_t[k]) <= kMaxTiltOffset_s))
      fail("tilt_t[" + std::to_string(k) + "] " + std::to_string(msg.tilt_t[k]) +
           " s is more than " + std::to_string(kMaxTiltOffset_s) + " s from the knot epoch");
    const int64_t t = epoch + secToNs(msg.tilt_t[k]);
    if (k > 0 && t <= previous)
      fail("tilt_t[" + std::to_string(k) + "] " + std::to_string(msg.tilt_t[k]) +
           " s is not after the sample before");
    Tilt tilt;
    tilt.roll = msg.tilt_roll[k];
    tilt.pitch = msg.tilt_pitch[k];
    history.add(t, tilt);
    previous = t;
  }
  return history;
}

BSpline splineFromMsg(const SplineTrajectory& msg) {
  auto fail = [](const std::string& m) { throw std::invalid_argument("SplineTrajectory: " + m); };
  if (msg.degree < 1 || msg.degree > kBSplineMaxDegree)
    fail("degree " + std::to_string(msg.degree) + " outside [1, " +
         std::to_string(kBSplineMaxDegree) + "]");
  if (msg.control_x.size() != msg.control_y.size())
    fail("control_x has " + std::to_string(msg.control_x.size()) + " entries but control_y " +
         std::to_string(msg.control_y.size()));
  if (msg.standstill_from.size() != msg.standstill_to.size())
    fail(std::to_string(msg.standstill_from.size()) + " standstill_from but " +
         std::to_string(msg.standstill_to.size()) + " standstill_to");
  const size_t n = msg.control_x.size();
  if (n < size_t(msg.degree) + 1)
    fail(std::to_string(n) + " control points, a degree " + std::to_string(msg.degree) +
         " spline needs at least " + std::to_string(msg.degree + 1));
  if (msg.knots.size() != n + msg.degree + 1)
    fail("knots has " + std::to_string(msg.knots.size()) + " entries, " + std::to_string(n) +
         " control points of degree " + std::to_string(msg.degree) + " need " +
         std::to_string(n + msg.degree + 1));
  for (size_t i = 0; i < msg.knots.size(); ++i)
    if (!std::isfinite(msg.knots[i])) fail("knots[" + std::to_string(i) + "] is not finite");
  std::vector<Vec2> control_points(n);
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(msg.control_x[i]) || !std::isfinite(msg.control_y[i]))
      fail("control point " + std::to_string(i) + " is not finite");
    control_points[i] = Vec2(msg.control_x[i], msg.control_y[i]);
  }
  if (!(std::isfinite(msg.min_speed) && msg.min_speed >= 0))
    fail("min_speed " + std::to_string(msg.min_speed) + " is not a finite speed >= 0");
  std::vector<BSpline::Interval> still;
  for (size_t k = 0; k < msg.standstill_from.size(); ++k) {
    if (!std::isfinite(msg.standstill_from[k]) || !std::isfinite(msg.standstill_to[k]))
      fail("standstill " + std::to_string(k) + " is not finite");
    still.push_back({msg.standstill_from[k], msg.standstill_to[k]});
  }
  try {
    BSpline spline(msg.degree, msg.knots, std::move(control_points), toNs(msg.knot_epoch));
    spline.setStandstills(still);
    if (msg.min_speed > 0) spline.setMinSpeed(msg.min_speed);
    return spline;
  } catch (const std::invalid_argument& e) {
    fail(std::string("knots: ") + e.what());
  }
  return BSpline();  // not reached
}

sensor_msgs::PointCloud2 cloudToMsg(const std::vector<MapPoint>& points,
                                    const std::string& frame_id, int64_t stamp_ns) {
  sensor_msgs::PointCloud2 msg;
  msg.header.frame_id = frame_id;
  msg.header.stamp = toRosTime(std::max<int64_t>(0, stamp_ns));
  const char* names[4] = {"x", "y", "z", "intensity"};
  for (uint32_t i = 0; i < 4; ++i) {
    sensor_msgs::PointField f;
    f.name = names[i];
    f.offset = 4 * i;
    f.datatype = sensor_msgs::PointField::FLOAT32;
    f.count = 1;
    msg.fields.push_back(f);
  }
  msg.is_bigendian = false;  // the machines we run on; memcpy of host floats below
  msg.point_step = 16;
  msg.height = 1;
  msg.is_dense = true;  // non-finite points are left out
  msg.data.reserve(points.size() * msg.point_step);
  uint32_t count = 0;
  for (const MapPoint& p : points) {
    if (!p.p.allFinite() || !std::isfinite(p.confidence)) continue;
    const float v[4] = {p.p.x(), p.p.y(), p.p.z(), p.confidence};
    const uint8_t* bytes = reinterpret_cast<const uint8_t*>(v);
    msg.data.insert(msg.data.end(), bytes, bytes + sizeof(v));
    ++count;
  }
  msg.width = count;
  msg.row_step = count * msg.point_step;
  return msg;
}

}  // namespace vwe_vo
