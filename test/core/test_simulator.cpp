// Event simulator: events against independent truths (noise statistics, rotation warping with
// the true trajectory, depth of a known wall, Ackermann geometry of the trajectories).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "vwe_vo/io/config.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sim/event_simulator.h"
#include "vwe_vo/sim/imu_simulator.h"
#include "vwe_vo/sim/scene.h"
#include "vwe_vo/sim/sequences.h"

namespace vwe_vo {
namespace sim {
namespace {

const CameraModel& camera() {
  static const CameraModel cam(
      loadCameraCalibrationYaml(std::string(VWE_VO_SOURCE_DIR) + "/config/davis346.yaml"));
  return cam;
}

EventVector simulate(const std::vector<ProfileSegment>& profile, double seconds,
                     EventSimulatorOptions opt, SimulatorStats* stats = nullptr,
                     const std::string& scene = "indoor", uint64_t seed = 5) {
  const auto tr = VehicleTrajectory::fromProfile(profile);
  EventSimulator sim(buildScene(scene, seed, tr), camera(), defaultTBaseCam(), tr, opt);
  EventVector ev;
  sim.simulateUntil(secToNs(seconds), &ev);
  if (stats) *stats = sim.stats();
  return ev;
}

size_t countIn(const EventVector& ev, double t0, double t1) {
  return std::count_if(ev.begin(), ev.end(), [&](const PixelEvent& e) {
    return e.t_ns >= secToNs(t0) && e.t_ns < secToNs(t1);
  });
}

TEST(Simulator, EventsSortedAndInsideSensor) {
  const EventVector ev =
      simulate(circleProfile(0.4, 25 * kRadPerDeg, 1.0), 0.25, EventSimulatorOptions());
  ASSERT_GT(ev.size(), 10000u);
  for (size_t i = 0; i < ev.size(); ++i) {
    ASSERT_LT(ev[i].x, 346);
    ASSERT_LT(ev[i].y, 260);
    ASSERT_TRUE(ev[i].polarity == 1 || ev[i].polarity == -1);
    ASSERT_GT(ev[i].t_ns, 0);
    ASSERT_LE(ev[i].t_ns, secToNs(0.25));
    if (i) {
      ASSERT_LE(ev[i - 1].t_ns, ev[i].t_ns);
    }
  }
}

TEST(Simulator, ChunkedCallsStaySortedInsideTheirIntervals) {
  // Tiles are re-rendered on their own schedules; every call must still flush them so that its
  // events lie in (previous end, end], sorted, and chunking must not change the event rate.
  const auto tr = VehicleTrajectory::fromProfile(circleProfile(0.4, 25 * kRadPerDeg, 1.0));
  const Scene scene = buildScene("indoor", 5, tr);
  EventSimulatorOptions opt;
  opt.noise_rate_hz = 0.0;
  EventSimulator whole(scene, camera(), defaultTBaseCam(), tr, opt);
  EventVector all;
  whole.simulateUntil(secToNs(0.3), &all);
  EXPECT_LT(whole.stats().tile_renders, whole.stats().renders * 22u * 17u);  // some tiles waited
  EventSimulator chunked(scene, camera(), defaultTBaseCam(), tr, opt);
  size_t total = 0;
  for (int k = 1; k <= 12; ++k) {
    EventVector ev;
    chunked.simulateUntil(secToNs(0.025 * k), &ev);
    for (size_t i = 0; i < ev.size(); ++i) {
      ASSERT_GT(ev[i].t_ns, secToNs(0.025 * (k - 1)));
      ASSERT_LE(ev[i].t_ns, secToNs(0.025 * k));
      if (i) {
        ASSERT_LE(ev[i - 1].t_ns, ev[i].t_ns);
      }
    }
    total += ev.size();
  }
  EXPECT_NEAR(static_cast<double>(total), static_cast<double>(all.size()), 0.05 * all.size());
}

TEST(Simulator, SameEventsWhateverTheThreadCount) {
  // Tile rows are rendered on a pool; the events (signal and noise) must not depend on how many
  // threads share them out.
  const auto tr = VehicleTrajectory::fromProfile(circleProfile(0.4, 25 * kRadPerDeg, 1.0));
  const Scene scene = buildScene("indoor", 5, tr);
  EventVector ev[2];
  for (int k = 0; k < 2; ++k) {
    EventSimulatorOptions opt;
    opt.num_threads = k == 0 ? 1 : 3;
    EventSimulator sim(scene, camera(), defaultTBaseCam(), tr, opt);
    for (int c = 1; c <= 4; ++c) sim.simulateUntil(secToNs(0.05 * c), &ev[k]);
  }
  ASSERT_GT(ev[0].size(), 10000u);
  ASSERT_EQ(ev[0].size(), ev[1].size());
  for (size_t i = 0; i < ev[0].size(); ++i) {
    const PixelEvent &a = ev[0][i], &b = ev[1][i];
    ASSERT_TRUE(a.t_ns == b.t_ns && a.x == b.x && a.y == b.y && a.polarity == b.polarity)
        << "event " << i;
  }
}

TEST(Simulator, StaticCameraGivesOnlyNoiseAtConfiguredRate) {
  EventSimulatorOptions opt;
  opt.noise_rate_hz = 2.0;
  SimulatorStats st;
  const double T = 0.5;
  const EventVector ev = simulate(straightProfile(0.0, 1.0), T, opt, &st);
  EXPECT_EQ(st.signal_events, 0u);
  const double expected = 346.0 * 260.0 * opt.noise_rate_hz * T;
  EXPECT_NEAR(static_cast<double>(ev.size()), expected, 5.0 * std::sqrt(expected));
  const double on =
      std::count_if(ev.begin(), ev.end(), [](const PixelEvent& e) { return e.polarity > 0; });
  EXPECT_NEAR(on / ev.size(), 0.5, 0.02);
}

TEST(Simulator, EventRateGrowsWithSpeed) {
  EventSimulatorOptions opt;
  opt.noise_rate_hz = 0.0;
  const size_t slow = simulate(straightProfile(0.2, 1.0), 0.3, opt).size();
  const size_t fast = simulate(straightProfile(0.5, 1.0), 0.3, opt).size();
  EXPECT_GT(fast, 1.5 * slow) << "slow " << slow << " fast " << fast;
}

TEST(Simulator, PolarityBalanceIsSane) {
  const EventVector ev =
      simulate(circleProfile(0.4, 25 * kRadPerDeg, 1.0), 0.3, EventSimulatorOptions());
  const double on =
      std::count_if(ev.begin(), ev.end(), [](const PixelEvent& e) { return e.polarity > 0; });
  std::printf("[simulator] ON fraction %.4f of %zu events\n", on / ev.size(), ev.size());
  // ON and OFF share each pixel's threshold: as many ON as OFF events, but for the net change of
  // the scene's brightness over the window.
  EXPECT_NEAR(on / ev.size(), 0.5, 0.009);  // measured 0.5058
}

// Variance of an image of events placed at warped positions (bilinear votes).
double warpedVariance(const EventVector& ev, const VehicleTrajectory& tr, int64_t t_ref, int mode) {
  const CameraModel& cam = camera();
  const Pose3 T_base_cam = defaultTBaseCam();
  const Mat3 R_odom_cr = (tr.T_odom_base(t_ref) * T_base_cam).linear();
  cv::Mat1d img = cv::Mat1d::zeros(cam.height(), cam.width());
  for (const PixelEvent& e : ev) {
    double u = e.x, v = e.y;
    if (mode != 0) {
      Mat3 R_cr_ct = R_odom_cr.transpose() * (tr.T_odom_base(e.t_ns) * T_base_cam).linear();
      if (mode == 2) R_cr_ct.transposeInPlace();  // the wrong sign of omega
      Vec2 uv;
      if (!cam.project(R_cr_ct * cam.bearing(e.x, e.y).cast<double>(), &uv)) continue;
      u = uv.x();
      v = uv.y();
    }
    const int x0 = static_cast<int>(std::floor(u)), y0 = static_cast<int>(std::floor(v));
    if (x0 < 0 || y0 < 0 || x0 + 1 >= cam.width() || y0 + 1 >= cam.height()) continue;
    const double ax = u - x0, ay = v - y0;
    img(y0, x0) += (1 - ax) * (1 - ay);
    img(y0, x0 + 1) += ax * (1 - ay);
    img(y0 + 1, x0) += (1 - ax) * ay;
    img(y0 + 1, x0 + 1) += ax * ay;
  }
  cv::Scalar mean, sd;
  cv::meanStdDev(img, mean, sd);
  return sd[0] * sd[0];
}

TEST(Simulator, EventsAgreeWithTrueRotation) {
  const auto tr = VehicleTrajectory::fromProfile(rotationProfile(30 * kRadPerDeg, 0.3));
  EventSimulator sim(buildScene("indoor", 3, tr), camera(), defaultTBaseCam(), tr);
  EventVector all;
  sim.simulateUntil(secToNs(0.2), &all);
  EventVector ev;
  for (const PixelEvent& e : all)
    if (e.t_ns >= secToNs(0.1) && e.t_ns < secToNs(0.175)) ev.push_back(e);
  ASSERT_GT(ev.size(), 20000u);
  const int64_t t_ref = secToNs(0.1375);
  const double unwarped = warpedVariance(ev, tr, t_ref, 0);
  const double truth = warpedVariance(ev, tr, t_ref, 1);
  const double wrong = warpedVariance(ev, tr, t_ref, 2);
  EXPECT_GT(truth, 1.5 * unwarped) << "true " << truth << " unwarped " << unwarped;
  EXPECT_GT(truth, 1.5 * wrong) << "true " << truth << " wrong " << wrong;
}

TEST(Simulator, HdrToggleChangesEventRate) {
  EventSimulatorOptions opt;
  opt.illumination = IlluminationMode::kToggle;
  opt.illumination_period_s = 0.3;
  opt.illumination_ramp_s = 0.05;
  opt.dark_noise_rate_hz = 0.0;  // signal only here; the noise rate is checked below
  SimulatorStats st;
  const EventVector ev = simulate(circleProfile(0.4, 25 * kRadPerDeg, 1.0), 0.55, opt, &st);
  const double bright = countIn(ev, 0.05, 0.2) / 0.15;
  const double ramp = countIn(ev, 0.25, 0.3) / 0.05;
  const double dark = countIn(ev, 0.35, 0.5) / 0.15;
  EXPECT_GT(ramp, 3.0 * bright) << "ramp " << ramp << " bright " << bright;
  EXPECT_LT(dark, 0.8 * bright) << "dark " << dark << " bright " << bright;
  // In the dark, noise dominates more: the noise rate is up by the configured amount.
  opt.dark_noise_rate_hz = 20.0;
  const auto tr = VehicleTrajectory::fromProfile(straightProfile(0.0, 1.0));
  EventSimulator s(buildScene("indoor", 1, tr), camera(), defaultTBaseCam(), tr, opt);
  EXPECT_NEAR(s.noiseRate(secToNs(0.4)), opt.noise_rate_hz + opt.dark_noise_rate_hz, 1e-6);
  EXPECT_NEAR(s.noiseRate(secToNs(0.1)), opt.noise_rate_hz, 1e-6);
  EXPECT_NEAR(s.illumination(secToNs(0.4)), opt.illumination_low, 1e-9);
}

TEST(Simulator, DepthOfAKnownWall) {
  // A wall at x = 3 m facing a camera 0.1 m ahead of base_link at the origin, looking along +x.
  Scene scene;
  scene.textures.push_back(
      std::make_shared<Texture>(makeTexture(TextureStyle::kGeneric, 64, 0.05f, 1)));
  scene.addRect(0, 3.0f, Eigen::Vector2f(-50, -50), Eigen::Vector2f(50, 50), 0, 1.0f, 1);
  const auto tr = VehicleTrajectory::fromProfile(straightProfile(0.0, 1.0));
  EventSimulator sim(scene, camera(), defaultTBaseCam(), tr);
  const cv::Mat1f z = sim.depthMap(0);
  const double expected = 3.0 - defaultTBaseCam().translation().x();
  for (int y = 0; y < z.rows; y += 37)
    for (int x = 0; x < z.cols; x += 41) EXPECT_NEAR(z(y, x), expected, 1e-4) << x << "," << y;
}

TEST(SimulatorTrajectory, CircleHasRadiusVOverOmegaAndTangentHeading) {
  const double v = 0.4, w = 25 * kRadPerDeg;
  const auto tr = VehicleTrajectory::fromProfile(circleProfile(v, w, 2 * kPi / w));
  const Vec2 centre(0.0, v / w);
  for (int64_t t = 0; t <= tr.durationNs(); t += secToNs(0.37)) {
    const Vec3 p = tr.planar(t);
    EXPECT_NEAR((p.head<2>() - centre).norm(), v / w, 1e-6);
    const Vec3 q = tr.planar(t + 1000000);
    const double dir = std::atan2(q.y() - p.y(), q.x() - p.x());
    if (t + 1000000 <= tr.durationNs()) {
      EXPECT_NEAR(wrapAngle(dir - p.z() - 0.5 * w * 1e-3), 0.0, 1e-5);
    }
  }
  EXPECT_NEAR(tr.pathLength(), 2 * kPi * v / w, 1e-3);
  EXPECT_NEAR(tr.planar(tr.durationNs()).head<2>().norm(), 0.0, 1e-6);  // closed loop
}

TEST(SimulatorTrajectory, LongIndoorHasAnExactStandstill) {
  const auto tr = VehicleTrajectory::fromProfile(longIndoorProfile(0.35, 3.0));
  double still = 0, longest = 0;
  for (int64_t t = 0; t <= tr.durationNs(); t += 10000000) {
    if (tr.speed(t) == 0.0 && tr.yawRate(t) == 0.0)
      still += 0.01;
    else
      still = 0;
    longest = std::max(longest, still);
  }
  EXPECT_GT(longest, 2.95);
  EXPECT_GT(tr.durationSec(), 28.0);
  // Turns of exactly duration * omega: net heading = 90 + 90 - 90 + 120 + 90 deg.
  EXPECT_NEAR(wrapAngle(tr.planar(tr.durationNs()).z() - wrapAngle(300 * kRadPerDeg)), 0.0, 1e-6);
}

TEST(SimulatorOptions, ValidateNamesTheField) {
  auto expectField = [](EventSimulatorOptions o, const std::string& field) {
    try {
      o.validate();
      ADD_FAILURE() << "no throw for " << field;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  EventSimulatorOptions o;
  EXPECT_NO_THROW(o.validate());
  o.contrast_threshold = -1;
  expectField(o, "contrast_threshold");
  o = EventSimulatorOptions();
  o.refractory_s = -1;
  expectField(o, "refractory_s");
  o = EventSimulatorOptions();
  o.noise_rate_hz = -0.1;
  expectField(o, "noise_rate_hz");
  o = EventSimulatorOptions();
  o.supersampling = 0;
  expectField(o, "supersampling");
  o = EventSimulatorOptions();
  o.num_threads = 0;
  expectField(o, "num_threads");
  VehicleTrajectoryOptions t;
  t.table_step_s = 0;
  EXPECT_THROW(t.validate(), std::invalid_argument);
}

TEST(SimulatorSequences, UnknownNameListsValidOnes) {
  try {
    findSequence("no_such_sequence");
    FAIL();
  } catch (const std::invalid_argument& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("indoor_circle"), std::string::npos) << msg;
    EXPECT_NE(msg.find("street_long"), std::string::npos) << msg;
  }
  const auto list = listSequences();
  ASSERT_GE(list.size(), 5u);
  for (const auto& s : list) {
    EXPECT_GT(s.duration_s, 5.0) << s.name;
    EXPECT_GT(s.path_length_m, 1.0) << s.name;
  }
  EXPECT_THROW(buildScene("moon", 1, VehicleTrajectory::fromProfile(straightProfile(1, 1))),
               std::invalid_argument);
}

TEST(SimulatorSequences, FlatSequencesAreUnchanged) {
  // Poses, speeds and yaw rates recorded from the simulator before continuous motion, suspension
  // and the DAVIS IMU were added: every new option defaults to off.
  struct Row {
    const char* name;
    double t, x, y, z, qx, qy, qz, qw, v, w;
  };
  const Row rows[] = {
      {"street_long", 0.70, 4.0992363748570497, 0, 0, 0, 0, 0, 1, 5.8560519640814013, 0},
      {"street_long", 5.30, 31.037075409628166, 0, 0, 0, 0, 0, 1, 5.8560519640814013, 0},
      {"street_long", 12.90, 69.469207034223601, 8.265956237230947, 0, 0, 0, 0.54809017368096069,
       0.83641924984685423, 5, 0.36379676635540426},
      {"street_long", 23.45, 71.08301638483195, 74.793081976540691, 0, 0, 0, 0.60433434307526601,
       0.79673082140694584, 5, -0.4105657334138037},
      {"street_long", 37.10, 162.43038473081282, 84.955876524074228, 0, 0, 0, 0.20489066570584513,
       0.97878486661095021, 5, 0.33760469293917633},
      {"indoor_long", 0.70, 0.2450000000000043, 0, 0, 0, 0, 0, 1, 0.34999999999999998, 0},
      {"indoor_long", 5.30, 1.549229855199272, 0.34385239408151358, 0, 0, 0, 0.56640623692456182,
       0.82412618862220188, 0.27999999999999997, 0.52359877559829882},
      {"indoor_long", 12.90, 0.95745511528590754, 1.7230569088657126, 0, 0, 0, 1,
       2.3809304881959094e-13, 0, 0},
      {"indoor_long", 23.45, -0.49223497816277034, 3.0859120203999044, 0, 0, 0, 0.87881711266241658,
       0.47715876025877735, 0.24499999999999997, 1.0471975511965976},
      {"indoor_figure8", 0.70, 0.23955132858653469, 0.04439821445230574, 0, 0, 0,
       0.18223552549213623, 0.98325490756395673, 0.34999999999999998, 0.52359877559829882},
      {"indoor_figure8", 5.30, 0.23955132858823527, 1.292503307520674, 0, 0, 0, 0.98325490756364264,
       0.18223552549383051, 0.34999999999999998, 0.52359877559829882},
      {"indoor_figure8", 12.90, 0.30342157041151846, -0.074321890073570568, 0, 0, 0,
       -0.23344536385796369, 0.9723699203971824, 0.34999999999999998, -0.52359877559829882},
      {"indoor_figure8", 23.45, -0.18989899792220216, -0.028992097786567989, 0, 0, 0,
       0.14349262199117066, 0.98965138681967146, 0.34999999999999998, -0.52359877559829882},
  };
  struct Length {
    const char* name;
    int64_t duration_ns;
    double path_m;
  };
  const Length lengths[] = {
      {"street_long", 40530320571, 252.28929604295845},
      {"indoor_long", 30500000000, 8.3299999999983623},
      {"indoor_figure8", 24000000000, 8.3999999999924775},
  };
  for (const Length& l : lengths) {
    const SequenceSpec s = findSequence(l.name);
    const auto tr = VehicleTrajectory::fromProfile(s.profile, s.trajectory);
    EXPECT_EQ(tr.durationNs(), l.duration_ns) << l.name;
    EXPECT_EQ(tr.pathLength(), l.path_m) << l.name;
    EXPECT_FALSE(s.davis_imu) << l.name;
  }
  for (const Row& r : rows) {
    const SequenceSpec s = findSequence(r.name);
    const auto tr = VehicleTrajectory::fromProfile(s.profile, s.trajectory);
    const Pose3 T = tr.T_odom_base(secToNs(r.t));
    const Quat q(T.linear());
    EXPECT_EQ(T.translation().x(), r.x) << r.name << " " << r.t;
    EXPECT_EQ(T.translation().y(), r.y) << r.name << " " << r.t;
    EXPECT_EQ(T.translation().z(), r.z) << r.name << " " << r.t;
    EXPECT_NEAR(q.x(), r.qx, 1e-15);
    EXPECT_NEAR(q.y(), r.qy, 1e-15);
    EXPECT_NEAR(q.z(), r.qz, 1e-15);
    EXPECT_NEAR(q.w(), r.qw, 1e-15);
    EXPECT_EQ(tr.speed(secToNs(r.t)), r.v) << r.name << " " << r.t;
    EXPECT_EQ(tr.yawRate(secToNs(r.t)), r.w) << r.name << " " << r.t;
  }
}

TEST(SimulatorSequences, SceneOfTheFlatSequencesIsUnchanged) {
  // Face counts recorded before the scene could follow a separate layout path.
  const std::pair<const char*, size_t> counts[] = {
      {"indoor_long", 158}, {"corridor_straight", 52}, {"street_long", 1185}};
  for (const auto& c : counts) {
    const SequenceSpec s = findSequence(c.first);
    const auto tr = VehicleTrajectory::fromProfile(s.profile, s.trajectory);
    EXPECT_EQ(buildSequenceScene(s, tr).faces.size(), c.second) << c.first;
  }
}

TEST(SimulatorTrajectory, DriveSequencesSteerAndChangeSpeedContinuously) {
  for (const char* name : {"street_drive", "indoor_drive"}) {
    const SequenceSpec s = findSequence(name);
    const auto tr = VehicleTrajectory::fromProfile(s.profile, s.trajectory);
    const double v_mean = s.profile.front().v;
    double max_dw = 0, max_dv = 0, max_w = 0, v_min = 1e9, v_max = 0;
    for (int64_t t = 1000000; t <= tr.durationNs(); t += 1000000) {
      max_dw = std::max(max_dw, std::abs(tr.yawRate(t) - tr.yawRate(t - 1000000)));
      max_dv = std::max(max_dv, std::abs(tr.speed(t) - tr.speed(t - 1000000)));
      max_w = std::max(max_w, std::abs(tr.yawRate(t)));
      bool stopping = false;
      for (const StopEvent& st : s.trajectory.motion.stops)
        stopping |= nsToSec(t) > st.t_start_s &&
                    nsToSec(t) < st.t_start_s + st.brake_s + st.dwell_s + st.go_s;
      if (!stopping) v_min = std::min(v_min, tr.speed(t)), v_max = std::max(v_max, tr.speed(t));
    }
    // No steps: per 1 ms the yaw rate moves by less than 0.1 deg/s, the speed by < 0.2 % of v.
    EXPECT_LT(max_dw, 0.1 * kRadPerDeg) << name;
    EXPECT_LT(max_dv, 2e-3 * v_mean) << name;
    EXPECT_GT(max_w, 10 * kRadPerDeg) << name;
    EXPECT_GE(v_min, 0.75 * v_mean) << name;
    EXPECT_LE(v_max, 1.25 * v_mean) << name;
    EXPECT_LT(v_min, 0.85 * v_mean) << name;  // the speed does change
    EXPECT_GT(v_max, 1.1 * v_mean) << name;
  }
  // indoor_drive stops twice, exactly.
  const SequenceSpec s = findSequence("indoor_drive");
  const auto tr = VehicleTrajectory::fromProfile(s.profile, s.trajectory);
  for (const StopEvent& st : s.trajectory.motion.stops) {
    const int64_t t = secToNs(st.t_start_s + st.brake_s + 0.5 * st.dwell_s);
    EXPECT_EQ(tr.speed(t), 0.0);
    EXPECT_EQ(tr.yawRate(t), 0.0);
  }
}

TEST(SimulatorTrajectory, StreetDriveHeadingLeavesTheFacadesAndBends) {
  const SequenceSpec s = findSequence("street_drive");
  const auto tr = VehicleTrajectory::fromProfile(s.profile, s.trajectory);
  // Before the bend the street runs along x: the heading deviates by 10-22 deg at most.
  double max_dev = 0;
  for (int64_t t = 0; t < secToNs(18.0); t += 10000000)
    max_dev = std::max(max_dev, std::abs(tr.planar(t).z()));
  EXPECT_GT(max_dev, 10 * kRadPerDeg);
  EXPECT_LT(max_dev, 22 * kRadPerDeg);
  // After the bend, along y.
  const double yaw_end = tr.planar(secToNs(28.0)).z();
  EXPECT_NEAR(yaw_end, kPi / 2, 20 * kRadPerDeg);
}

TEST(SimulatorTrajectory, SuspensionAmplitudesAreInTheirRanges) {
  struct Case {
    const char* name;
    double tilt_min_deg, tilt_max_deg, heave_max_m;
  };
  for (const Case& c :
       {Case{"street_drive", 0.8, 2.5, 0.03}, Case{"indoor_drive", 0.25, 1.0, 0.01}}) {
    for (const bool flat : {false, true}) {
      const SequenceSpec s = findSequence(std::string(c.name) + (flat ? "_flat" : ""));
      const auto tr = VehicleTrajectory::fromProfile(s.profile, s.trajectory);
      double pitch = 0, roll = 0, heave = 0;
      for (int64_t t = 0; t <= tr.durationNs(); t += 5000000) {
        const SuspensionState b = tr.suspension(t);
        pitch = std::max(pitch, std::abs(b.pitch_rad));
        roll = std::max(roll, std::abs(b.roll_rad));
        heave = std::max(heave, std::abs(b.heave_m));
        // The ground truth carries it: T_odom_base's z and tilt.
        const Pose3 T = tr.T_odom_base(t);
        ASSERT_NEAR(T.translation().z(), b.heave_m, 1e-12);
        ASSERT_NEAR(std::acos(std::min(1.0, T.linear()(2, 2))),
                    std::acos(std::cos(b.pitch_rad) * std::cos(b.roll_rad)), 1e-6);
      }
      if (flat) {
        EXPECT_EQ(pitch + roll + heave, 0.0) << c.name;
        continue;
      }
      EXPECT_GT(std::max(pitch, roll), c.tilt_min_deg * kRadPerDeg) << c.name;
      EXPECT_LT(pitch, c.tilt_max_deg * kRadPerDeg) << c.name;
      EXPECT_LT(roll, c.tilt_max_deg * kRadPerDeg) << c.name;
      EXPECT_GT(heave, 0.0) << c.name;
      EXPECT_LT(heave, c.heave_max_m) << c.name;
    }
  }
}

TEST(SimulatorImu, TruthIsTheDerivativeOfThePose) {
  const SequenceSpec s = findSequence("street_drive");
  const auto tr = VehicleTrajectory::fromProfile(s.profile, s.trajectory);
  const ImuSimulator imu(tr, s.T_base_cam, s.imu);
  auto T_cam = [&](int64_t t) { return tr.T_odom_base(t) * s.T_base_cam; };
  for (double ts = 1.0; ts < 39.0; ts += 0.77) {
    const int64_t t = secToNs(ts), h = 200000;  // 0.2 ms
    const ImuSample z = imu.truth(t);
    const Eigen::AngleAxisd aa(T_cam(t - h).linear().transpose() * T_cam(t + h).linear());
    const Vec3 w_fd = aa.axis() * aa.angle() / (2e-9 * h);
    EXPECT_LT((z.gyro - w_fd).norm(), 2e-3) << ts;
    const int64_t H = 2000000;  // 2 ms: second difference of the camera's position
    const Vec3 a =
        (T_cam(t - H).translation() - 2 * T_cam(t).translation() + T_cam(t + H).translation()) /
        std::pow(1e-9 * H, 2);
    const Vec3 f = T_cam(t).linear().transpose() * (a + Vec3(0, 0, s.imu.gravity));
    EXPECT_LT((z.accel - f).norm(), 0.05) << ts;
  }
}

TEST(SimulatorImu, GyroMinusBiasIntegratesToTheTrueRotation) {
  const SequenceSpec s = findSequence("street_drive");
  const auto tr = VehicleTrajectory::fromProfile(s.profile, s.trajectory);
  ImuSimulator imu(tr, s.T_base_cam, s.imu);
  const Vec3 b = imu.gyroBias();
  EXPECT_LE(b.cwiseAbs().maxCoeff(), 0.5 * kRadPerDeg);
  EXPECT_GT(b.norm(), 0.0);
  const int64_t t0 = secToNs(12.0), t1 = secToNs(27.0), dt = imu.periodNs();
  Mat3 R = Mat3::Identity(), R_biased = Mat3::Identity();
  ImuSample prev = imu.measure(t0);
  for (int64_t t = t0 + dt; t <= t1; t += dt) {
    const ImuSample z = imu.measure(t);
    const Vec3 w = 0.5 * (prev.gyro + z.gyro);  // trapezoidal rate over the step
    R = R * Eigen::AngleAxisd((w - b).norm() * 1e-9 * dt, (w - b).normalized()).toRotationMatrix();
    R_biased =
        R_biased * Eigen::AngleAxisd(w.norm() * 1e-9 * dt, w.normalized()).toRotationMatrix();
    prev = z;
  }
  const Mat3 truth = ((tr.T_odom_base(t0) * s.T_base_cam).linear().transpose() *
                      (tr.T_odom_base(t1) * s.T_base_cam).linear());
  // Random walk of the white noise: sigma * dt * sqrt(N) per axis (~4e-4 rad over 15 s); 5 sigma
  // plus the integration error.
  const double walk = s.imu.gyroSigma() * 1e-3 * std::sqrt(15000.0);
  EXPECT_LT(rotationAngle(truth.transpose() * R), 5 * std::sqrt(3.0) * walk + 1e-3);
  // The bias itself drifts by |b| * 15 s.
  EXPECT_GT(rotationAngle(truth.transpose() * R_biased), 0.5 * b.norm() * 15.0);
}

TEST(SimulatorImu, AccelerometerAtRestReadsGravityInTheCameraFrame) {
  const SequenceSpec s = findSequence("indoor_drive_flat");
  const auto tr = VehicleTrajectory::fromProfile(s.profile, s.trajectory);
  const ImuSimulator imu(tr, s.T_base_cam, s.imu);
  const StopEvent& st = s.trajectory.motion.stops.front();
  const int64_t t = secToNs(st.t_start_s + st.brake_s + 0.5 * st.dwell_s);
  const ImuSample z = imu.truth(t);
  const Mat3 R_odom_cam = (tr.T_odom_base(t) * s.T_base_cam).linear();
  EXPECT_LT((z.accel - R_odom_cam.transpose() * Vec3(0, 0, 9.80665)).norm(), 1e-6);
  EXPECT_LT(z.gyro.norm(), 1e-9);
  // The default camera looks forward (z forward, y down): gravity reads along -y of the camera.
  EXPECT_LT(z.accel.y(), -9.0);
}

TEST(SimulatorSequences, ReseedingChangesTheRoadAndTheImuButNotThePlannedMotion) {
  const SequenceSpec a = findSequence("street_drive");
  SequenceSpec b = a;
  b.reseed(7);
  EXPECT_EQ(b.seed, 7u);
  EXPECT_EQ(b.simulator.seed, 7u);
  EXPECT_EQ(b.imu.seed, 7u);
  EXPECT_EQ(b.trajectory.suspension.seed, 7u);
  const auto ta = VehicleTrajectory::fromProfile(a.profile, a.trajectory);
  const auto tb = VehicleTrajectory::fromProfile(b.profile, b.trajectory);
  // The same planned path (x, y within 5 cm), another road: the pitch differs by more than
  // 0.1 deg somewhere in 40 s.
  double max_pitch_diff = 0, max_xy_diff = 0;
  for (int64_t t = 0; t <= ta.durationNs(); t += 10000000) {
    const Pose3 pa = ta.T_odom_base(t), pb = tb.T_odom_base(t);
    const Vec3 xa = pa.linear() * Vec3::UnitX(), xb = pb.linear() * Vec3::UnitX();
    max_pitch_diff = std::max(max_pitch_diff, std::abs(std::asin(xa.z()) - std::asin(xb.z())));
    max_xy_diff = std::max(max_xy_diff, (pa.translation() - pb.translation()).head<2>().norm());
  }
  EXPECT_GT(max_pitch_diff, 0.1 * kRadPerDeg);
  EXPECT_LT(max_xy_diff, 0.05);
}

}  // namespace
}  // namespace sim
}  // namespace vwe_vo
