// The frame-based baseline: the 1-point Ackermann solver against synthetic correspondences of a
// known arc (exact, and with outliers), end to end on simulated APS frames against ground truth,
// and bad frames.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <random>

#include "vwe_vo/baseline/frame_baseline.h"
#include "vwe_vo/eval/evaluation.h"
#include "vwe_vo/io/config.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sim/frame_simulator.h"
#include "vwe_vo/sim/sequences.h"
#include "vwe_vo/trajectory/ackermann_arc.h"

namespace vwe_vo {
namespace {

const std::string kCalib = std::string(VWE_VO_SOURCE_DIR) + "/config/davis346.yaml";

CameraModel camera() {
  return CameraModel(loadCameraCalibrationYaml(kCalib));
}

struct Synthetic {
  std::vector<Vec3> f_r, f_t;
};

// Random points 1-8 m in front of camera r, seen from camera t after the arc (theta, s).
Synthetic makeCorrespondences(double theta, double s_m, const Pose3& T_base_cam, int n,
                              uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> ux(-0.6, 0.6), uy(-0.4, 0.4), uz(1.0, 8.0);
  const Pose3 T_Cr_Ct = arcT_Cr_Ct(theta, s_m, 1.0, T_base_cam);
  const Pose3 T_Ct_Cr = T_Cr_Ct.inverse();
  Synthetic out;
  while (static_cast<int>(out.f_r.size()) < n) {
    const double z = uz(rng);
    const Vec3 p_r(ux(rng) * z, uy(rng) * z, z);
    const Vec3 p_t = T_Ct_Cr * p_r;
    if (p_t.z() < 0.5) continue;
    out.f_r.push_back(p_r.normalized());
    out.f_t.push_back(p_t.normalized());
  }
  return out;
}

TEST(FrameBaseline, OnePointSolverIsExactWithOurExtrinsics) {
  const Pose3 mounts[] = {defaultTBaseCam(),
                          mountToTBaseCam(Vec3(1.5, 0.0, 1.4), 0.0, 5.0 * kPi / 180, 0.0)};
  const double cases[][2] = {{0.0174, 0.016}, {-0.05, 0.02}, {0.3, 0.5},
                             {-0.25, 1.2},    {0.0, 0.3},    {1e-4, 0.016}};
  int total = 0, unique = 0, none = 0;
  std::vector<double> roots;
  for (const Pose3& T_bc : mounts)
    for (const auto& c : cases) {
      const Synthetic s = makeCorrespondences(c[0], c[1], T_bc, 50, 42);
      for (size_t i = 0; i < s.f_r.size(); ++i) {
        ++total;
        solveTheta1Point(s.f_r[i], s.f_t[i], c[1], T_bc, 0.5, &roots);
        if (roots.empty()) {  // a double root (e touches zero without a sign change): degenerate
                              // track
          ++none;
          continue;
        }
        double best = 1e9;
        for (double r : roots) best = std::min(best, std::abs(r - c[0]));
        EXPECT_LT(best, 1e-6) << "theta " << c[0] << " s " << c[1] << " track " << i << ": "
                              << roots.size() << " roots";
        unique += roots.size() == 1;
      }
    }
  // Every track has the true root (a few degenerate ones none); most have no second root within
  // +-0.5 rad (RANSAC resolves the others).
  std::printf("1-point solver: %d tracks, %d with one root, %d with none\n", total, unique, none);
  EXPECT_LT(none, 0.02 * total);
  EXPECT_GT(unique, 0.5 * total);
}

TEST(FrameBaseline, OffsetMattersClosedFormIsOnlyApproximate) {
  // The on-axle closed form is exact for a camera on the rear axle and biased with our offset.
  Pose3 on_axle = defaultTBaseCam();
  on_axle.translation().setZero();
  const Synthetic a = makeCorrespondences(0.2, 0.3, on_axle, 20, 3);
  for (size_t i = 0; i < a.f_r.size(); ++i)
    EXPECT_NEAR(theta1PointOnAxle(a.f_r[i], a.f_t[i], on_axle), 0.2, 1e-9);
  const Synthetic b = makeCorrespondences(0.2, 0.3, defaultTBaseCam(), 20, 3);
  double max_err = 0;
  for (size_t i = 0; i < b.f_r.size(); ++i)
    max_err =
        std::max(max_err, std::abs(theta1PointOnAxle(b.f_r[i], b.f_t[i], defaultTBaseCam()) - 0.2));
  EXPECT_GT(max_err, 1e-4);
}

TEST(FrameBaseline, RansacWithThirtyPercentOutliers) {
  const Pose3 T_bc = defaultTBaseCam();
  const double theta = 0.035, s_m = 0.016;  // ~50 deg/s and 0.4 m/s over 40 ms
  Synthetic s = makeCorrespondences(theta, s_m, T_bc, 200, 7);
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> off(-0.15, 0.15);  // ~ +-40 px
  std::vector<bool> is_outlier(s.f_r.size(), false);
  for (size_t i = 0; i < s.f_t.size(); i += 10)
    for (size_t k = i; k < i + 3 && k < s.f_t.size(); ++k) {  // 30 %
      Vec3 x = s.f_t[k] / s.f_t[k].z();
      x.x() += off(rng);
      x.y() += off(rng);
      s.f_t[k] = x.normalized();
      is_outlier[k] = true;
    }
  const ThetaRansacResult r =
      estimateThetaRansac(s.f_r, s.f_t, s_m, T_bc, 0.5, 1.0 / 255.0, 200, 12, 1);
  ASSERT_TRUE(r.ok);
  EXPECT_NEAR(r.theta, theta, 1e-6);
  int inlier_outliers = 0;
  for (int i : r.inliers) inlier_outliers += is_outlier[i];
  EXPECT_GE(static_cast<int>(r.inliers.size()), 135);
  EXPECT_LE(inlier_outliers, 6);  // an outlier may land on its own epipolar line by chance

  // With 0.3 px of pixel noise on the inliers it stays within 0.05 deg.
  Synthetic n = makeCorrespondences(theta, s_m, T_bc, 200, 8);
  std::normal_distribution<double> px(0.0, 0.3 / 255.0);
  for (size_t k = 0; k < n.f_t.size(); ++k) {
    Vec3 x = n.f_t[k] / n.f_t[k].z();
    x.x() += k % 10 < 3 ? off(rng) : px(rng);
    x.y() += k % 10 < 3 ? off(rng) : px(rng);
    n.f_t[k] = x.normalized();
  }
  const ThetaRansacResult rn =
      estimateThetaRansac(n.f_r, n.f_t, s_m, T_bc, 0.5, 1.0 / 255.0, 200, 12, 1);
  ASSERT_TRUE(rn.ok);
  EXPECT_NEAR(rn.theta, theta, 0.05 * kPi / 180);
}

TEST(FrameBaseline, OptionsValidateNamesTheField) {
  FrameBaselineOptions o;
  EXPECT_NO_THROW(o.validate());
  o.klt_window_px = 4;
  try {
    o.validate();
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("klt_window_px"), std::string::npos);
  }
}

// Simulated frames of a standard sequence (first duration_s), through the core API.
struct SimRun {
  EvaluationResult eval;
  FrameBaselineStats stats;
  size_t frames = 0;
};

SimRun runOnSequence(const std::string& name, double duration_s,
                     std::vector<FrameEstimate>* estimates = nullptr,
                     std::vector<sim::SimulatedFrame>* frames = nullptr) {
  const sim::SequenceSpec spec = sim::findSequence(name);
  const auto tr = sim::VehicleTrajectory::fromProfile(spec.profile, spec.trajectory);
  const CameraModel cam = camera();
  sim::EventSimulator esim(sim::buildScene(spec.scene, spec.seed, tr), cam, spec.T_base_cam, tr,
                           spec.simulator);
  sim::FrameSimulatorOptions fo;
  fo.seed = spec.seed;
  sim::FrameSimulator fsim(&esim, fo);
  FrameBaselineOptions bo;
  bo.nominal_speed_mps = spec.profile.front().v;
  FrameBaseline baseline(bo, cam, spec.T_base_cam);
  SimRun run;
  for (int64_t t = 0; t <= secToNs(duration_s); t += secToNs(1.0)) {
    for (sim::SimulatedFrame& f :
         fsim.simulateUntil(std::min(t + secToNs(1.0), secToNs(duration_s)))) {
      baseline.addOdometry(f.t_ns, tr.speed(f.t_ns),
                           tr.yawRate(f.t_ns));  // speed (and standstill) as from /odom
      const FrameEstimate e = baseline.addFrame(f.t_ns, f.image);
      EXPECT_TRUE(std::isfinite(e.omega) && std::isfinite(e.theta));
      ++run.frames;
      if (frames) {
        f.image.release();  // the statistics are enough
        frames->push_back(f);
      }
    }
  }
  Trajectory3 gt;
  for (int64_t t = 0; t <= secToNs(duration_s); t += secToNs(0.01))
    gt.push_back({t, tr.T_odom_base(t)});
  EvaluationOptions eo;
  eo.extra_deltas_s.clear();
  run.eval = evaluate(gt, baseline.trajectory(), eo);
  run.stats = baseline.stats();
  if (estimates) *estimates = baseline.estimates();
  return run;
}

TEST(FrameBaseline, TracksSimulatedIndoorCircle) {
  const SimRun r = runOnSequence("indoor_circle", 3.0);
  std::printf(
      "indoor_circle 3 s: %zu frames, %zu ok, %zu lost, rot RPE RMSE %.3f deg/s, tracked %.2f\n",
      r.frames, r.stats.ok, r.stats.lost, r.eval.rpe.rot_rmse_deg_s, r.eval.tracked_fraction);
  EXPECT_GT(r.stats.ok, 0.9 * r.frames);
  EXPECT_GT(r.eval.tracked_fraction, 0.9);
  EXPECT_LE(r.eval.rpe.rot_rmse_deg_s, 0.055);  // measured 0.038
}

TEST(FrameBaseline, TracksSimulatedIndoorStraight) {
  const SimRun r = runOnSequence("indoor_straight", 3.0);
  std::printf(
      "indoor_straight 3 s: %zu frames, %zu ok, %zu lost, rot RPE RMSE %.3f deg/s, tracked %.2f\n",
      r.frames, r.stats.ok, r.stats.lost, r.eval.rpe.rot_rmse_deg_s, r.eval.tracked_fraction);
  EXPECT_GT(r.stats.ok, 0.9 * r.frames);
  EXPECT_GT(r.eval.tracked_fraction, 0.9);
  EXPECT_LE(r.eval.rpe.rot_rmse_deg_s, 0.04);  // measured 0.027
}

TEST(FrameBaseline, TracksSimulatedIndoorLongThroughTwoTurns) {
  // indoor_long: straight, a 90-degree left turn at 30 deg/s, straight, a tighter one at 45 deg/s.
  const SimRun r = runOnSequence("indoor_long", 11.0);
  std::printf(
      "indoor_long 11 s: %zu frames, %zu ok, %zu lost, rot RPE RMSE %.3f deg/s, tracked %.2f\n",
      r.frames, r.stats.ok, r.stats.lost, r.eval.rpe.rot_rmse_deg_s, r.eval.tracked_fraction);
  EXPECT_GT(r.stats.ok + r.stats.standstill, 0.9 * r.frames);
  EXPECT_GT(r.eval.tracked_fraction, 0.9);
  EXPECT_LE(r.eval.rpe.rot_rmse_deg_s, 0.045);  // measured 0.032
}

TEST(FrameBaseline, LosesTrackWhereTheHdrFramesFailNeverNaN) {
  // indoor_hdr: full light, then 5 % from 4 s (ramp from 3.8 s), full light again from 8 s. While
  // the light ramps, consecutive frames differ in brightness by 2x and KLT loses its tracks; the
  // auto-exposure lags and then stays at its 25 ms cap, ~10x below target; when the light returns
  // the frames clip. The baseline must say LOST there, not make up a motion, and never NaN.
  std::vector<FrameEstimate> est;
  std::vector<sim::SimulatedFrame> frames;
  const SimRun r = runOnSequence("indoor_hdr", 9.0, &est, &frames);
  ASSERT_EQ(est.size(), frames.size());
  int bright = 0, bright_ok = 0, ramps = 0, ramps_lost = 0, dark = 0, dark_ok = 0;
  double dark_exposure = 0, bright_exposure = 0, sat_return = 0;
  for (size_t i = 0; i < est.size(); ++i) {
    const double t = nsToSec(est[i].t_ns);
    const bool ok = est[i].status == FrameStatus::kOk;
    EXPECT_TRUE(std::isfinite(est[i].omega) && std::isfinite(est[i].theta) &&
                std::isfinite(est[i].v));
    if (t > 1.0 && t < 3.7) ++bright, bright_ok += ok, bright_exposure = frames[i].exposure_s;
    if ((t > 3.85 && t < 3.97) || (t > 7.85 && t < 7.97))
      ++ramps, ramps_lost += est[i].status == FrameStatus::kLost;
    if (t > 4.5 && t < 7.7) ++dark, dark_ok += ok, dark_exposure = frames[i].exposure_s;
    if (t > 7.97 && t < 8.1) sat_return = std::max(sat_return, frames[i].saturated_fraction);
    if (ok && t > 4.5 && t < 7.7) {  // when it does track in the dark, it is right
      EXPECT_NEAR(est[i].omega * kDegPerRad, 20.0, 3.0) << "at " << t << " s";
    }
  }
  std::printf(
      "indoor_hdr 9 s: bright %d/%d ok (exposure %.1f ms), light ramps %d/%d lost, dark %d/%d ok "
      "(exposure "
      "%.1f ms), %.0f %% saturated after the return, rot RPE RMSE %.3f deg/s, tracked %.2f\n",
      bright_ok, bright, bright_exposure * 1e3, ramps_lost, ramps, dark_ok, dark,
      dark_exposure * 1e3, 100 * sat_return, r.eval.rpe.rot_rmse_deg_s, r.eval.tracked_fraction);
  EXPECT_GT(bright_ok, 0.9 * bright);
  EXPECT_EQ(ramps_lost, ramps);            // every frame of the light ramps is LOST
  EXPECT_DOUBLE_EQ(dark_exposure, 25e-3);  // the auto-exposure is at its cap in the dark
  EXPECT_GT(sat_return, 0.3);              // and far too long when the light returns
  EXPECT_GT(r.stats.lost, 6u);
}

// A textured frame for the bad-input tests.
cv::Mat1b texturedFrame(const CameraModel& cam, uint64_t seed) {
  cv::Mat1b img(cam.height(), cam.width());
  cv::RNG rng(seed);
  rng.fill(img, cv::RNG::UNIFORM, 0, 255);
  cv::Mat1b out;
  cv::GaussianBlur(img, out, cv::Size(0, 0), 2.0);
  cv::normalize(out, out, 0, 255, cv::NORM_MINMAX);
  return out;
}

void expectFinite(const FrameBaseline& b) {
  for (const FrameEstimate& e : b.estimates()) {
    EXPECT_TRUE(std::isfinite(e.theta) && std::isfinite(e.omega) && std::isfinite(e.v));
  }
  for (const StampedPose& p : b.trajectory()) EXPECT_TRUE(p.T.matrix().allFinite());
}

TEST(FrameBaseline, BadFramesAreLostOrRefused) {
  const CameraModel cam = camera();
  FrameBaseline b(FrameBaselineOptions(), cam, defaultTBaseCam());
  const cv::Mat1b tex = texturedFrame(cam, 1);
  EXPECT_EQ(b.addFrame(secToNs(0.00), tex).status, FrameStatus::kFirst);
  // Identical frame: no parallax to estimate from.
  const FrameEstimate same = b.addFrame(secToNs(0.04), tex.clone());
  EXPECT_EQ(same.status, FrameStatus::kLost);
  EXPECT_NE(same.reason.find("identical"), std::string::npos) << same.reason;
  // Black and saturated frames.
  const FrameEstimate black =
      b.addFrame(secToNs(0.08), cv::Mat1b::zeros(cam.height(), cam.width()));
  EXPECT_EQ(black.status, FrameStatus::kLost);
  EXPECT_FALSE(black.reason.empty());
  const FrameEstimate white =
      b.addFrame(secToNs(0.12), cv::Mat1b(cam.height(), cam.width(), uint8_t(255)));
  EXPECT_EQ(white.status, FrameStatus::kLost);
  EXPECT_NE(white.reason.find("over-exposed"), std::string::npos) << white.reason;
  // Back to a textured frame: tracks restart, still not a made-up estimate.
  EXPECT_EQ(b.addFrame(secToNs(0.16), tex).status, FrameStatus::kLost);
  // Wrong size and wrong type are refused with an error naming the sizes.
  try {
    b.addFrame(secToNs(0.20), cv::Mat1b::zeros(cam.height() / 2, cam.width() / 2));
    FAIL() << "wrong size accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("346x260"), std::string::npos) << e.what();
  }
  EXPECT_THROW(b.addFrame(secToNs(0.24), cv::Mat3b::zeros(cam.height(), cam.width())),
               std::invalid_argument);
  EXPECT_THROW(b.addFrame(secToNs(0.10), tex), std::invalid_argument);  // stamp going backwards
  expectFinite(b);
  EXPECT_EQ(b.trajectory().size(), 1u);  // only the first frame: nothing was estimated
  EXPECT_EQ(b.stats().ok, 0u);

  // Black from the start: LOST, no trajectory, no NaN.
  FrameBaseline dark(FrameBaselineOptions(), cam, defaultTBaseCam());
  for (int k = 0; k < 3; ++k)
    EXPECT_EQ(dark.addFrame(secToNs(0.04 * k), cv::Mat1b::zeros(cam.height(), cam.width())).status,
              FrameStatus::kLost);
  EXPECT_TRUE(dark.trajectory().empty());
}

TEST(FrameSimulator, ExposureFollowsTheIlluminationToggleLateAndCapped) {
  // indoor_hdr: light drops to 5 % at 4 s (ramp from 3.8 s). Right after the drop the frame is
  // under-exposed, the auto-exposure then opens up to its 25 ms cap, which leaves the dark frames
  // ~10x below target; the frames after the light returns clip while it closes down again.
  const sim::SequenceSpec spec = sim::findSequence("indoor_hdr");
  const auto tr = sim::VehicleTrajectory::fromProfile(spec.profile, spec.trajectory);
  const CameraModel cam = camera();
  sim::EventSimulator esim(sim::buildScene(spec.scene, spec.seed, tr), cam, spec.T_base_cam, tr,
                           spec.simulator);
  sim::FrameSimulatorOptions fo;
  fo.rate_hz = 5.0;  // fewer renders; the same physics (the lag is in seconds, the delay one frame)
  sim::FrameSimulator fsim(&esim, fo);
  double level_bright = 0, mean_bright = 0, mean_dark_first = -1, mean_dark = 0, sat_after = 0,
         exposure_dark = 0;
  double exposure_at_drop = 0;
  for (const auto& f : fsim.simulateUntil(secToNs(8.6))) {
    const double m = cv::mean(f.image)[0];
    const double t = nsToSec(f.t_ns);
    if (t > 2.0 && t < 3.5) mean_bright = m, level_bright = fsim.meteredLevel(f.image);
    if (t > 3.9 && mean_dark_first < 0) mean_dark_first = m, exposure_at_drop = f.exposure_s;
    if (t > 7.0 && t < 7.9) exposure_dark = f.exposure_s, mean_dark = m;
    if (t > 8.05 && t < 8.3) sat_after = std::max(sat_after, f.saturated_fraction);
    EXPECT_EQ(f.image.rows, cam.height());
  }
  std::printf(
      "hdr frames: bright mean %.1f DN (metered %.2f), first dark mean %.1f DN at %.1f ms, dark "
      "mean %.1f DN "
      "at %.1f ms, saturated after %.2f\n",
      mean_bright, level_bright, mean_dark_first, exposure_at_drop * 1e3, mean_dark,
      exposure_dark * 1e3, sat_after);
  EXPECT_NEAR(level_bright, fo.ae_target,
              0.1);  // the auto-exposure settles on its target in full light
  EXPECT_LT(mean_dark_first,
            0.3 * mean_bright);  // late: the first dark frame keeps the bright exposure
  EXPECT_LT(exposure_at_drop, 2 * fo.exposure_s * 4);  // (it is still near the full-light exposure)
  EXPECT_DOUBLE_EQ(exposure_dark, fo.exposure_max_s);  // capped: the dark frames stay under-exposed
  EXPECT_LT(mean_dark, 0.25 * mean_bright);
  EXPECT_GT(sat_after, 0.15);  // a large part of the frame clips while the auto-exposure catches up
}

TEST(FrameSimulator, DynamicRangeIsAbout55DbIn8Bits) {
  // Temporal noise at (almost) no signal from two frames of the same instant (fixed-pattern noise
  // cancels): full scale over it is the dynamic range, read noise and 8-bit quantisation together.
  const sim::SequenceSpec spec = sim::findSequence("indoor_circle");
  const auto tr = sim::VehicleTrajectory::fromProfile(spec.profile, spec.trajectory);
  const CameraModel cam = camera();
  sim::EventSimulator esim(sim::buildScene(spec.scene, spec.seed, tr), cam, spec.T_base_cam, tr,
                           spec.simulator);
  sim::FrameSimulatorOptions fo;
  fo.auto_exposure = false;
  fo.exposure_s = fo.exposure_min_s;  // 10 us: a few electrons of signal
  sim::FrameSimulator fsim(&esim, fo);
  const cv::Mat1b a = fsim.render(secToNs(1.0)).image, b = fsim.render(secToNs(1.0)).image;
  cv::Mat diff;
  cv::subtract(a, b, diff, cv::noArray(), CV_32F);
  cv::Scalar m, s;
  cv::meanStdDev(diff, m, s);
  const double noise_dn = s[0] / std::sqrt(2.0);
  const double dr_db = 20 * std::log10((255.0 - fo.black_level_dn) / noise_dn);
  std::printf("APS noise floor %.2f DN, dynamic range %.1f dB (full well / read noise %.1f dB)\n",
              noise_dn, dr_db, fo.dynamicRangeDb());
  EXPECT_NEAR(fo.dynamicRangeDb(), 55.0, 1.0);
  EXPECT_GT(dr_db, 50.0);
  EXPECT_LT(dr_db, 56.0);

  // Shot noise: at mid scale the temporal noise is several times the floor.
  fo.exposure_s = 4e-3;
  sim::FrameSimulator mid(&esim, fo);
  const cv::Mat1b c = mid.render(secToNs(1.0)).image, d = mid.render(secToNs(1.0)).image;
  cv::subtract(c, d, diff, cv::noArray(), CV_32F);
  cv::meanStdDev(diff, m, s);
  EXPECT_GT(s[0] / std::sqrt(2.0), 2.0 * noise_dn);
}

TEST(FrameSimulator, MotionBlurGrowsWithExposure) {
  const sim::SequenceSpec spec = sim::findSequence("indoor_circle");
  const auto tr = sim::VehicleTrajectory::fromProfile(spec.profile, spec.trajectory);
  const CameraModel cam = camera();
  sim::EventSimulator esim(sim::buildScene(spec.scene, spec.seed, tr), cam, spec.T_base_cam, tr,
                           spec.simulator);
  auto sharpness = [&](double exposure_s) {
    sim::FrameSimulatorOptions fo;
    fo.auto_exposure = false;
    fo.exposure_s = exposure_s;
    fo.saturation_exposure_s = exposure_s / 0.6;  // same brightness
    fo.read_noise_e = fo.dsnu_dn = fo.prnu = 0;
    fo.full_well_e = 1e9;  // no shot noise
    sim::FrameSimulator fsim(&esim, fo);
    cv::Mat lap;
    cv::Laplacian(fsim.render(secToNs(1.0)).image, lap, CV_64F);
    cv::Scalar m, s;
    cv::meanStdDev(lap, m, s);
    return s[0];
  };
  const double sharp = sharpness(1e-3), blurred = sharpness(25e-3);
  EXPECT_LT(blurred, 0.8 * sharp) << sharp << " vs " << blurred;
}

}  // namespace
}  // namespace vwe_vo
