#include "vwe_vo/ros/conversions.h"

#include <stdexcept>

namespace vwe_vo {

ros::Time toRosTime(int64_t t_ns) {
  if (t_ns < 0) throw std::invalid_argument("toRosTime: negative time " + std::to_string(t_ns) + " ns");
  ros::Time t;
  t.sec = static_cast<uint32_t>(t_ns / kNsPerSec);
  t.nsec = static_cast<uint32_t>(t_ns % kNsPerSec);
  return t;
}

int64_t fromRosTime(const ros::Time& t) { return static_cast<int64_t>(t.sec) * kNsPerSec + t.nsec; }

EventArray toEventArrayMsg(const EventVector& events, size_t begin, size_t end, int width, int height,
                           const std::string& frame_id, int64_t epoch_ns, int64_t stamp_ns) {
  if (begin > end || end > events.size()) throw std::invalid_argument("toEventArrayMsg: bad range");
  EventArray msg;
  msg.header.frame_id = frame_id;
  msg.width = static_cast<uint32_t>(width);
  msg.height = static_cast<uint32_t>(height);
  msg.events.resize(end - begin);
  for (size_t i = begin; i < end; ++i) {
    EventMsg& m = msg.events[i - begin];
    m.x = events[i].x;
    m.y = events[i].y;
    m.ts = toRosTime(events[i].t_ns + epoch_ns);
    m.polarity = events[i].polarity > 0;
  }
  const int64_t stamp = stamp_ns >= 0 ? stamp_ns : (end > begin ? events[end - 1].t_ns : 0);
  msg.header.stamp = toRosTime(stamp + epoch_ns);
  return msg;
}

size_t appendEventArrayMsg(const EventArray& msg, EventVector* out, int64_t epoch_ns) {
  size_t outside = 0;
  out->reserve(out->size() + msg.events.size());
  for (const auto& m : msg.events) {
    if (m.x >= msg.width || m.y >= msg.height) {
      ++outside;
      continue;
    }
    out->push_back(Event{fromRosTime(m.ts) - epoch_ns, m.x, m.y, static_cast<int8_t>(m.polarity ? 1 : -1)});
  }
  return outside;
}

sensor_msgs::CameraInfo toCameraInfoMsg(const CameraCalibration& c, const std::string& frame_id) {
  sensor_msgs::CameraInfo msg;
  msg.header.frame_id = frame_id;
  msg.width = static_cast<uint32_t>(c.width);
  msg.height = static_cast<uint32_t>(c.height);
  msg.distortion_model = "plumb_bob";
  msg.D.assign(c.distortion.begin(), c.distortion.end());
  msg.K = {c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1};
  msg.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  msg.P = {c.fx, 0, c.cx, 0, 0, c.fy, c.cy, 0, 0, 0, 1, 0};
  return msg;
}

CameraCalibration fromCameraInfoMsg(const sensor_msgs::CameraInfo& msg) {
  if (!msg.distortion_model.empty() && msg.distortion_model != "plumb_bob")
    throw std::invalid_argument("CameraInfo: distortion_model '" + msg.distortion_model + "' is not plumb_bob");
  if (msg.D.size() > 5) throw std::invalid_argument("CameraInfo: D has " + std::to_string(msg.D.size()) + " > 5 coefficients");
  CameraCalibration c;
  c.width = static_cast<int>(msg.width);
  c.height = static_cast<int>(msg.height);
  c.fx = msg.K[0];
  c.fy = msg.K[4];
  c.cx = msg.K[2];
  c.cy = msg.K[5];
  for (size_t i = 0; i < msg.D.size(); ++i) c.distortion[i] = msg.D[i];
  c.validate();
  return c;
}

geometry_msgs::Point toPointMsg(const Vec3& p) {
  geometry_msgs::Point m;
  m.x = p.x();
  m.y = p.y();
  m.z = p.z();
  return m;
}

geometry_msgs::Vector3 toVector3Msg(const Vec3& v) {
  geometry_msgs::Vector3 m;
  m.x = v.x();
  m.y = v.y();
  m.z = v.z();
  return m;
}

geometry_msgs::Quaternion toQuaternionMsg(const Quat& q_in) {
  const Quat q = q_in.normalized();
  geometry_msgs::Quaternion m;
  m.x = q.x();
  m.y = q.y();
  m.z = q.z();
  m.w = q.w();
  return m;
}

geometry_msgs::Pose toPoseMsg(const Pose3& T) {
  geometry_msgs::Pose m;
  m.position = toPointMsg(T.translation());
  m.orientation = toQuaternionMsg(Quat(T.linear()));
  return m;
}

Pose3 fromPoseMsg(const geometry_msgs::Pose& m) {
  const Quat q(m.orientation.w, m.orientation.x, m.orientation.y, m.orientation.z);
  if (!(q.norm() > 1e-9)) throw std::invalid_argument("Pose message: zero quaternion");
  return makePose(q, Vec3(m.position.x, m.position.y, m.position.z));
}

geometry_msgs::Transform toTransformMsg(const Pose3& T) {
  geometry_msgs::Transform m;
  m.translation = toVector3Msg(T.translation());
  m.rotation = toQuaternionMsg(Quat(T.linear()));
  return m;
}

}  // namespace vwe_vo
