#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <stdexcept>
#include <string>

#include "../common/expect_error.h"
#include "vwe_vo/io/trajectory_io.h"

using namespace vwe_vo;

namespace {

std::string tempPath(const std::string& name) {
  return ::testing::TempDir() + "vwe_vo_test_io_" + name;
}

std::string writeText(const std::string& name, const std::string& text) {
  const std::string path = tempPath(name);
  std::ofstream(path) << text;
  return path;
}

using test::errorOf;
using test::expectContains;

}  // namespace

TEST(TrajectoryIo, TumWriteReadRoundTrip) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Trajectory3 traj;
  for (int i = 0; i < 200; ++i) {
    const Quat q = Quat(u(rng), u(rng), u(rng), u(rng)).normalized();
    traj.push_back(
        {secToNs(100.0 + 0.013 * i) + i, makePose(q, Vec3(50 * u(rng), 50 * u(rng), u(rng)))});
  }
  const std::string path = tempPath("roundtrip.tum");
  writeTum(path, traj);
  const Trajectory3 back = readTum(path);
  ASSERT_EQ(back.size(), traj.size());
  for (size_t i = 0; i < traj.size(); ++i) {
    EXPECT_EQ(back[i].t_ns, traj[i].t_ns) << i;
    EXPECT_LT((back[i].T.translation() - traj[i].T.translation()).cwiseAbs().maxCoeff(), 1e-9) << i;
    EXPECT_LT((back[i].T.linear() - traj[i].T.linear()).cwiseAbs().maxCoeff(), 2e-9) << i;
  }
}

TEST(TrajectoryIo, EcdRoundTrips) {
  EventVector events;
  for (int i = 0; i < 1000; ++i) {
    PixelEvent e;
    e.t_ns = 1000000 + 37013LL * i;
    e.x = static_cast<uint16_t>((i * 7) % 346);
    e.y = static_cast<uint16_t>((i * 13) % 260);
    e.polarity = i % 3 == 0 ? -1 : 1;
    events.push_back(e);
  }
  const std::string events_path = tempPath("events.txt");
  writeEcdEvents(events_path, events);
  const EventVector back = readEcdEvents(events_path, 346, 260);
  ASSERT_EQ(back.size(), events.size());
  for (size_t i = 0; i < events.size(); ++i) {
    EXPECT_EQ(back[i].t_ns, events[i].t_ns);
    EXPECT_EQ(back[i].x, events[i].x);
    EXPECT_EQ(back[i].y, events[i].y);
    EXPECT_EQ(back[i].polarity, events[i].polarity);
  }

  const EcdCalibration calib{199.092366542,      198.82882047,       132.192071378,
                             110.712660011,      -0.368436311798,    0.150947243557,
                             -0.000296130534385, -0.000759431726241, 0.0};
  const std::string calib_path = tempPath("calib.txt");
  writeEcdCalibration(calib_path, calib);
  const EcdCalibration c = readEcdCalibration(calib_path);
  EXPECT_NEAR(c.fx, calib.fx, 1e-6);
  EXPECT_NEAR(c.fy, calib.fy, 1e-6);
  EXPECT_NEAR(c.cx, calib.cx, 1e-6);
  EXPECT_NEAR(c.cy, calib.cy, 1e-6);
  EXPECT_NEAR(c.k1, calib.k1, 1e-9);
  EXPECT_NEAR(c.k2, calib.k2, 1e-9);
  EXPECT_NEAR(c.p1, calib.p1, 1e-12);
  EXPECT_NEAR(c.p2, calib.p2, 1e-12);
  EXPECT_EQ(c.k3, 0.0);

  const Pose3 T_base_cam = makePose(R_base_opticalFrame(), Vec3(0.2, 0.0, 0.3));
  const std::string extrinsics_path = tempPath("extrinsics.txt");
  writePoseLine(extrinsics_path, T_base_cam);
  const Pose3 T = readPoseLine(extrinsics_path);
  EXPECT_LT((T.matrix() - T_base_cam.matrix()).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(TrajectoryIo, MalformedTumNamesFileAndLine) {
  const std::string bad = writeText("bad.tum",
                                    "# t px py pz qx qy qz qw\n"
                                    "0.0 0 0 0 0 0 0 1\n"
                                    "0.1 0 0 zero 0 0 0 1\n");
  const std::string msg = errorOf([&] { readTum(bad); });
  expectContains(msg, bad);
  expectContains(msg, ":3");

  const std::string short_line = writeText("short.tum", "0.0 0 0 0 0 0 0 1\n0.1 0 0 0 0 0 1\n");
  expectContains(errorOf([&] { readTum(short_line); }), short_line + ":2");

  const std::string back = writeText("back.tum",
                                     "0.0 0 0 0 0 0 0 1\n"
                                     "0.1 0 0 0 0 0 0 1\n"
                                     "\n"
                                     "0.1 1 0 0 0 0 0 1\n");
  const std::string back_msg = errorOf([&] { readTum(back); });
  expectContains(back_msg, back + ":4");
  expectContains(back_msg, "not after");

  const std::string quat = writeText("quat.tum", "0.0 0 0 0 0 0 0 2\n");
  expectContains(errorOf([&] { readTum(quat); }), quat + ":1");

  const std::string empty = writeText("empty.tum", "# only a comment\n");
  expectContains(errorOf([&] { readTum(empty); }), empty);

  const std::string missing = tempPath("does_not_exist.tum");
  expectContains(errorOf([&] { readTum(missing); }), missing);
}

TEST(TrajectoryIo, MalformedEcdFilesNameFileAndLine) {
  const std::string events = writeText("bad_events.txt", "0.001 10 20 1\n0.002 10 20 2\n");
  const std::string m1 = errorOf([&] { readEcdEvents(events); });
  expectContains(m1, events + ":2");
  expectContains(m1, "polarity");

  const std::string outside = writeText("outside_events.txt", "0.001 10 20 1\n0.002 400 20 1\n");
  expectContains(errorOf([&] { readEcdEvents(outside, 346, 260); }), outside + ":2");

  const std::string backwards = writeText("back_events.txt", "0.002 10 20 1\n0.001 10 20 0\n");
  expectContains(errorOf([&] { readEcdEvents(backwards); }), backwards + ":2");

  const std::string calib = writeText("bad_calib.txt", "# fx fy cx cy\n200 0 173 130\n");
  expectContains(errorOf([&] { readEcdCalibration(calib); }), calib + ":2");
  const std::string empty_calib = writeText("empty_calib.txt", "");
  expectContains(errorOf([&] { readEcdCalibration(empty_calib); }), empty_calib);

  const std::string pose = writeText("bad_pose.txt", "0 0 0.3 0 0 0\n");
  expectContains(errorOf([&] { readPoseLine(pose); }), pose + ":1");
  const std::string empty_pose = writeText("empty_pose.txt", "\n");
  expectContains(errorOf([&] { readPoseLine(empty_pose); }), empty_pose);
}

TEST(TrajectoryIo, EcdImuRoundTripAndMalformedLines) {
  std::vector<ImuSample> in;
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n01(0.0, 1.0);
  for (int i = 0; i < 50; ++i)
    in.push_back({1000000000 + i * 1000000, Vec3(n01(rng), n01(rng), 9.81 + n01(rng)),
                  0.1 * Vec3(n01(rng), n01(rng), n01(rng))});
  const std::string path = tempPath("imu.txt");
  writeEcdImu(path, in);
  const std::vector<ImuSample> out = readEcdImu(path);
  ASSERT_EQ(out.size(), in.size());
  for (size_t i = 0; i < in.size(); ++i) {
    EXPECT_EQ(out[i].t_ns, in[i].t_ns);
    // %.9g: 9 significant digits.
    EXPECT_LT((out[i].accel - in[i].accel).norm(), 1e-7 * (1 + in[i].accel.norm()));
    EXPECT_LT((out[i].gyro - in[i].gyro).norm(), 1e-8);
  }
  const std::string short_line =
      writeText("bad_imu.txt", "# t ax ay az gx gy gz\n1.0 0 0 9.8 0 0 0\n1.001 0 0 9.8 0 0\n");
  expectContains(errorOf([&] { readEcdImu(short_line); }), short_line + ":3");
  const std::string word = writeText("word_imu.txt", "1.0 0 0 9.8 0 0 x\n");
  expectContains(errorOf([&] { readEcdImu(word); }), word + ":1");
  const std::string back = writeText("back_imu.txt", "1.0 0 0 9.8 0 0 0\n0.9 0 0 9.8 0 0 0\n");
  expectContains(errorOf([&] { readEcdImu(back); }), back + ":2");
}
