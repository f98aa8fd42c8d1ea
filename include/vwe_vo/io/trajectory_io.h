// Trajectory and event files: TUM trajectories (`t px py pz qx qy qz qw`) and the Event Camera
// Dataset text format (events.txt `t x y p`, calib.txt, groundtruth.txt, extrinsics.txt).
// Readers throw std::runtime_error naming the file and the line of anything malformed;
// nothing is skipped silently (comment lines starting with '#' and blank lines are allowed).
#pragma once

#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "vwe_vo/sensor/events.h"
#include "vwe_vo/trajectory/stamped_trajectory.h"

struct gzFile_s;  // zlib's stream

namespace vwe_vo {

/// Reads a TUM file. Throws on malformed lines, non-finite values, non-increasing time and on a
/// file without any pose.
Trajectory3 readTum(const std::string& path);
/// Writes a TUM file (9 decimals for time, quaternion with qw last).
void writeTum(const std::string& path, const Trajectory3& trajectory);

/// Event Camera Dataset events.txt (or .gz): `t x y p` per line, t in seconds, p in {0, 1}.
/// Throws on malformed lines, events outside width x height (if given > 0), time going back.
EventVector readEcdEvents(const std::string& path, int width = 0, int height = 0);
/// The same, streamed in chunks so that memory does not grow with the file.
class EcdEventReader {
 public:
  EcdEventReader(const std::string& path, int width = 0, int height = 0);
  ~EcdEventReader();
  /// Replaces *out with up to max_events next events; returns how many (0 at the end).
  size_t read(size_t max_events, EventVector* out);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};
/// Writes events.txt; a path ending in ".gz" is written gzip-compressed.
void writeEcdEvents(const std::string& path, const EventVector& events);
/// The same, streamed: events are appended chunk by chunk (memory does not grow).
class EcdEventWriter {
 public:
  explicit EcdEventWriter(const std::string& path);
  ~EcdEventWriter();
  EcdEventWriter(const EcdEventWriter&) = delete;
  EcdEventWriter& operator=(const EcdEventWriter&) = delete;
  void write(const EventVector& events);

 private:
  std::string path_;
  FILE* file_ = nullptr;
  gzFile_s* gz_ = nullptr;
};

/// calib.txt: `fx fy cx cy k1 k2 p1 p2 k3` (the last five optional, default 0).
struct EcdCalibration {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  double k1 = 0, k2 = 0, p1 = 0, p2 = 0, k3 = 0;
};
EcdCalibration readEcdCalibration(const std::string& path);
void writeEcdCalibration(const std::string& path, const EcdCalibration& calib);

/// imu.txt: `t ax ay az gx gy gz` per line (Event Camera Dataset layout), t in seconds,
/// specific force in m/s^2 and angular velocity in rad/s, both in the IMU frame.
struct ImuSample {
  int64_t t_ns = 0;
  Vec3 accel = Vec3::Zero();  // specific force [m/s^2]
  Vec3 gyro = Vec3::Zero();   // angular velocity [rad/s]
};
/// Throws on malformed lines, non-finite values and time going back.
std::vector<ImuSample> readEcdImu(const std::string& path);
void writeEcdImu(const std::string& path, const std::vector<ImuSample>& samples);
/// The same, streamed.
class EcdImuWriter {
 public:
  explicit EcdImuWriter(const std::string& path);
  ~EcdImuWriter();
  EcdImuWriter(const EcdImuWriter&) = delete;
  EcdImuWriter& operator=(const EcdImuWriter&) = delete;
  void write(const ImuSample& sample);

 private:
  std::string path_;
  FILE* file_;
};

/// extrinsics.txt: T_base_cam as `px py pz qx qy qz qw` on one line.
Pose3 readPoseLine(const std::string& path);
void writePoseLine(const std::string& path, const Pose3& T);

}  // namespace vwe_vo
