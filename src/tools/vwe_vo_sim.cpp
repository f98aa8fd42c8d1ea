// vwe_vo_sim: simulates a standard sequence (events, ground truth, odometry, IMU, depth) and writes
// it as an Event Camera Dataset folder and/or a rosbag. See --help.
#include <geometry_msgs/PoseStamped.h>
#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sys/stat.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "vwe_vo/io/config.h"
#include "vwe_vo/io/files.h"
#include "vwe_vo/io/trajectory_io.h"
#include "vwe_vo/ros/conversions.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sim/frame_simulator.h"
#include "vwe_vo/sim/imu_simulator.h"
#include "vwe_vo/sim/sequences.h"
#include "vwe_vo/trajectory/ackermann_arc.h"

namespace {

using namespace vwe_vo;

// Time of simulated t = 0 in every output (bag stamps, events.txt, groundtruth.txt), so that
// all outputs share one time base (ros::Time cannot be 0 or negative).
constexpr int64_t kEpochNs = kNsPerSec;

struct Args {
  bool list = false;
  std::string sequence, format = "ecd", out, config, calib;
  bool seed_set = false;
  uint64_t seed = 0;
  double duration_s = -1;
  std::vector<double> depth_times;
  bool images = false;
  double packet_ms = 1.0;
};

void usage(std::ostream& os) {
  os << "usage: vwe_vo_sim --list\n"
        "       vwe_vo_sim --sequence NAME --format ecd|bag|ecd,bag --out DIR [--seed N] "
        "[--duration S]\n"
        "                  [--config YAML] [--calib YAML] [--depth-times t1,t2,...] [--images] "
        "[--packet-ms MS]\n"
        "ecd: DIR/events.txt calib.txt groundtruth.txt extrinsics.txt; bag: DIR/NAME.bag\n"
        "(/dvs/events /dvs/camera_info /gt/pose /odom /dvs/imu [/dvs/image_raw]); always "
        "DIR/groundtruth.txt\n"
        "(6-DoF T_odom_base at 200 Hz). Sequences with the DAVIS-like IMU (street_drive, "
        "indoor_drive and\n"
        "their _flat twins): /dvs/imu at 1 kHz, DIR/imu.txt (`t ax ay az gx gy gz`, m/s^2, rad/s, "
        "camera frame)\n"
        "in ECD folders, the true gyro bias in DIR/imu_bias.txt.\n"
        "--images: 25 Hz mono8 APS frames with motion blur, noise and auto-exposure: "
        "/dvs/image_raw in the\n"
        "bag, DIR/images/frame_NNNNNNNN.png listed in DIR/images.txt (`t "
        "images/frame_00000000.png`).\n"
        "--depth-times: DIR/depth/depth_<t>.png, 16-bit depth z in the camera frame in "
        "millimetres\n"
        "(0 = nothing hit), listed in DIR/depth/depth_times.txt.\n"
        "--seed N: another realisation of the sequence (scene, event noise and thresholds, the "
        "road under the\n"
        "suspension, the IMU's noise and bias); the planned motion stays.\n";
}

double parseDouble(const std::string& flag, const std::string& v) {
  try {
    size_t pos = 0;
    const double d = std::stod(v, &pos);
    if (pos != v.size() || !std::isfinite(d)) throw std::invalid_argument("");
    return d;
  } catch (...) {
    throw std::invalid_argument(flag + ": '" + v + "' is not a number");
  }
}

Args parseArgs(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string f = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(f + " needs a value");
      return argv[++i];
    };
    if (f == "--list")
      a.list = true;
    else if (f == "--sequence")
      a.sequence = value();
    else if (f == "--format")
      a.format = value();
    else if (f == "--out")
      a.out = value();
    else if (f == "--config")
      a.config = value();
    else if (f == "--calib")
      a.calib = value();
    else if (f == "--images")
      a.images = true;
    else if (f == "--seed") {
      const double s = parseDouble(f, value());
      if (s < 0 || s != std::floor(s))
        throw std::invalid_argument("--seed must be a non-negative integer");
      a.seed = static_cast<uint64_t>(s);
      a.seed_set = true;
    } else if (f == "--duration") {
      a.duration_s = parseDouble(f, value());
      if (!(a.duration_s > 0)) throw std::invalid_argument("--duration must be > 0");
    } else if (f == "--packet-ms") {
      a.packet_ms = parseDouble(f, value());
      if (!(a.packet_ms > 0 && a.packet_ms <= 1000))
        throw std::invalid_argument("--packet-ms must be in (0, 1000]");
    } else if (f == "--depth-times") {
      std::stringstream ss(value());
      std::string tok;
      while (std::getline(ss, tok, ',')) {
        const double t = parseDouble("--depth-times", tok);
        if (t < 0) throw std::invalid_argument("--depth-times: negative time");
        a.depth_times.push_back(t);
      }
    } else if (f == "--help" || f == "-h") {
      usage(std::cout);
      std::exit(0);
    } else {
      throw std::invalid_argument("unknown argument '" + f + "'");
    }
  }
  if (a.list) return a;
  if (a.sequence.empty()) throw std::invalid_argument("--sequence is required");
  if (a.out.empty()) throw std::invalid_argument("--out is required");
  if (a.format != "ecd" && a.format != "bag" && a.format != "ecd,bag" && a.format != "bag,ecd")
    throw std::invalid_argument("--format must be ecd, bag or ecd,bag (got '" + a.format + "')");
  return a;
}

std::string fmt(const char* f, double v) {
  char b[64];
  std::snprintf(b, sizeof(b), f, v);
  return b;
}

int run(const Args& args) {
  if (args.list) {
    std::printf("%-18s %9s %9s %5s  %s\n", "name", "duration", "path", "seed", "description");
    for (const auto& s : sim::listSequences())
      std::printf("%-18s %8.1fs %8.1fm %5llu  %s\n", s.name.c_str(), s.duration_s, s.path_length_m,
                  static_cast<unsigned long long>(s.seed), s.description.c_str());
    return 0;
  }
  sim::SequenceSpec spec = sim::findSequence(args.sequence);
  if (args.seed_set) spec.reseed(args.seed);
  // Calibration and mount: --calib, else the config's camera_calibration, else
  // config/davis346.yaml.
  std::string calib_path = args.calib;
  Pose3 T_base_cam = spec.T_base_cam;
  if (!args.config.empty()) {
    const YAML::Node root = YAML::LoadFile(args.config);
    T_base_cam = loadTBaseCam(root, args.config);  // throws on unknown keys under T_base_cam
    if (calib_path.empty()) {
      if (root["camera_calibration"]) {
        calib_path = root["camera_calibration"].as<std::string>();
        if (!calib_path.empty() && calib_path[0] != '/') {
          const size_t slash = args.config.rfind('/');
          calib_path =
              (slash == std::string::npos ? std::string(".") : args.config.substr(0, slash)) + "/" +
              calib_path;
        }
      }
    }
  }
  if (calib_path.empty()) calib_path = defaultConfigDir() + "/davis346.yaml";
  const CameraCalibration calib = loadCameraCalibrationYaml(calib_path);
  const CameraModel camera(calib);

  const sim::VehicleTrajectory trajectory =
      sim::VehicleTrajectory::fromProfile(spec.profile, spec.trajectory);
  const int64_t duration_ns = args.duration_s > 0
                                  ? std::min(trajectory.durationNs(), secToNs(args.duration_s))
                                  : trajectory.durationNs();
  const sim::Scene scene = sim::buildSequenceScene(spec, trajectory);
  sim::EventSimulator simulator(scene, camera, T_base_cam, trajectory, spec.simulator);

  const bool want_ecd = args.format.find("ecd") != std::string::npos;
  const bool want_bag = args.format.find("bag") != std::string::npos;
  makeDirs(args.out);
  std::fprintf(stderr, "[vwe_vo_sim] %s: %s scene (%zu faces), %.1f s, seed %llu, calibration %s\n",
               spec.name.c_str(), spec.scene.c_str(), scene.faces.size(), nsToSec(duration_ns),
               static_cast<unsigned long long>(spec.seed), calib_path.c_str());

  rosbag::Bag bag;
  uint32_t packet_seq = 0;
  if (want_bag) bag.open(args.out + "/" + spec.name + ".bag", rosbag::bagmode::Write);
  auto stamp = [](int64_t t_ns) { return toRosTime(t_ns + kEpochNs); };
  std::mt19937_64 rng(spec.seed * 31 + 7);
  std::normal_distribution<double> n01(0.0, 1.0);
  // Wheel odometry: 1% scale error, white speed / yaw-rate noise per 1 ms step, dead reckoned.
  const double odom_scale = 1.01, odom_v_sigma = 0.02, odom_w_sigma = 0.01;
  Vec3 odom_pose = trajectory.planar(0);
  double odom_v_sum = 0, odom_w_sum = 0;
  int odom_n = 0;
  // Gyro: constant bias and white noise, in the camera frame.
  const Vec3 gyro_bias(0.004, -0.003, 0.002);
  const double gyro_sigma = 0.005, accel_sigma = 0.05;
  const sensor_msgs::CameraInfo info = calibrationToMsg(calib, "davis");

  // The DAVIS-like IMU (sequences with davis_imu): 1 kHz, its own random stream; imu.txt in ECD
  // folders, the true gyro bias in imu_bias.txt.
  std::unique_ptr<sim::ImuSimulator> davis_imu;
  std::unique_ptr<EcdImuWriter> imu_txt;
  int64_t next_davis_imu = 0;
  if (spec.davis_imu) {
    davis_imu = std::make_unique<sim::ImuSimulator>(trajectory, T_base_cam, spec.imu);
    if (want_ecd) imu_txt = std::make_unique<EcdImuWriter>(args.out + "/imu.txt");
    std::ofstream bias(args.out + "/imu_bias.txt");
    const Vec3& b = davis_imu->gyroBias();
    bias << "# true constant gyro bias in the camera (IMU) frame [rad/s]: bx by bz; noise sigma "
            "per sample: gyro [rad/s] accel [m/s^2]\n"
         << fmt("%.9g", b.x()) << " " << fmt("%.9g", b.y()) << " " << fmt("%.9g", b.z()) << "\n"
         << fmt("%.9g", spec.imu.gyroSigma()) << " " << fmt("%.9g", spec.imu.accelSigma()) << "\n";
    if (!bias) throw std::runtime_error("cannot write " + args.out + "/imu_bias.txt");
  }
  std::unique_ptr<EcdEventWriter> ecd_events;  // streamed: memory does not grow with the sequence
  if (want_ecd) ecd_events = std::make_unique<EcdEventWriter>(args.out + "/events.txt");
  EventVector shifted;
  EventVector chunk;
  const int64_t chunk_ns = 100000000;  // 0.1 s
  const int64_t packet_ns = secToNs(args.packet_ms * 1e-3);
  uint64_t n_events = 0;
  const auto wall0 = std::chrono::steady_clock::now();
  auto last_report = wall0;
  int64_t next_gt = 0, next_imu = 0, next_info = 0, next_odom_step = 0;
  std::unique_ptr<sim::FrameSimulator> frames;
  std::ofstream images_txt;
  int n_frames = 0;
  if (args.images) {
    sim::FrameSimulatorOptions fo;
    fo.seed = spec.seed;
    frames = std::make_unique<sim::FrameSimulator>(&simulator, fo);
    if (want_ecd) {
      makeDirs(args.out + "/images");
      images_txt.open(args.out + "/images.txt");
      if (!images_txt) throw std::runtime_error("cannot write " + args.out + "/images.txt");
      images_txt
          << "# timestamp [s] filename (mono8 APS frames, 25 Hz, stamp = middle of the exposure)\n";
    }
  }
  for (int64_t t0 = 0; t0 < duration_ns; t0 += chunk_ns) {
    const int64_t t1 = std::min(duration_ns, t0 + chunk_ns);
    chunk.clear();
    simulator.simulateUntil(t1, &chunk);
    n_events += chunk.size();
    if (want_ecd) {
      shifted = chunk;
      for (PixelEvent& e : shifted) e.t_ns += kEpochNs;
      ecd_events->write(shifted);
    }
    if (want_bag) {
      // Event packets: fixed windows of packet_ns; stamp = window end (the last event's time
      // bound).
      size_t i = 0;
      for (int64_t w0 = t0; w0 < t1; w0 += packet_ns) {
        const int64_t w1 = std::min(t1, w0 + packet_ns);
        size_t j = i;
        while (j < chunk.size() && chunk[j].t_ns <= w1) ++j;
        if (j > i) {
          EventArray msg =
              eventsToMsg(chunk, i, j, calib.width, calib.height, "davis", kEpochNs, w1);
          msg.header.seq = packet_seq++;  // numbered as a recording of the driver's publisher
          bag.write("/dvs/events", msg.header.stamp, msg);
        }
        i = j;
      }
      for (; next_info <= t1 && next_info <= duration_ns; next_info += kNsPerSec) {
        sensor_msgs::CameraInfo m = info;
        m.header.stamp = stamp(next_info);
        bag.write("/dvs/camera_info", m.header.stamp, m);
      }
      for (; next_gt <= t1; next_gt += 5000000) {
        geometry_msgs::PoseStamped m;
        m.header.stamp = stamp(next_gt);
        m.header.frame_id = "odom";
        m.pose = poseToMsg(trajectory.T_odom_base(next_gt));
        bag.write("/gt/pose", m.header.stamp, m);
      }
      for (; davis_imu && next_davis_imu <= t1; next_davis_imu += davis_imu->periodNs()) {
        const ImuSample z = davis_imu->measure(next_davis_imu);
        if (imu_txt) imu_txt->write({z.t_ns + kEpochNs, z.accel, z.gyro});
        sensor_msgs::Imu m;
        m.header.stamp = stamp(next_davis_imu);
        m.header.frame_id = "davis";
        m.orientation_covariance[0] = -1;  // no orientation
        m.angular_velocity = vectorToMsg(z.gyro);
        m.linear_acceleration = vectorToMsg(z.accel);
        for (int k = 0; k < 3; ++k) {
          m.angular_velocity_covariance[4 * k] = spec.imu.gyroSigma() * spec.imu.gyroSigma();
          m.linear_acceleration_covariance[4 * k] = spec.imu.accelSigma() * spec.imu.accelSigma();
        }
        bag.write("/dvs/imu", m.header.stamp, m);
      }
      for (; !davis_imu && next_imu <= t1; next_imu += 5000000) {
        const int64_t h = 1000000;
        const int64_t ta = std::max<int64_t>(0, next_imu - h), tb = ta + 2 * h;
        const Pose3 Ta = simulator.T_odom_cam(ta), Tm = simulator.T_odom_cam(ta + h),
                    Tb = simulator.T_odom_cam(tb);
        const Eigen::AngleAxisd aa(Ta.linear().transpose() * Tb.linear());
        const Vec3 w_C = aa.axis() * aa.angle() / (2e-9 * h);
        const Vec3 a_odom =
            (Ta.translation() - 2 * Tm.translation() + Tb.translation()) / std::pow(1e-9 * h, 2);
        const Vec3 f_C = Tm.linear().transpose() * (a_odom + Vec3(0, 0, 9.81));
        sensor_msgs::Imu m;
        m.header.stamp = stamp(next_imu);
        m.header.frame_id = "davis";
        m.orientation_covariance[0] = -1;  // no orientation
        m.angular_velocity =
            vectorToMsg(w_C + gyro_bias + gyro_sigma * Vec3(n01(rng), n01(rng), n01(rng)));
        m.linear_acceleration = vectorToMsg(f_C + accel_sigma * Vec3(n01(rng), n01(rng), n01(rng)));
        for (int k = 0; k < 3; ++k) {
          m.angular_velocity_covariance[4 * k] = gyro_sigma * gyro_sigma;
          m.linear_acceleration_covariance[4 * k] = accel_sigma * accel_sigma;
        }
        bag.write("/dvs/imu", m.header.stamp, m);
      }
      // Wheel odometry, integrated at 1 kHz, published at 50 Hz.
      for (; next_odom_step < t1; next_odom_step += 1000000) {
        const int64_t tm = next_odom_step + 500000;
        const double v = trajectory.speed(tm) * odom_scale +
                         (trajectory.speed(tm) > 0 ? odom_v_sigma * n01(rng) : 0.0);
        const double w =
            trajectory.yawRate(tm) + (trajectory.speed(tm) > 0 ? odom_w_sigma * n01(rng) : 0.0);
        const Vec2 d = arcT_Vr_Vt(w, v, 1e-3).translation().head<2>();
        odom_pose.x() += std::cos(odom_pose.z()) * d.x() - std::sin(odom_pose.z()) * d.y();
        odom_pose.y() += std::sin(odom_pose.z()) * d.x() + std::cos(odom_pose.z()) * d.y();
        odom_pose.z() = wrapAngle(odom_pose.z() + w * 1e-3);
        odom_v_sum += v;
        odom_w_sum += w;
        ++odom_n;
        const int64_t t_pub = next_odom_step + 1000000;
        if (t_pub % 20000000 == 0) {
          nav_msgs::Odometry m;
          m.header.stamp = stamp(t_pub);
          m.header.frame_id = "odom";
          m.child_frame_id = "base_link";
          m.pose.pose = poseToMsg(planarPose(odom_pose.x(), odom_pose.y(), odom_pose.z()));
          m.twist.twist.linear.x = odom_n ? odom_v_sum / odom_n : 0.0;
          m.twist.twist.angular.z = odom_n ? odom_w_sum / odom_n : 0.0;
          m.twist.covariance[0] = odom_v_sigma * odom_v_sigma;
          m.twist.covariance[35] = odom_w_sigma * odom_w_sigma;
          bag.write("/odom", m.header.stamp, m);
          odom_v_sum = odom_w_sum = 0;
          odom_n = 0;
        }
      }
    }
    // ECD only: the DAVIS IMU still goes to imu.txt.
    for (; davis_imu && !want_bag && next_davis_imu <= t1;
         next_davis_imu += davis_imu->periodNs()) {
      const ImuSample z = davis_imu->measure(next_davis_imu);
      if (imu_txt) imu_txt->write({z.t_ns + kEpochNs, z.accel, z.gyro});
    }
    if (frames) {
      // APS frames (sim_frames.cpp): exposure blur, shot/read/fixed-pattern noise, auto-exposure.
      for (const sim::SimulatedFrame& f : frames->simulateUntil(t1)) {
        if (want_bag) {
          sensor_msgs::Image m;
          m.header.stamp = stamp(f.t_ns);
          m.header.frame_id = "davis";
          m.height = calib.height;
          m.width = calib.width;
          m.encoding = "mono8";
          m.step = calib.width;
          m.data.assign(f.image.datastart, f.image.dataend);
          bag.write("/dvs/image_raw", m.header.stamp, m);
        }
        if (want_ecd) {
          char name[64];
          std::snprintf(name, sizeof(name), "images/frame_%08d.png", n_frames);
          if (!cv::imwrite(args.out + "/" + name, f.image))
            throw std::runtime_error(std::string("cannot write ") + name);
          images_txt << fmt("%.9f", nsToSec(f.t_ns + kEpochNs)) << " " << name << "\n";
        }
        ++n_frames;
      }
    }
    const auto now = std::chrono::steady_clock::now();
    if (std::chrono::duration<double>(now - last_report).count() > 2.0 || t1 == duration_ns) {
      last_report = now;
      std::fprintf(stderr, "[vwe_vo_sim] t = %6.2f / %.2f s, %.2f M events\n", nsToSec(t1),
                   nsToSec(duration_ns), n_events * 1e-6);
    }
  }
  const double wall =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  if (want_bag) bag.close();

  // Ground truth at 200 Hz, always; ECD files.
  Trajectory3 gt;
  for (int64_t t = 0; t <= duration_ns; t += 5000000)
    gt.push_back({t + kEpochNs, trajectory.T_odom_base(t)});
  writeTum(args.out + "/groundtruth.txt", gt);
  if (want_ecd) {
    ecd_events.reset();
    imu_txt.reset();
    EcdCalibration ec{calib.fx,
                      calib.fy,
                      calib.cx,
                      calib.cy,
                      calib.distortion[0],
                      calib.distortion[1],
                      calib.distortion[2],
                      calib.distortion[3],
                      calib.distortion[4]};
    writeEcdCalibration(args.out + "/calib.txt", ec);
    writePoseLine(args.out + "/extrinsics.txt", T_base_cam);
  }
  if (!args.depth_times.empty()) {
    makeDirs(args.out + "/depth");
    std::ofstream list(args.out + "/depth/depth_times.txt");
    list << "# t[s] file (16-bit PNG, depth z in the camera frame in millimetres, 0 = nothing "
            "hit)\n";
    for (double t : args.depth_times) {
      const int64_t t_ns = secToNs(t);
      if (t_ns > trajectory.durationNs())
        throw std::invalid_argument("--depth-times: " + fmt("%g", t) +
                                    " s is after the sequence end");
      const cv::Mat1f z = simulator.depthMap(t_ns);
      cv::Mat1w mm(z.rows, z.cols);
      for (int y = 0; y < z.rows; ++y)
        for (int x = 0; x < z.cols; ++x)
          mm(y, x) = static_cast<uint16_t>(std::clamp(std::lround(z(y, x) * 1000.0), 0L, 65535L));
      const std::string name = "depth_" + fmt("%.6f", t) + ".png";
      if (!cv::imwrite(args.out + "/depth/" + name, mm))
        throw std::runtime_error("cannot write " + name);
      list << fmt("%.9f", nsToSec(t_ns + kEpochNs)) << " " << name << "\n";
    }
  }
  const double sim_s = nsToSec(duration_ns);
  const auto& st = simulator.stats();
  std::fprintf(
      stderr,
      "[vwe_vo_sim] done: %llu events (%llu noise, %llu refractory drops), %.0f events/s "
      "simulated, "
      "%llu renders, wall %.2f s, real-time factor %.3f (path %.1f m)\n",
      static_cast<unsigned long long>(n_events), static_cast<unsigned long long>(st.noise_events),
      static_cast<unsigned long long>(st.refractory_drops), n_events / sim_s,
      static_cast<unsigned long long>(st.renders), wall, wall / sim_s, trajectory.pathLength());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(parseArgs(argc, argv));
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "vwe_vo_sim: %s\n", e.what());
    usage(std::cerr);
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "vwe_vo_sim: error: %s\n", e.what());
    return 1;
  }
}
