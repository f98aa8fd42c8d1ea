// Helpers of the rostests that replay a simulated rosbag into the nodes (frontend_bag_test,
// frontend_backend_bag_test, replay_launch_test): simulate a short bag into a temporary
// directory with vwe_vo_sim, run `rosbag play` / `roslaunch` / vwe_vo_offline as child processes,
// record topics with their arrival (ROS) time, and turn what was recorded into core trajectories
// for the core evaluator. Header-only.
#pragma once

#include <fcntl.h>
#include <geometry_msgs/PoseStamped.h>
#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <ros/ros.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "vwe_vo/eval/evaluation.h"
#include "vwe_vo/io/trajectory_io.h"
#include "vwe_vo/ros/conversions.h"

#ifndef VWE_VO_TOOLS_DIR
#error "VWE_VO_TOOLS_DIR (the directory of vwe_vo_sim and vwe_vo_offline) must be defined"
#endif

namespace vwe_vo {
namespace test {

/// A fresh directory under /tmp, removed with everything in it on destruction.
class TempDir {
 public:
  TempDir() {
    std::string pattern =
        (std::filesystem::temp_directory_path() / "vwe_vo_rostest_XXXXXX").string();
    if (!mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp failed for " + pattern);
    path_ = pattern;
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

inline std::string toolPath(const std::string& name) {
  return std::string(VWE_VO_TOOLS_DIR) + "/" + name;
}

/// Last `lines` lines of a text file that contain `needle` (for failure messages), without
/// rosbag's progress lines.
inline std::string tailOf(const std::string& path, size_t lines = 30,
                          const std::string& needle = "") {
  std::ifstream in(path);
  std::vector<std::string> all;
  for (std::string l; std::getline(in, l);)
    if (l.find("[RUNNING]") == std::string::npos && l.find("[DELAYED]") == std::string::npos &&
        l.find(needle) != std::string::npos)
      all.push_back(l);
  std::string out;
  for (size_t i = all.size() > lines ? all.size() - lines : 0; i < all.size(); ++i)
    out += all[i] + "\n";
  return out;
}

/// A child process in its own process group with stdout and stderr going to a log file.
class ChildProcess {
 public:
  ChildProcess(const std::vector<std::string>& argv, const std::string& log_path)
      : log_path_(log_path) {
    std::vector<char*> args;
    for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    const int fd = ::open(log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd < 0) throw std::runtime_error("cannot open " + log_path);
    pid_ = ::fork();
    if (pid_ < 0) throw std::runtime_error("fork failed for " + argv.front());
    if (pid_ == 0) {  // child: only async-signal-safe calls until exec
      ::setpgid(0, 0);
      ::dup2(fd, 1);
      ::dup2(fd, 2);
      ::execvp(args[0], args.data());
      ::_exit(127);
    }
    ::close(fd);
    ::setpgid(pid_, pid_);  // also here: no race with the child's own call
  }
  ~ChildProcess() { stop(); }
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  /// True while the child runs; reaps it (and keeps its exit code) once it has ended.
  bool running() {
    if (pid_ <= 0) return false;
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
      exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      pid_ = -1;
      return false;
    }
    return true;
  }
  /// Waits (wall time) for the child to end; false on timeout.
  bool wait(double timeout_s) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
    while (running()) {
      if (ros::WallTime::now() > end) return false;
      ros::WallDuration(0.05).sleep();
    }
    return true;
  }
  /// SIGINT to the whole process group (roslaunch shuts its nodes down), SIGKILL after 15 s.
  void stop() {
    if (!running()) return;
    ::kill(-pid_, SIGINT);
    if (wait(15.0)) return;
    ::kill(-pid_, SIGKILL);
    wait(5.0);
  }
  int exitCode() const { return exit_code_; }
  const std::string& logPath() const { return log_path_; }

 private:
  pid_t pid_ = -1;
  int exit_code_ = -1;
  std::string log_path_;
};

/// Runs a command line to its end; returns its exit code. Output goes to log_path.
inline int runToEnd(const std::vector<std::string>& argv, const std::string& log_path,
                    double timeout_s) {
  ChildProcess child(argv, log_path);
  if (!child.wait(timeout_s)) return -1;
  return child.exitCode();
}

/// A simulated standard sequence as a bag, with its ground truth (groundtruth.txt, the same
/// time base as the bag's stamps).
struct SimulatedBag {
  std::string bag_path, gt_path;
  Trajectory3 gt;
  double duration_s = 0;
};

/// Simulates `duration_s` of a standard sequence (fixed seed) into dir with vwe_vo_sim.
/// Throws std::runtime_error with the tail of the simulator's log if it fails.
inline SimulatedBag simulateBag(const std::string& dir, const std::string& sequence,
                                double duration_s) {
  const std::string log = dir + "/sim.log";
  std::ostringstream d;
  d << duration_s;
  const int rc = runToEnd({toolPath("vwe_vo_sim"), "--sequence", sequence, "--format", "bag",
                           "--duration", d.str(), "--out", dir},
                          log, 180.0);
  if (rc != 0)
    throw std::runtime_error("vwe_vo_sim exited with " + std::to_string(rc) + ":\n" + tailOf(log));
  SimulatedBag bag;
  bag.bag_path = dir + "/" + sequence + ".bag";
  bag.gt_path = dir + "/groundtruth.txt";
  bag.gt = readTum(bag.gt_path);
  bag.duration_s = dtSec(bag.gt.back().t_ns, bag.gt.front().t_ns);
  return bag;
}

/// Records every message of one topic with the ROS time (simulated under /use_sim_time) at which
/// it arrived.
template <class M>
class TopicRecorder {
 public:
  struct Stamped {
    ros::Time received;
    M msg;
  };
  TopicRecorder(ros::NodeHandle& nh, const std::string& topic, uint32_t queue = 10000) {
    sub_ = nh.subscribe<M>(topic, queue, [this](const boost::shared_ptr<const M>& m) {
      std::lock_guard<std::mutex> lock(mutex_);
      messages_.push_back({ros::Time::now(), *m});
    });
  }
  std::vector<Stamped> all() {
    std::lock_guard<std::mutex> lock(mutex_);
    return messages_;
  }
  std::vector<M> messages() {
    std::lock_guard<std::mutex> lock(mutex_);
    std::vector<M> out;
    for (const Stamped& s : messages_) out.push_back(s.msg);
    return out;
  }
  size_t size() {
    std::lock_guard<std::mutex> lock(mutex_);
    return messages_.size();
  }
  size_t numPublishers() const { return sub_.getNumPublishers(); }

 private:
  std::mutex mutex_;  // guards messages_
  std::vector<Stamped> messages_;
  ros::Subscriber sub_;  // last: unsubscribed before the messages go
};

/// Waits (wall time) until pred() holds; false on timeout.
template <class Pred>
bool waitUntil(Pred pred, double timeout_s) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
  while (!pred()) {
    if (ros::WallTime::now() > end) return false;
    ros::WallDuration(0.05).sleep();
  }
  return true;
}

/// Waits until `count()` has not changed for quiet_s (wall time), at most timeout_s.
template <class Count>
void waitUntilQuiet(Count count, double quiet_s, double timeout_s) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
  size_t last = count();
  ros::WallTime changed = ros::WallTime::now();
  while (ros::WallTime::now() < end && (ros::WallTime::now() - changed).toSec() < quiet_s) {
    ros::WallDuration(0.1).sleep();
    const size_t now = count();
    if (now != last) last = now, changed = ros::WallTime::now();
  }
}

inline Trajectory3 trajectoryOf(const std::vector<nav_msgs::Odometry>& odoms) {
  Trajectory3 out;
  for (const nav_msgs::Odometry& o : odoms)
    if (out.empty() || toNs(o.header.stamp) > out.back().t_ns)
      out.push_back({toNs(o.header.stamp), poseFromMsg(o.pose.pose)});
  return out;
}
inline Trajectory3 trajectoryOf(const std::vector<geometry_msgs::PoseStamped>& poses) {
  Trajectory3 out;
  for (const geometry_msgs::PoseStamped& p : poses)
    if (out.empty() || toNs(p.header.stamp) > out.back().t_ns)
      out.push_back({toNs(p.header.stamp), poseFromMsg(p.pose)});
  return out;
}

/// Rotation RMSE [deg/s] of the relative pose error over 1 s (the core evaluator,
/// docs/evaluation.md). Throws like computeRpe when the trajectories do not overlap enough.
inline double rotationRmseDegS(const Trajectory3& gt, const Trajectory3& est) {
  const EvaluationOptions options;
  return computeRpe(gt, est, options.delta_s, options).rot_rmse_deg_s;
}

/// Sorted differences of consecutive values (e.g. message stamps) in seconds.
inline std::vector<double> spacings(const std::vector<ros::Time>& times) {
  std::vector<double> out;
  for (size_t i = 1; i < times.size(); ++i) out.push_back((times[i] - times[i - 1]).toSec());
  std::sort(out.begin(), out.end());
  return out;
}
inline double median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

/// main() of the replay rostests: gtest with ROS and a two-thread spinner. Each suite plays its
/// bag in SetUpTestSuite and frees what it kept in TearDownTestSuite, while the spinner runs.
inline int runReplayTests(int argc, char** argv, const char* node_name) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, node_name);
  ros::AsyncSpinner spinner(2);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  spinner.stop();
  ros::shutdown();
  return result;
}

/// A suite that replays its bag once, in SetUpTestSuite, and whose tests inspect what was
/// recorded. A replay that threw fails every test with its message, so no test depends on the
/// order in which the others run. Replay has a `std::string error`; Play fills a Replay.
template <class Replay, void (*Play)(ros::NodeHandle&, Replay*)>
class ReplayedOnce : public testing::Test {
 protected:
  static void SetUpTestSuite() {
    replay = std::make_unique<Replay>();
    ros::NodeHandle nh;
    try {
      Play(nh, replay.get());
    } catch (const std::exception& e) {
      replay->error = e.what();
    }
  }
  static void TearDownTestSuite() { replay.reset(); }
  void SetUp() override { ASSERT_TRUE(replay->error.empty()) << replay->error; }
  static std::unique_ptr<Replay> replay;
};
template <class Replay, void (*Play)(ros::NodeHandle&, Replay*)>
std::unique_ptr<Replay> ReplayedOnce<Replay, Play>::replay;

}  // namespace test
}  // namespace vwe_vo
