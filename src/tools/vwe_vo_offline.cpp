// vwe_vo_offline: runs the pipeline synchronously at full speed over a rosbag or an Event
// Camera Dataset folder and writes trajectories, arcs and a JSON report.
//   vwe_vo_offline (--bag FILE | --ecd DIR) [--config YAML] [--nominal-speed V] --out OUTDIR
#include <nav_msgs/Odometry.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sys/stat.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>

#include "vwe_vo/EventArray.h"
#include "vwe_vo/io/config.h"
#include "vwe_vo/io/files.h"
#include "vwe_vo/pipeline/offline_pipeline.h"
#include "vwe_vo/ros/conversions.h"

namespace {

const char* kUsage =
    "usage: vwe_vo_offline (--bag FILE | --ecd DIR) [--config YAML] [--nominal-speed V] --out "
    "OUTDIR\n"
    "                      [--use-odom] [--frontend-only] [--backend-inline] [--events-topic T] "
    "[--odom-topic T]\n"
    "                      [--imu-topic T] [--no-map] [--depth-png] [--baseline] [--baseline-only] "
    "[--image-topic T] [--quiet]\n"
    "                      [--start S] [--truth-arcs GT.tum [--truth-arcs-blend A]] "
    "[--no-follow-backend] [--use-imu]\n"
    "  Runs the front-end and the back-end over recorded events at full speed (a bag from S "
    "seconds\n"
    "  after its start with --start, as a live system that starts late). Writes\n"
    "  OUTDIR/frontend.tum, OUTDIR/arcs.csv, OUTDIR/report.json, OUTDIR/options.yaml (the options\n"
    "  in use, every key) and (unless --frontend-only)\n"
    "  OUTDIR/backend.tum, OUTDIR/odom.tum (the continuous odometry backend_node would publish\n"
    "  live) and OUTDIR/spline.json. Then (unless --no-map) a second pass over the\n"
    "  events maps them (EMVS) on the back-end's trajectory (the front-end's with "
    "--frontend-only)\n"
    "  into OUTDIR/map.ply (binary PLY, odom frame); --depth-png adds OUTDIR/depth/depth_NNNN.png\n"
    "  per keyframe. The back-end runs on its own thread beside the front-end (as the nodes do "
    "live);\n"
    "  --backend-inline runs it in the front-end's thread after each event chunk (same results).\n"
    "  As frontend_node (~follow_backend, on by default), the front-end takes the back-end's "
    "speed\n"
    "  after each refinement unless --use-odom gives it; --no-follow-backend keeps its nominal "
    "speed.\n"
    "  A bag cut short (a killed `rosbag record`, FILE.bag.active, no index) is reindexed into a\n"
    "  temporary copy with `rosbag reindex` and read up to its last complete chunk (a warning "
    "says\n"
    "  how many seconds that recovered). Event timestamps that jump back up to\n"
    "  input.max_backward_jump_s are dropped and counted (report.json \"input\"), larger jumps\n"
    "  and gaps longer than input.max_gap_s reset; both are warned about on the terminal.\n"
    "  No events at all (an empty events.txt, no events topic, --start past the end) is an error.\n"
    "  An ECD folder holds events.txt or events.txt.gz, calib.txt and optionally\n"
    "  extrinsics.txt (T_base_cam, overrides the config).\n"
    "  --baseline: also runs the frame-based baseline (KLT + 1-point Ackermann RANSAC) on the APS\n"
    "  frames (ECD: images.txt + images/, bag: /dvs/image_raw) and writes OUTDIR/baseline.tum and "
    "a\n"
    "  \"baseline\" stage in report.json; --baseline-only skips the event pipeline.\n"
    "  --truth-arcs (research): the back-end gets the ground truth's yaw rate over each arc's "
    "window,\n"
    "  moved towards the front-end's by A (default 0): truth + A * (front-end - truth). A = 0 "
    "shows\n"
    "  the back-end objective's own bias, A = 0.5 how much of a front-end error it corrects.\n"
    "  The front-end's outputs are unchanged; report.json says how many arcs were replaced.\n"
    "  --use-imu: the back-end fuses the IMU (bag: --imu-topic, ECD: DIR/imu.txt; config imu:):\n"
    "  the gyro's yaw rate as a measurement with its bias estimated, pitch and roll from gyro and\n"
    "  accelerometer in backend.tum and odom.tum (with --use-odom: without it the vehicle's\n"
    "  acceleration is unknown and the pose stays planar); report.json stages.backend.imu has\n"
    "  the bias.\n";

/// Duration of the ECD folder's ground truth if there is one (for the progress line), else 0.
double groundTruthDuration(const std::string& dir) {
  if (!vwe_vo::fileExists(dir + "/groundtruth.txt")) return 0.0;
  try {
    const vwe_vo::Trajectory3 gt = vwe_vo::readTum(dir + "/groundtruth.txt");
    return vwe_vo::dtSec(gt.back().t_ns, gt.front().t_ns);
  } catch (const std::exception&) {
    return 0.0;
  }
}

/// Feeds the ECD folder's images.txt (`t images/frame_00000000.png`, # comments) to the pipeline.
size_t feedEcdFrames(const std::string& dir, vwe_vo::OfflinePipeline* pipeline) {
  const std::string list = dir + "/images.txt";
  std::ifstream in(list);
  if (!in)
    throw std::runtime_error("--baseline: cannot open " + list +
                             " (simulate with vwe_vo_sim --images)");
  std::string line;
  size_t n = 0, line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ss(line);
    double t = 0;
    std::string name;
    if (!(ss >> t >> name))
      throw std::runtime_error(list + ":" + std::to_string(line_no) + ": expected `t file`");
    const cv::Mat img = cv::imread(dir + "/" + name, cv::IMREAD_UNCHANGED);
    if (img.empty())
      throw std::runtime_error(list + ":" + std::to_string(line_no) + ": cannot read " + dir + "/" +
                               name);
    if (img.type() != CV_8UC1)
      throw std::runtime_error(list + ":" + std::to_string(line_no) + ": " + name +
                               " is not an 8-bit mono image");
    try {
      pipeline->addFrame(vwe_vo::secToNs(t), img);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(list + ":" + std::to_string(line_no) + ": " + e.what());
    }
    ++n;
  }
  if (n == 0) throw std::runtime_error("--baseline: " + list + " lists no frames");
  return n;
}

/// A bag to read: the file itself, or, for one cut short, a reindexed temporary copy (removed
/// when this goes out of scope).
class BagFile {
 public:
  explicit BagFile(const std::string& path) : path_(path) {
    if (!vwe_vo::fileExists(path)) throw std::runtime_error(path + ": no such file");
    try {
      rosbag::Bag bag(path, rosbag::bagmode::Read);
      return;
    } catch (const rosbag::BagException& e) {
      // A killed `rosbag record` leaves no index (BagUnindexedException) or, for a copy cut
      // short, an index position past the end (BagIOException). Either way: reindex a copy.
      std::fprintf(
          stderr,
          "[vwe_vo_offline] warning: %s cannot be opened as it is (%s): reindexing a copy\n",
          path.c_str(), e.what());
    }
    const char* tmp = std::getenv("TMPDIR");
    std::string dir = std::string(tmp && *tmp ? tmp : "/tmp") + "/vwe_vo_reindex_XXXXXX";
    if (!mkdtemp(&dir[0]))
      throw std::runtime_error("cannot create a temporary folder " + dir + " to reindex " + path);
    temp_dir_ = dir;
    try {
      recover(path);
    } catch (...) {
      std::error_code ec;
      std::filesystem::remove_all(temp_dir_, ec);
      throw;
    }
  }
  ~BagFile() {
    std::error_code ec;
    if (!temp_dir_.empty()) std::filesystem::remove_all(temp_dir_, ec);
  }
  BagFile(const BagFile&) = delete;
  BagFile& operator=(const BagFile&) = delete;
  const std::string& path() const { return path_; }
  bool recovered() const { return !temp_dir_.empty(); }
  double recoveredSeconds() const { return recovered_s_; }

 private:
  void recover(const std::string& path) {
    // rosbag's C++ API has no reindex; the python tool (the system python with its ROS modules)
    // has.
    if (path.find('\'') != std::string::npos)
      throw std::runtime_error(path + ": cannot reindex a path with a quote");
    const std::string log = temp_dir_ + "/reindex.log";
    const std::string cmd =
        "PATH=/usr/bin:$PATH /usr/bin/python3 /usr/bin/rosbag reindex -q --output-dir '" +
        temp_dir_ + "' '" + path + "' > '" + log + "' 2>&1";
    const int rc = std::system(cmd.c_str());
    path_ = temp_dir_ + "/" + std::filesystem::path(path).filename().string();
    if (rc != 0 || !vwe_vo::fileExists(path_)) {
      std::ifstream in(log);
      const std::string why((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      throw std::runtime_error(
          path + ": not a readable bag, and `rosbag reindex` could not recover it: " + why);
    }
    rosbag::Bag bag(path_, rosbag::bagmode::Read);
    rosbag::View all(bag);
    recovered_s_ = all.size() > 0 ? (all.getEndTime() - all.getBeginTime()).toSec() : 0.0;
    if (all.size() == 0)
      throw std::runtime_error(path +
                               ": cut short before its first complete chunk: no message to read");
    std::fprintf(stderr,
                 "[vwe_vo_offline] warning: %s was cut short (no index): %.2f s of data recovered "
                 "(%u messages, up to its last complete chunk)\n",
                 path.c_str(), recovered_s_, all.size());
  }
  std::string path_, temp_dir_;
  double recovered_s_ = 0.0;
};

/// Prints the input's throttled warnings about timestamp jumps.
void printInputWarning(vwe_vo::OfflinePipeline* pipeline, bool end = false) {
  const std::string w = end ? pipeline->inputSummary() : pipeline->takeInputWarning();
  if (w.empty()) return;
  std::string line;
  std::istringstream lines(w);
  while (std::getline(lines, line))
    std::fprintf(stderr, "\n[vwe_vo_offline] warning: %s", line.c_str());
  std::fprintf(stderr, "\n");
}

class Progress {
 public:
  explicit Progress(bool quiet) : quiet_(quiet), last_(std::chrono::steady_clock::now()) {}
  void update(const vwe_vo::OfflinePipeline& p, double total_s) {
    if (quiet_) return;
    const auto now = std::chrono::steady_clock::now();
    if (std::chrono::duration<double>(now - last_).count() < 0.5) return;
    last_ = now;
    const double t = p.firstTime() >= 0 ? vwe_vo::dtSec(p.lastTime(), p.firstTime()) : 0.0;
    std::fprintf(stderr, "\r[vwe_vo_offline] %6.1f / %.1f s of data, %zu windows, %.1f M events   ",
                 t, total_s, p.arcs().size(), p.events() * 1e-6);
  }
  void done() {
    if (!quiet_) std::fprintf(stderr, "\n");
  }

 private:
  bool quiet_;
  std::chrono::steady_clock::time_point last_;
};

/// Adds the wall time of f() to *total_s and returns what f returns.
template <typename F>
auto timed(double* total_s, F&& f) {
  struct Add {
    double* total_s;
    std::chrono::steady_clock::time_point t0 = std::chrono::steady_clock::now();
    ~Add() {
      *total_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    }
  } add{total_s};
  return f();
}

}  // namespace

int main(int argc, char** argv) {
  std::map<std::string, std::string> args;
  bool use_odom = false, quiet = false, frontend_only = false, backend_inline = false, map = true,
       depth_png = false;
  bool baseline = false, baseline_only = false, follow_backend = true, use_imu = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      std::cout << kUsage;
      return 0;
    } else if (a == "--use-odom") {
      use_odom = true;
    } else if (a == "--frontend-only") {
      frontend_only = true;
    } else if (a == "--backend-inline") {
      backend_inline = true;
    } else if (a == "--no-map") {
      map = false;
    } else if (a == "--depth-png") {
      depth_png = true;
    } else if (a == "--baseline") {
      baseline = true;
    } else if (a == "--baseline-only") {
      baseline = baseline_only = true;
    } else if (a == "--use-imu") {
      use_imu = true;
    } else if (a == "--no-follow-backend") {
      follow_backend = false;
    } else if (a == "--quiet") {
      quiet = true;
    } else if ((a == "--bag" || a == "--ecd" || a == "--config" || a == "--nominal-speed" ||
                a == "--out" || a == "--events-topic" || a == "--odom-topic" ||
                a == "--imu-topic" || a == "--image-topic" || a == "--start" ||
                a == "--truth-arcs" || a == "--truth-arcs-blend") &&
               i + 1 < argc) {
      args[a] = argv[++i];
    } else {
      std::cerr << "vwe_vo_offline: unknown or incomplete option '" << a << "'\n" << kUsage;
      return 2;
    }
  }
  if (args.count("--bag") == args.count("--ecd") || !args.count("--out")) {
    std::cerr << "vwe_vo_offline: give exactly one of --bag or --ecd, and --out\n" << kUsage;
    return 2;
  }
  double start_s = 0.0;
  if (args.count("--start")) {
    char* end = nullptr;
    start_s = std::strtod(args["--start"].c_str(), &end);
    if (end == args["--start"].c_str() || *end != '\0' || !(start_s >= 0) || !args.count("--bag")) {
      std::cerr << "vwe_vo_offline: --start needs a number of seconds >= 0 and a --bag (got '"
                << args["--start"] << "')\n";
      return 2;
    }
  }
  double truth_blend = 0.0;
  if (args.count("--truth-arcs-blend")) {
    char* end = nullptr;
    truth_blend = std::strtod(args["--truth-arcs-blend"].c_str(), &end);
    if (end == args["--truth-arcs-blend"].c_str() || *end != '\0' || !std::isfinite(truth_blend) ||
        !args.count("--truth-arcs") || frontend_only) {
      std::cerr << "vwe_vo_offline: --truth-arcs-blend needs a finite number, --truth-arcs and the "
                   "back-end (got '"
                << args["--truth-arcs-blend"] << "')\n";
      return 2;
    }
  }
  if (use_imu && frontend_only) {
    std::cerr
        << "vwe_vo_offline: --use-imu feeds the back-end: it cannot go with --frontend-only\n";
    return 2;
  }
  if (args.count("--truth-arcs") && frontend_only) {
    std::cerr
        << "vwe_vo_offline: --truth-arcs feeds the back-end: it cannot go with --frontend-only\n";
    return 2;
  }
  try {
    vwe_vo::PipelineConfig cfg = vwe_vo::loadPipelineConfig(
        args.count("--config") ? args["--config"] : vwe_vo::defaultConfigDir() + "/vwe_vo.yaml");
    cfg.frontend_only = frontend_only;
    cfg.backend_thread = !backend_inline;
    for (const auto& w : cfg.warnings) std::cerr << "vwe_vo_offline: warning: " << w << "\n";
    if (args.count("--nominal-speed")) {
      cfg.frontend.nominal_speed_mps = std::stod(args["--nominal-speed"]);
      cfg.frontend.validate();
      cfg.baseline.nominal_speed_mps = cfg.frontend.nominal_speed_mps;
    }
    const auto wall0 = std::chrono::steady_clock::now();
    double read_s = 0;  // reading and decoding the input (report.json input.read_s)
    Progress progress(quiet);
    nlohmann::json input;
    std::string ecd_events;
    std::unique_ptr<BagFile> bag_file;
    if (args.count("--ecd")) {
      const std::string dir = args["--ecd"];
      const vwe_vo::EcdCalibration c = vwe_vo::readEcdCalibration(dir + "/calib.txt");
      cfg.camera.fx = c.fx, cfg.camera.fy = c.fy, cfg.camera.cx = c.cx, cfg.camera.cy = c.cy;
      cfg.camera.distortion = {c.k1, c.k2, c.p1, c.p2, c.k3};
      if (vwe_vo::fileExists(dir + "/extrinsics.txt"))
        cfg.T_base_cam = vwe_vo::readPoseLine(dir + "/extrinsics.txt");
      const std::string events_path =
          vwe_vo::fileExists(dir + "/events.txt") ? dir + "/events.txt" : dir + "/events.txt.gz";
      if (!quiet) std::fprintf(stderr, "[vwe_vo_offline] reading %s\n", events_path.c_str());
      ecd_events = events_path;
      input = {{"ecd", dir}};
    }
    vwe_vo::OfflinePipeline pipeline(cfg);
    vwe_vo::FollowOptions follow;
    follow.follow_backend = follow_backend;
    pipeline.setFrontendFollowsBackend(follow, use_odom);
    pipeline.setSpeedsMeasured(use_odom);
    if (args.count("--truth-arcs")) {
      pipeline.setBackendArcsFromTruth(vwe_vo::readTum(args["--truth-arcs"]), truth_blend);
    }
    if (baseline) pipeline.enableBaseline();
    if (use_imu) pipeline.enableImu();
    const vwe_vo::Pose3 T_base_imu = cfg.T_base_cam * cfg.imu.T_cam_imu();
    size_t frames = 0;
    if (args.count("--ecd") && baseline) frames = feedEcdFrames(args["--ecd"], &pipeline);
    if (args.count("--ecd")) {
      if (!baseline_only) {
        // Streamed in chunks: memory does not grow with the length of the recording.
        const double total = groundTruthDuration(args["--ecd"]);
        vwe_vo::EcdEventReader reader(ecd_events, cfg.camera.width, cfg.camera.height);
        vwe_vo::EventVector chunk;
        std::vector<vwe_vo::ImuSample> imu;
        const auto readChunk = [&] {
          return timed(&read_s, [&] { return reader.read(50000, &chunk); });
        };
        if (use_imu) {
          const std::string imu_path = args["--ecd"] + "/imu.txt";
          if (!vwe_vo::fileExists(imu_path)) throw std::runtime_error("--use-imu: no " + imu_path);
          imu = timed(&read_s, [&] { return vwe_vo::readEcdImu(imu_path); });
          input["imu_samples"] = imu.size();
        }
        size_t next_imu = 0;
        while (readChunk() > 0) {
          // The IMU in time order with the events: the samples up to the chunk's newest event.
          for (; next_imu < imu.size() && imu[next_imu].t_ns <= chunk.back().t_ns; ++next_imu) {
            const vwe_vo::ImuSample& s = imu[next_imu];
            pipeline.addGyro(s.t_ns, (T_base_imu.linear() * s.gyro).z());
            pipeline.addImu(s);
          }
          pipeline.addEvents(chunk);
          printInputWarning(&pipeline);
          progress.update(pipeline, total);
        }
        if (pipeline.input().stats().events_in == 0)
          throw std::runtime_error(ecd_events +
                                   ": no events (the file is empty or holds only comments)");
      }
    } else {
      const std::string events_topic =
          args.count("--events-topic") ? args["--events-topic"] : "/dvs/events";
      const std::string odom_topic = args.count("--odom-topic") ? args["--odom-topic"] : "/odom";
      const std::string imu_topic = args.count("--imu-topic") ? args["--imu-topic"] : "/dvs/imu";
      const std::string image_topic =
          args.count("--image-topic") ? args["--image-topic"] : "/dvs/image_raw";
      bag_file = std::make_unique<BagFile>(args["--bag"]);
      const auto read0 = std::chrono::steady_clock::now();
      rosbag::Bag bag(bag_file->path(), rosbag::bagmode::Read);
      std::vector<std::string> topics = {odom_topic, imu_topic};
      if (!baseline_only) topics.push_back(events_topic);
      if (baseline) topics.push_back(image_topic);
      const ros::Time begin =
          rosbag::View(bag, rosbag::TopicQuery(topics)).getBeginTime() + ros::Duration(start_s);
      rosbag::View view(bag, rosbag::TopicQuery(topics), begin);
      // An empty view (--start past the end) has no span: the no-events error below names it.
      const double total =
          view.size() == 0 ? 0.0 : (view.getEndTime() - view.getBeginTime()).toSec();
      size_t packets = 0;
      vwe_vo::EventVector events;
      vwe_vo::EventConversionStats conv;
      read_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - read0).count();
      for (auto it = timed(&read_s, [&] { return view.begin(); }); it != view.end();
           timed(&read_s, [&] { ++it; })) {
        const rosbag::MessageInstance& m = *it;
        if (baseline && m.getTopic() == image_topic) {
          if (const auto img =
                  timed(&read_s, [&] { return m.instantiate<sensor_msgs::Image>(); })) {
            pipeline.addFrame(vwe_vo::toNs(img->header.stamp), vwe_vo::imageFromMsg(*img));
            ++frames;
          }
        } else if (!baseline_only && m.getTopic() == events_topic) {
          const auto msg = timed(&read_s, [&] { return m.instantiate<vwe_vo::EventArray>(); });
          if (!msg) continue;
          if (int(msg->width) != cfg.camera.width || int(msg->height) != cfg.camera.height)
            throw std::runtime_error("EventArray is " + std::to_string(msg->width) + "x" +
                                     std::to_string(msg->height) + " but the calibration is " +
                                     std::to_string(cfg.camera.width) + "x" +
                                     std::to_string(cfg.camera.height));
          timed(&read_s, [&] { vwe_vo::eventsFromMsg(*msg, &events, &conv); });
          pipeline.addEvents(events);
          printInputWarning(&pipeline);
          ++packets;
          progress.update(pipeline, total);
        } else if (use_odom && m.getTopic() == odom_topic) {
          if (const auto o = timed(&read_s, [&] { return m.instantiate<nav_msgs::Odometry>(); })) {
            const vwe_vo::OdometrySample s = vwe_vo::odometryFromMsg(*o);
            pipeline.addOdometry(s.t_ns, s.v_mps, s.yaw_rate_rad_s);
          }
        } else if (m.getTopic() == imu_topic) {
          if (const auto imu = timed(&read_s, [&] { return m.instantiate<sensor_msgs::Imu>(); })) {
            const vwe_vo::GyroSample g = vwe_vo::gyroFromMsg(*imu, T_base_imu);
            pipeline.addGyro(g.t_ns, g.yaw_rate_rad_s);
            if (use_imu) pipeline.addImu(vwe_vo::imuFromMsg(*imu));
          }
        }
      }
      input = {{"bag", args["--bag"]},
               {"start_s", start_s},
               {"event_packets", packets},
               {"events_dropped_in_conversion", conv.dropped}};
      if (bag_file->recovered()) input["recovered_from_unindexed_s"] = bag_file->recoveredSeconds();
      if (!baseline_only && pipeline.input().stats().events_in == 0) {
        std::string have;
        for (const rosbag::ConnectionInfo* c : rosbag::View(bag).getConnections())
          if (have.find(" " + c->topic + " ") == std::string::npos) have += " " + c->topic + " ";
        throw std::runtime_error(
            args["--bag"] + ": no events on " + events_topic +
            (start_s > 0 ? " after --start " + args["--start"] + " s" : std::string()) + " (" +
            std::to_string(packets) +
            " messages; topics in the bag:" + (have.empty() ? std::string(" none") : have) + ")");
      }
      if (baseline && frames == 0)
        throw std::runtime_error("--baseline: no " + image_topic + " frames in " + args["--bag"]);
    }
    if (baseline) input["frames"] = frames;
    pipeline.finish();
    progress.done();
    printInputWarning(&pipeline, true);
    const vwe_vo::TimestampPolicyStats& ts = pipeline.input().stats();
    if (ts.backward_jumps + ts.resets > 0)
      std::fprintf(stderr,
                   "[vwe_vo_offline] input: %zu backward timestamp jumps absorbed (%zu events "
                   "dropped, largest "
                   "%.1f ms), %zu resets (%zu jumps back, %zu gaps)\n",
                   ts.backward_jumps, ts.events_absorbed, ts.largest_backward_jump_s * 1e3,
                   ts.resets, ts.resets_backward, ts.resets_gap);
    if (map) {
      // Second pass: the mapper needs the final trajectory, and the events are not kept.
      if (!quiet) std::fprintf(stderr, "[vwe_vo_offline] mapping\n");
      pipeline.startMapping(depth_png ? args["--out"] + "/depth" : "");
      vwe_vo::EventVector chunk;
      if (args.count("--ecd")) {
        vwe_vo::EcdEventReader reader(ecd_events, cfg.camera.width, cfg.camera.height);
        while (timed(&read_s, [&] { return reader.read(200000, &chunk); }) > 0)
          pipeline.addMappingEvents(chunk);
      } else {
        const std::string events_topic =
            args.count("--events-topic") ? args["--events-topic"] : "/dvs/events";
        const auto read0 = std::chrono::steady_clock::now();
        rosbag::Bag bag(bag_file->path(), rosbag::bagmode::Read);
        const ros::Time begin =
            rosbag::View(bag, rosbag::TopicQuery({events_topic})).getBeginTime() +
            ros::Duration(start_s);
        rosbag::View view(bag, rosbag::TopicQuery({events_topic}), begin);
        vwe_vo::EventConversionStats conv;
        read_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - read0).count();
        for (auto it = timed(&read_s, [&] { return view.begin(); }); it != view.end();
             timed(&read_s, [&] { ++it; })) {
          const rosbag::MessageInstance& m = *it;
          const bool got = timed(&read_s, [&] {
            const auto msg = m.instantiate<vwe_vo::EventArray>();
            if (msg) vwe_vo::eventsFromMsg(*msg, &chunk, &conv);
            return msg != nullptr;
          });
          if (got) pipeline.addMappingEvents(chunk);
        }
      }
      pipeline.finishMapping();
    }
    const double wall =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    input["read_s"] = read_s;
    pipeline.writeOutputs(args["--out"], {{"input", input}, {"wall_s", wall}});
    {
      const std::string options_path = args["--out"] + "/options.yaml";
      std::ofstream options_file(options_path);
      options_file << "# The options in use (" << (cfg.path.empty() ? "defaults" : cfg.path)
                   << " and the command line)\n"
                   << YAML::Dump(vwe_vo::optionsToYaml(cfg)) << "\n";
      if (!options_file) throw std::runtime_error(options_path + ": cannot write");
    }
    const nlohmann::json r = pipeline.report();
    std::fprintf(stderr,
                 "[vwe_vo_offline] %zu events, %zu windows over %.1f s in %.2f s (real-time factor "
                 "%.3f) -> %s\n",
                 pipeline.events(), pipeline.arcs().size(), r["duration_s"].get<double>(),
                 pipeline.processingSeconds(), r["real_time_factor"].get<double>(),
                 args["--out"].c_str());
    if (pipeline.map())
      std::fprintf(stderr,
                   "[vwe_vo_offline] map: %zu points from %zu keyframes in %.2f s -> %s/map.ply\n",
                   pipeline.map()->size(), r["stages"]["mapping"]["keyframes"].get<size_t>(),
                   r["stages"]["mapping"]["processing_s"].get<double>(), args["--out"].c_str());
    if (baseline) {
      const auto& b = r["stages"]["baseline"];
      std::fprintf(stderr,
                   "[vwe_vo_offline] baseline: %zu frames, %zu ok, %zu lost, tracked %.2f, %.2f s "
                   "-> baseline.tum\n",
                   b["frames"].get<size_t>(), b["frames_ok"].get<size_t>(),
                   b["frames_lost"].get<size_t>(), b["tracked_fraction"].get<double>(),
                   b["processing_s"].get<double>());
    }
  } catch (const std::exception& e) {
    std::cerr << "\nvwe_vo_offline: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
