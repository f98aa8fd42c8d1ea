// The message conversions on messages deserialized from fuzz bytes (ros::serialization), as a
// node gets them from a topic or a bag: byte 0 picks EventArray, SplineTrajectory or
// AckermannArc, the rest is the serialized message.
#include <ros/serialization.h>

#include <cmath>
#include <cstring>

#include "vwe_vo/ros/conversions.h"

namespace {

/// Walks a serialized message's layout and refuses array lengths the bytes cannot hold. The
/// transport gives every message its length, so a real message never claims more elements than
/// it carries; roscpp's deserializer resizes before it checks, so without this a four-byte
/// length would be a multi-gigabyte allocation in ROS's code, not in ours.
class Layout {
 public:
  Layout(const uint8_t* data, size_t size) : data_(data), left_(size) {}
  bool skip(size_t n) {
    if (n > left_) return ok_ = false;
    data_ += n, left_ -= n;
    return true;
  }
  bool array(size_t element_size) {
    uint32_t n = 0;
    if (left_ < 4) return ok_ = false;
    std::memcpy(&n, data_, 4);
    skip(4);
    if (element_size == 0) return true;
    return skip(size_t(n) * element_size);
  }
  void header() { skip(4), skip(8), array(1); }  // seq, stamp, frame_id
  bool ok() const { return ok_; }

 private:
  const uint8_t* data_;
  size_t left_;
  bool ok_ = true;
};

template <typename Msg>
bool deserialize(const uint8_t* data, size_t size, Msg* msg) {
  ros::serialization::IStream stream(const_cast<uint8_t*>(data), uint32_t(size));
  try {
    ros::serialization::deserialize(stream, *msg);
  } catch (const ros::Exception&) {
    return false;
  }
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1 || size > (1u << 20)) return 0;
  const uint8_t kind = data[0] % 3;
  ++data, --size;
  Layout layout(data, size);
  layout.header();
  try {
    if (kind == 0) {
      layout.skip(8);    // height, width
      layout.array(13);  // Event: x, y, ts, polarity
      vwe_vo::EventArray msg;
      if (!layout.ok() || !deserialize(data, size, &msg)) return 0;
      vwe_vo::EventVector events;
      vwe_vo::EventConversionStats stats;
      vwe_vo::eventsFromMsg(msg, &events, &stats);
      if (stats.converted + stats.dropped != msg.events.size()) __builtin_trap();
    } else if (kind == 1) {
      layout.skip(1 + 8);  // degree, knot_epoch
      layout.array(8), layout.array(8), layout.array(8);
      layout.skip(8 + 8 + 4);  // valid_from, valid_to, first_free_control_point
      layout.array(8), layout.array(8);
      layout.skip(8);                                     // min_speed
      layout.array(8), layout.array(8), layout.array(8);  // tilt_t, tilt_roll, tilt_pitch
      vwe_vo::SplineTrajectory msg;
      if (!layout.ok() || !deserialize(data, size, &msg)) return 0;
      const vwe_vo::BSpline spline = vwe_vo::splineFromMsg(msg);
      // An accepted spline can be evaluated over its whole domain, and so can accepted tilts.
      const double a = spline.validFrom(), b = spline.validTo();
      for (int i = 0; i <= 4; ++i) (void)spline.position(a + (b - a) * i / 4.0);
      const vwe_vo::TiltHistory tilts = vwe_vo::tiltFromMsg(msg);
      for (int i = 0; i <= 4; ++i) {
        const vwe_vo::Tilt tilt =
            tilts.at(spline.epochNs() + vwe_vo::secToNs(a + (b - a) * i / 4.0));
        if (!std::isfinite(tilt.roll) || !std::isfinite(tilt.pitch)) __builtin_trap();
      }
    } else {
      vwe_vo::AckermannArc msg;
      if (!deserialize(data, size, &msg)) return 0;
      vwe_vo::arcFromMsg(msg);
    }
  } catch (const std::exception&) {
  }
  return 0;
}
