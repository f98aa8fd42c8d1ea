#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <random>

#include "vwe_vo/eval/evaluation.h"

using namespace vwe_vo;

namespace {

/// Planar ground vehicle at rate_hz for duration_s: yaw(t) given in closed form, speed v(t),
/// position integrated with a fine midpoint rule (position accuracy does not matter for the
/// rotation checks; both trajectories of a test come from the same function).
Trajectory3 planarTrajectory(double duration_s, const std::function<double(double)>& yaw,
                             const std::function<double(double)>& speed, double rate_hz = 100.0) {
  Trajectory3 traj;
  const int substeps = 10;
  const int n = static_cast<int>(std::lround(duration_s * rate_hz));
  const double dt = 1.0 / (rate_hz * substeps);
  double x = 0, y = 0;
  for (int i = 0; i <= n; ++i) {
    const double t = i / rate_hz;
    traj.push_back({secToNs(t), planarPose(x, y, yaw(t))});
    for (int k = 0; k < substeps; ++k) {
      const double tm = t + (k + 0.5) * dt;
      x += speed(tm) * std::cos(yaw(tm)) * dt;
      y += speed(tm) * std::sin(yaw(tm)) * dt;
    }
  }
  return traj;
}

/// A curved drive: omega(t) = 0.3 + 0.2 sin(t) rad/s (+ bias), 1.5 m/s.
Trajectory3 curvedDrive(double duration_s, double yaw_rate_bias = 0.0) {
  return planarTrajectory(
      duration_s, [=](double t) { return 0.3 * t + 0.2 * (1.0 - std::cos(t)) + yaw_rate_bias * t; },
      [](double) { return 1.5; });
}

/// Every pose mapped by the similarity x -> s R x + t of the world (body orientation R * R_i).
Trajectory3 similarCopy(const Trajectory3& in, double s, const Mat3& R, const Vec3& t) {
  Trajectory3 out = in;
  for (StampedPose& sp : out) sp.T = makePose(R * sp.T.linear(), s * (R * sp.T.translation()) + t);
  return out;
}

Mat3 someRotation() {
  return Eigen::AngleAxisd(0.7, Vec3(1, -2, 0.5).normalized()).toRotationMatrix();
}

}  // namespace

TEST(Evaluation, GroundTruthAgainstItselfHasNoError) {
  const Trajectory3 gt = curvedDrive(30.0);
  const EvaluationResult r = evaluate(gt, gt, EvaluationOptions());
  EXPECT_EQ(r.rpe.pairs, 581);  // starts 0, 0.05, ..., 29
  EXPECT_EQ(r.rpe.standstill_pairs, 0);
  EXPECT_LT(r.rpe.rot_rmse_deg_s, 1e-9);
  EXPECT_LT(r.rpe.trans_dir_rmse_deg_s, 1e-9);
  EXPECT_LT(r.yaw_rate_rmse_deg_s, 1e-9);
  EXPECT_LT(r.ate_rmse_m, 1e-9);
  EXPECT_LT(r.ate_se3_rmse_m, 1e-9);
  EXPECT_NEAR(r.ate_scale, 1.0, 1e-9);
  EXPECT_NEAR(r.path_length_m, 45.0, 1e-3);  // 30 s at 1.5 m/s
  EXPECT_NEAR(r.tracked_fraction, 1.0, 1e-12);
  ASSERT_EQ(r.rpe_extra.size(), 1u);
  EXPECT_EQ(r.rpe_extra[0].delta_s, 0.5);
  EXPECT_LT(r.rpe_extra[0].rot_rmse_deg_s, 1e-9);
}

TEST(Evaluation, ConstantYawRateBiasGivesRotationErrorOfTheBias) {
  const double bias = 2.0 / kDegPerRad;  // 2 deg/s
  const Trajectory3 gt = curvedDrive(30.0);
  const Trajectory3 est = curvedDrive(30.0, bias);
  const EvaluationResult r = evaluate(gt, est, EvaluationOptions());
  EXPECT_NEAR(r.rpe.rot_rmse_deg_s, 2.0, 0.02 * 2.0);
  EXPECT_NEAR(r.rpe.rot_median_deg_s, 2.0, 0.02 * 2.0);
  EXPECT_NEAR(r.yaw_rate_rmse_deg_s, 2.0, 0.02 * 2.0);
  EXPECT_GT(r.rpe.trans_dir_rmse_deg_s, 0.1);  // the heading drifts, so does the direction
  // A negative bias gives the same magnitude.
  const EvaluationResult n = evaluate(gt, curvedDrive(30.0, -bias), EvaluationOptions());
  EXPECT_NEAR(n.rpe.rot_rmse_deg_s, 2.0, 0.02 * 2.0);
}

TEST(Evaluation, UmeyamaRecoversAKnownSimilarity) {
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  const Mat3 R = someRotation();
  const Vec3 t(3.0, -1.0, 2.0);
  const double s = 2.5;
  for (bool planar : {false, true}) {  // coplanar points are where the reflection fix matters
    std::vector<Vec3> src, dst;
    for (int i = 0; i < 50; ++i) {
      src.emplace_back(u(rng), u(rng), planar ? 0.0 : u(rng));
      dst.push_back(s * (R * src.back()) + t);
    }
    const Sim3 a = alignUmeyama(src, dst);
    EXPECT_NEAR(a.scale, s, 1e-9) << planar;
    EXPECT_LT((a.R - R).cwiseAbs().maxCoeff(), 1e-9) << planar;
    EXPECT_LT((a.t - t).cwiseAbs().maxCoeff(), 1e-9) << planar;
    EXPECT_NEAR(a.R.determinant(), 1.0, 1e-12);
    // Without scale: still a rotation, scale 1.
    const Sim3 rigid = alignUmeyama(src, dst, false);
    EXPECT_EQ(rigid.scale, 1.0);
    EXPECT_NEAR(rigid.R.determinant(), 1.0, 1e-12);
  }
}

TEST(Evaluation, UmeyamaRejectsBadInput) {
  const std::vector<Vec3> two{Vec3(0, 0, 0), Vec3(1, 0, 0)};
  EXPECT_THROW(alignUmeyama(two, two), std::invalid_argument);
  const std::vector<Vec3> three{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  EXPECT_THROW(alignUmeyama(three, two), std::invalid_argument);
  const std::vector<Vec3> same(3, Vec3(1, 2, 3));
  EXPECT_THROW(alignUmeyama(same, three), std::runtime_error);
}

TEST(Evaluation, SimilarCopyHasNoErrorAndTheInverseScale) {
  const Trajectory3 gt = curvedDrive(30.0);
  const double applied_scale = 0.4;
  const Trajectory3 est = similarCopy(gt, applied_scale, someRotation(), Vec3(5, -3, 1));
  const EvaluationResult r = evaluate(gt, est, EvaluationOptions());
  EXPECT_LT(r.ate_rmse_m, 1e-9);
  EXPECT_NEAR(r.ate_scale, 1.0 / applied_scale, 1e-9);
  EXPECT_GT(r.ate_se3_rmse_m, 1.0);  // without scale the copy does not fit
  EXPECT_LT(r.rpe.rot_rmse_deg_s, 1e-6);
  EXPECT_LT(r.rpe.trans_dir_rmse_deg_s, 1e-6);
  EXPECT_LT(r.yaw_rate_rmse_deg_s, 1e-6);
}

TEST(Evaluation, StandstillPairsAreCountedAndLeftOut) {
  // Straight along x at 1 m/s, standing still in [3, 6] s while the ground truth wobbles
  // sideways by < 1 mm; the estimate creeps forward 1 mm/s instead. Pairs inside the standstill
  // would have a 90 deg direction error if they were counted.
  auto x_gt = [](double t) { return t < 3 ? t : (t < 6 ? 3.0 : t - 3.0); };
  auto y_gt = [](double t) {
    return t > 3 && t < 6 ? 5e-4 * std::sin(2 * kPi * (t - 3) / 1.5) : 0.0;
  };
  auto creep = [](double t) { return t < 3 ? 0.0 : 1e-3 * (std::min(t, 6.0) - 3.0); };
  Trajectory3 gt, est;
  for (int i = 0; i <= 900; ++i) {
    const double t = i / 100.0;
    gt.push_back({secToNs(t), planarPose(x_gt(t), y_gt(t), 0.0)});
    est.push_back({secToNs(t), planarPose(x_gt(t) + creep(t), 0.0, 0.0)});
  }
  const EvaluationResult r = evaluate(gt, est, EvaluationOptions());
  EXPECT_EQ(r.rpe.pairs, 161);            // starts 0 .. 8 s
  EXPECT_EQ(r.rpe.standstill_pairs, 41);  // starts 3.00 .. 5.00 s lie wholly in the standstill
  int left_out = 0;
  for (const RpePair& p : r.rpe.series) left_out += std::isnan(p.trans_dir_err_deg_s) ? 1 : 0;
  EXPECT_EQ(left_out, 41);
  EXPECT_LT(r.rpe.trans_dir_rmse_deg_s, 10.0);
  EXPECT_TRUE(std::isfinite(r.rpe.trans_dir_median_deg_s));
  // The same with a larger threshold leaves out more pairs.
  EvaluationOptions wide;
  wide.standstill_threshold_m = 0.2;
  EXPECT_GT(evaluate(gt, est, wide).rpe.standstill_pairs, 41);
}

TEST(Evaluation, NonOverlappingOrTooShortOverlapThrows) {
  const Trajectory3 gt = curvedDrive(5.0);
  Trajectory3 late = gt;
  for (StampedPose& sp : late) sp.t_ns += secToNs(10.0);
  try {
    evaluate(gt, late, EvaluationOptions());
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("do not overlap"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("[10.000, 15.000] s"), std::string::npos) << e.what();
  }
  Trajectory3 shifted = gt;
  for (StampedPose& sp : shifted) sp.t_ns += secToNs(4.5);  // overlap [4.5, 5] s
  try {
    evaluate(gt, shifted, EvaluationOptions());
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("shorter than delta 1 s"), std::string::npos) << e.what();
  }
  EXPECT_THROW(evaluate(gt, Trajectory3(), EvaluationOptions()), std::runtime_error);
}

TEST(Evaluation, ScaleDriftOfAPerfectTrajectoryIsOne) {
  const Trajectory3 gt = curvedDrive(60.0);  // 90 m
  const Trajectory3 est = similarCopy(gt, 0.4, someRotation(), Vec3(1, 2, 3));
  const EvaluationResult r = evaluate(gt, est, EvaluationOptions());
  ASSERT_EQ(r.scale_drift.ratios.size(), 8u);  // 90 m in segments a step over 10 m
  for (double ratio : r.scale_drift.ratios) EXPECT_NEAR(ratio, 1.0, 1e-9);
  EXPECT_LT(r.scale_drift.max_abs_deviation, 1e-9);

  // Shorter than one segment: no ratio, null in JSON.
  const EvaluationResult s = evaluate(curvedDrive(5.0), curvedDrive(5.0), EvaluationOptions());
  EXPECT_TRUE(s.scale_drift.ratios.empty());
  EXPECT_TRUE(std::isnan(s.scale_drift.min_ratio));
  EXPECT_TRUE(toJson(s)["scale_drift"]["min_ratio"].is_null());
}

TEST(Evaluation, ScaleDriftSeesASpeedChange) {
  // The estimate runs 20 % fast in the second half: segments there differ from the first half.
  auto yaw = [](double t) { return 0.1 * t; };
  const Trajectory3 gt = planarTrajectory(40.0, yaw, [](double) { return 1.0; });
  const Trajectory3 est = planarTrajectory(40.0, yaw, [](double t) { return t < 20 ? 1.0 : 1.2; });
  const EvaluationResult r = evaluate(gt, est, EvaluationOptions());
  ASSERT_GE(r.scale_drift.ratios.size(), 3u);
  EXPECT_NEAR(r.scale_drift.max_ratio / r.scale_drift.min_ratio, 1.2, 0.03);
}

TEST(Evaluation, GapInTheEstimateLowersTheTrackedFraction) {
  const Trajectory3 gt = curvedDrive(10.0);
  Trajectory3 est;
  for (const StampedPose& sp : gt)
    if (sp.t_ns <= secToNs(4.0) || sp.t_ns >= secToNs(5.5)) est.push_back(sp);  // 1.5 s gap
  const EvaluationResult r = evaluate(gt, est, EvaluationOptions());
  EXPECT_NEAR(r.tracked_fraction, (10.0 - 1.5) / 10.0, 1e-9);
  EXPECT_GT(r.rpe.untracked_pairs, 0);
  EXPECT_EQ(r.rpe.pairs + r.rpe.untracked_pairs, 181);
  EXPECT_LT(r.rpe.rot_rmse_deg_s, 1e-9);
  // Short gaps (below max_gap_s) do not count.
  Trajectory3 sparse;
  for (size_t i = 0; i < gt.size(); i += 20) sparse.push_back(gt[i]);  // every 0.2 s
  EXPECT_NEAR(evaluate(gt, sparse, EvaluationOptions()).tracked_fraction, 1.0, 1e-12);
}

TEST(Evaluation, OptionsValidateNamesTheField) {
  auto message = [](const EvaluationOptions& o) {
    try {
      o.validate();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  EvaluationOptions o;
  EXPECT_NO_THROW(o.validate());
  o.delta_s = 0;
  EXPECT_NE(message(o).find("delta_s"), std::string::npos);
  o = EvaluationOptions();
  o.max_gap_s = -1;
  EXPECT_NE(message(o).find("max_gap_s"), std::string::npos);
  o = EvaluationOptions();
  o.pair_step_s = std::nan("");
  EXPECT_NE(message(o).find("pair_step_s"), std::string::npos);
  o = EvaluationOptions();
  o.standstill_threshold_m = -0.1;
  EXPECT_NE(message(o).find("standstill_threshold_m"), std::string::npos);
}

TEST(Evaluation, JsonHasTheDocumentedKeys) {
  const Trajectory3 gt = curvedDrive(12.0);
  const EvaluationResult r = evaluate(gt, curvedDrive(12.0, 0.01), EvaluationOptions());
  const nlohmann::json j = toJson(r);
  for (const char* k : {"delta_s", "pairs", "standstill_pairs", "rot_rmse_deg_s",
                        "rot_median_deg_s", "trans_dir_rmse_deg_s", "trans_dir_median_deg_s"}) {
    EXPECT_TRUE(j["rpe"].contains(k)) << k;
    EXPECT_TRUE(j["rpe_0.5"].contains(k)) << k;
  }
  for (const char* k : {"rmse_m", "percent_of_path", "scale"})
    EXPECT_TRUE(j["ate"].contains(k)) << k;
  for (const char* k : {"yaw_rate_rmse_deg_s", "path_length_m", "tracked_fraction", "scale_drift"})
    EXPECT_TRUE(j.contains(k)) << k;
  EXPECT_EQ(j["rpe"]["delta_s"].get<double>(), 1.0);
  EXPECT_EQ(j["rpe_0.5"]["delta_s"].get<double>(), 0.5);
  EXPECT_EQ(j["rpe"]["pairs"].get<int>(), r.rpe.pairs);
  EXPECT_FALSE(j.contains("series"));
  const nlohmann::json js = toJson(r, true);
  ASSERT_TRUE(js.contains("series"));
  EXPECT_EQ(js["series"]["t_s"].size(), static_cast<size_t>(r.rpe.pairs));
  EXPECT_EQ(js["series"]["rot_err_deg_s"].size(), static_cast<size_t>(r.rpe.pairs));
}

// arcs.csv by header name: the front-end's own yaw rate is omega_without_roll where the file has
// it (a window refined at a roll rate), else omega.
TEST(Evaluation, ArcsCsvReadsTheYawRateWithoutTheRollWhereItIsThere) {
  const std::string path = testing::TempDir() + "/arcs_roll.csv";
  for (const bool with_column : {false, true}) {
    {
      std::ofstream out(path);
      out << "t_start,t_end,omega,status" << (with_column ? ",omega_without_roll" : "") << "\n";
      out << "1.0,1.3,0.25,OK" << (with_column ? ",0.2" : "") << "\n";
      out << "1.3,1.6,0.0,STANDSTILL" << (with_column ? ",0.0" : "") << "\n";
    }
    const std::vector<vwe_vo::WindowYawRate> w = vwe_vo::readArcsCsv(path);
    ASSERT_EQ(w.size(), 2u);
    EXPECT_EQ(w[0].omega_rad_s, with_column ? 0.2 : 0.25);
    EXPECT_EQ(w[0].t_start_ns, 1000000000);
    EXPECT_EQ(w[0].t_end_ns, 1300000000);
    EXPECT_FALSE(w[0].standstill);
    EXPECT_TRUE(w[1].standstill);
  }
}

// Found by fuzz_arcs_csv: a time too large for int64 nanoseconds was converted anyway (UB).
TEST(Evaluation, ArcsCsvRefusesTimesOutsideTheRepresentableRange) {
  const std::string path =
      std::string(VWE_VO_SOURCE_DIR) + "/test/data/fuzz_arcs_time_out_of_range.csv";
  try {
    vwe_vo::readArcsCsv(path);
    FAIL() << "accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("fuzz_arcs_time_out_of_range.csv:3"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("3e19"), std::string::npos) << e.what();
  }
}

namespace {
/// A drive whose yaw rate varies: omega(t) = 0.3 sin(2 pi t / 4) + 0.15 sin(2 pi t / 1.7) rad/s.
double weaveYaw(double t) {
  return 0.3 * 4 / (2 * kPi) * (1 - std::cos(2 * kPi * t / 4)) +
         0.15 * 1.7 / (2 * kPi) * (1 - std::cos(2 * kPi * t / 1.7));
}
}  // namespace

TEST(Evaluation, YawRateLagOfADelayedAndAnAdvancedEstimate) {
  for (const double lag : {0.2, -0.2, 0.0}) {
    // The estimate at t is the truth at t - lag (lag > 0: late).
    const Trajectory3 gt = planarTrajectory(30.0, weaveYaw, [](double) { return 1.0; });
    const Trajectory3 est = planarTrajectory(
        30.0, [=](double t) { return weaveYaw(t - lag); }, [](double) { return 1.0; });
    int samples = 0;
    const double found = yawRateLag(gt, est, EvaluationOptions(), &samples);
    EXPECT_NEAR(found, lag, 0.005) << "lag " << lag;
    EXPECT_GT(samples, 2000);
    const EvaluationResult r = evaluate(gt, est, EvaluationOptions());
    EXPECT_NEAR(r.yaw_rate_lag_s, lag, 0.005);
    // A lagging estimate has a pure yaw error.
    EXPECT_NEAR(r.rpe.tilt_rmse_deg_s, 0.0, 1e-6);
    if (lag != 0) {
      EXPECT_GT(r.rpe.yaw_rmse_deg_s, 1.0);
    }
  }
}

TEST(Evaluation, YawRateLagIsUndefinedWithoutYawRateVariation) {
  const Trajectory3 gt = planarTrajectory(
      20.0, [](double t) { return 0.2 * t; }, [](double) { return 1.0; });
  EXPECT_TRUE(std::isnan(yawRateLag(gt, gt, EvaluationOptions())));
}

TEST(Evaluation, PureTiltErrorHasNoYawPartAndPureYawErrorNoTiltPart) {
  // Truth drives straight; the estimate rolls by phi(t) = a sin(2 pi t / T) about base_link's x.
  const double a = 0.02, period = 3.0;
  const Trajectory3 gt = planarTrajectory(
      20.0, [](double) { return 0.0; }, [](double) { return 1.0; });
  Trajectory3 est = gt;
  for (StampedPose& p : est) {
    const double phi = a * std::sin(2 * kPi * nsToSec(p.t_ns) / period);
    p.T = p.T * makePose(Eigen::AngleAxisd(phi, Vec3::UnitX()).toRotationMatrix(), Vec3::Zero());
  }
  EvaluationOptions o;
  const EvaluationResult r = evaluate(gt, est, o);
  // Independent truth: the error of each pair is a roll by phi(t + Delta) - phi(t).
  double se = 0;
  int n = 0;
  for (const RpePair& p : r.rpe.series) {
    const double t = nsToSec(p.t_ns);
    const double d =
        a * (std::sin(2 * kPi * (t + o.delta_s) / period) - std::sin(2 * kPi * t / period));
    se += std::pow(d * kDegPerRad / o.delta_s, 2);
    ++n;
    EXPECT_NEAR(p.yaw_err_deg_s, 0.0, 1e-9);
  }
  EXPECT_NEAR(r.rpe.yaw_rmse_deg_s, 0.0, 1e-9);
  EXPECT_NEAR(r.rpe.tilt_rmse_deg_s, std::sqrt(se / n), 1e-6);
  EXPECT_NEAR(r.rpe.tilt_rmse_deg_s, r.rpe.rot_rmse_deg_s, 1e-9);
  EXPECT_GT(r.rpe.tilt_rmse_deg_s, 0.5);

  // A yaw-rate bias of 0.01 rad/s on a curved planar drive: a pure heading error.
  const Trajectory3 gt2 = curvedDrive(20.0), est2 = curvedDrive(20.0, 0.01);
  const EvaluationResult r2 = evaluate(gt2, est2, o);
  EXPECT_NEAR(r2.rpe.tilt_rmse_deg_s, 0.0, 1e-6);
  EXPECT_NEAR(r2.rpe.yaw_rmse_deg_s, 0.01 * kDegPerRad, 1e-6);
  EXPECT_NEAR(r2.rpe.yaw_median_deg_s, 0.01 * kDegPerRad, 1e-6);
  const nlohmann::json j = toJson(r2);
  EXPECT_NEAR(j["yaw_rpe_rmse_deg_s"].get<double>(), r2.rpe.yaw_rmse_deg_s, 1e-12);
  EXPECT_TRUE(j.contains("yaw_rpe_median_deg_s"));
  EXPECT_TRUE(j.contains("tilt_rpe_rmse_deg_s"));
  EXPECT_TRUE(j.contains("yaw_rate_lag_s"));
}

TEST(Evaluation, PlanarFloorIsTheErrorOfTheFlattenedTruth) {
  // Truth drives straight along x at 1 m/s and pitches by theta(t) = a sin(2 pi t / T) about
  // base_link's y: the flattened truth's error on each pair is a pitch by
  // theta(t + Delta) - theta(t), and its translation (along x) leaves the truth's, seen from the
  // pitched start frame, by |theta(t)|.
  const double a = 0.02, period = 2.5;
  const Trajectory3 planar = planarTrajectory(
      20.0, [](double) { return 0.0; }, [](double) { return 1.0; });
  Trajectory3 gt = planar;
  auto theta = [&](double t) { return a * std::sin(2 * kPi * t / period); };
  for (StampedPose& p : gt)
    p.T =
        p.T * makePose(Eigen::AngleAxisd(theta(nsToSec(p.t_ns)), Vec3::UnitY()).toRotationMatrix(),
                       Vec3::Zero());
  const Trajectory3 flat = planarProjection(gt);
  ASSERT_EQ(flat.size(), gt.size());
  for (size_t i = 0; i < gt.size(); i += 97)
    EXPECT_TRUE(flat[i].T.isApprox(planar[i].T, 1e-12)) << i;

  EvaluationOptions o;
  const EvaluationResult r = evaluate(gt, planar, o);
  double se_rot = 0, se_dir = 0;
  int n = 0;
  for (const RpePair& p : r.rpe.series) {
    const double t = nsToSec(p.t_ns);
    se_rot += std::pow((theta(t + o.delta_s) - theta(t)) * kDegPerRad / o.delta_s, 2);
    se_dir += std::pow(theta(t) * kDegPerRad / o.delta_s, 2);
    ++n;
  }
  ASSERT_GT(n, 300);
  EXPECT_NEAR(r.planar_floor_rot_rmse_deg_s, std::sqrt(se_rot / n), 1e-6);
  EXPECT_NEAR(r.planar_floor_tilt_rmse_deg_s, std::sqrt(se_rot / n), 1e-6);
  EXPECT_NEAR(r.planar_floor_trans_dir_rmse_deg_s, std::sqrt(se_dir / n), 1e-6);
  EXPECT_GT(r.planar_floor_trans_dir_rmse_deg_s, 0.5);
  // The flattened truth as the estimate scores exactly the floor.
  EXPECT_NEAR(r.rpe.rot_rmse_deg_s, r.planar_floor_rot_rmse_deg_s, 1e-9);
  EXPECT_NEAR(r.rpe.trans_dir_rmse_deg_s, r.planar_floor_trans_dir_rmse_deg_s, 1e-9);
  const nlohmann::json j = toJson(r);
  EXPECT_NEAR(j["planar_floor"]["trans_dir_rmse_deg_s"].get<double>(),
              r.planar_floor_trans_dir_rmse_deg_s, 1e-12);

  // A planar truth has no floor.
  const EvaluationResult r0 = evaluate(planar, gt, o);
  EXPECT_LT(r0.planar_floor_rot_rmse_deg_s, 1e-9);
  EXPECT_LT(r0.planar_floor_trans_dir_rmse_deg_s, 1e-9);
}
