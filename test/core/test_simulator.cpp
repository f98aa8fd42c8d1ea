// Event simulator: events against independent truths (noise statistics, rotation warping with
// the true trajectory, depth of a known wall, Ackermann geometry of the trajectories).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "vwe_vo/io/config.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sim/event_simulator.h"
#include "vwe_vo/sim/scene.h"
#include "vwe_vo/sim/sequences.h"

namespace vwe_vo {
namespace sim {
namespace {

constexpr double kDeg = kPi / 180.0;

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
      simulate(circleProfile(0.4, 25 * kDeg, 1.0), 0.25, EventSimulatorOptions());
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
  const auto tr = VehicleTrajectory::fromProfile(circleProfile(0.4, 25 * kDeg, 1.0));
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
  const auto tr = VehicleTrajectory::fromProfile(circleProfile(0.4, 25 * kDeg, 1.0));
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
  const EventVector ev = simulate(circleProfile(0.4, 25 * kDeg, 1.0), 0.3, EventSimulatorOptions());
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
  const auto tr = VehicleTrajectory::fromProfile(rotationProfile(30 * kDeg, 0.3));
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
  const EventVector ev = simulate(circleProfile(0.4, 25 * kDeg, 1.0), 0.55, opt, &st);
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
  const double v = 0.4, w = 25 * kDeg;
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
  EXPECT_NEAR(wrapAngle(tr.planar(tr.durationNs()).z() - wrapAngle(300 * kDeg)), 0.0, 1e-6);
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

}  // namespace
}  // namespace sim
}  // namespace vwe_vo
