#include "vwe_vo/baseline/frame_baseline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <random>
#include <stdexcept>

namespace vwe_vo {

namespace {

// The camera motion for yaw theta along an arc of length s_m: the shared arc model with
// dt = 1 s, so omega = theta and v = s_m.
Pose3 cameraMotion(double theta, double s_m, const Pose3& T_base_cam, ArcJacobian* jac = nullptr) {
  return arcT_Cr_Ct(theta, s_m, 1.0, T_base_cam, jac);
}

double epipolar(const Pose3& T, const Vec3& f_r, const Vec3& f_t) {
  return f_r.dot(T.translation().cross(T.linear() * f_t));
}

std::string fmt(const char* f, double a, double b = 0) {
  char buf[160];
  std::snprintf(buf, sizeof(buf), f, a, b);
  return buf;
}

}  // namespace

void FrameBaselineOptions::validate(const std::string& section) const {
  auto fail = [&](const std::string& m) { throw std::invalid_argument(section + "." + m); };
  if (max_features < 8) fail("max_features must be >= 8");
  if (!(quality_level > 0 && quality_level < 1)) fail("quality_level must be in (0, 1)");
  if (!(min_distance_px >= 1)) fail("min_distance_px must be >= 1 [px]");
  if (klt_window_px < 5 || klt_window_px % 2 == 0) fail("klt_window_px must be odd and >= 5 [px]");
  if (klt_levels < 0 || klt_levels > 6) fail("klt_levels must be in [0, 6]");
  if (!(max_fb_error_px > 0)) fail("max_fb_error_px must be positive [px]");
  if (border_px < 0) fail("border_px must be >= 0 [px]");
  if (min_tracks < 2) fail("min_tracks must be >= 2");
  if (min_inliers < 2) fail("min_inliers must be >= 2");
  if (!(min_inlier_fraction >= 0 && min_inlier_fraction <= 1))
    fail("min_inlier_fraction must be in [0, 1]");
  if (!(inlier_threshold_px > 0)) fail("inlier_threshold_px must be positive [px]");
  if (max_hypotheses < 1) fail("max_hypotheses must be >= 1");
  if (!(omega_max_rad_s > 0)) fail("omega_max_rad_s must be positive [rad/s]");
  if (!(nominal_speed_mps >= 0 && std::isfinite(nominal_speed_mps)))
    fail("nominal_speed_mps must be >= 0 [m/s]");
  if (!(standstill_speed_mps >= 0)) fail("standstill_speed_mps must be >= 0 [m/s]");
  if (!(odom_max_age_s > 0)) fail("odom_max_age_s must be positive [s]");
  if (!(min_contrast_dn >= 0)) fail("min_contrast_dn must be >= 0 [DN]");
  if (!(max_saturated_fraction > 0 && max_saturated_fraction <= 1))
    fail("max_saturated_fraction must be in (0, 1]");
  if (!(min_median_flow_px >= 0)) fail("min_median_flow_px must be >= 0 [px]");
  if (!(max_frame_gap_s > 0)) fail("max_frame_gap_s must be positive [s]");
}

const char* toString(FrameStatus s) {
  switch (s) {
    case FrameStatus::kOk:
      return "OK";
    case FrameStatus::kStandstill:
      return "STANDSTILL";
    case FrameStatus::kLost:
      return "LOST";
    case FrameStatus::kFirst:
      return "FIRST";
  }
  return "?";
}

// ------------------------------------------------------------------------------------------------
// 1-point solver

double theta1PointOnAxle(const Vec3& f_r, const Vec3& f_t, const Pose3& T_base_cam) {
  const Vec3 a = T_base_cam.linear() * f_r, b = T_base_cam.linear() * f_t;
  const double num = a.y() * b.z() - a.z() * b.y();
  const double den = a.x() * b.z() + a.z() * b.x();
  if (den == 0.0) return num == 0.0 ? 0.0 : (num > 0 ? kPi : -kPi);
  return 2.0 * std::atan(num / den);
}

int solveTheta1Point(const Vec3& f_r, const Vec3& f_t, double s_m, const Pose3& T_base_cam,
                     double theta_max, std::vector<double>* thetas) {
  thetas->clear();
  auto e = [&](double th) { return epipolar(cameraMotion(th, s_m, T_base_cam), f_r, f_t); };
  // Bracket sign changes on a grid no coarser than kStep, then polish each by safeguarded Newton
  // (bisection whenever a Newton step leaves the bracket).
  constexpr double kStep = 0.005;
  const int n = std::max(4, static_cast<int>(std::ceil(2.0 * theta_max / kStep)));
  double x0 = -theta_max, e0 = e(x0);
  for (int k = 1; k <= n; ++k) {
    const double x1 = -theta_max + 2.0 * theta_max * k / n, e1 = e(x1);
    if (e0 == 0.0) thetas->push_back(x0);
    if (e0 * e1 < 0.0) {
      double lo = x0, hi = x1, elo = e0, x = 0.5 * (x0 + x1);
      for (int it = 0; it < 100; ++it) {
        ArcJacobian jac;
        const Pose3 T = cameraMotion(x, s_m, T_base_cam, &jac);
        const Vec3 Rf = T.linear() * f_t;
        const double ex = f_r.dot(T.translation().cross(Rf));
        const double de =
            f_r.dot(jac.dp_domega.cross(Rf)) + f_r.dot(T.translation().cross(jac.dR_domega * f_t));
        if (ex == 0.0) break;
        if ((ex < 0) == (elo < 0))
          lo = x, elo = ex;
        else
          hi = x;
        double next = de != 0.0 ? x - ex / de : 0.5 * (lo + hi);
        if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
        const bool done = std::abs(next - x) < 1e-15 || hi - lo < 1e-14;
        x = next;
        if (done) break;
      }
      thetas->push_back(x);
    }
    x0 = x1, e0 = e1;
  }
  return static_cast<int>(thetas->size());
}

double sampsonDistance(const Pose3& T_Cr_Ct, const Vec3& f_r, const Vec3& f_t) {
  if (f_r.z() <= 1e-9 || f_t.z() <= 1e-9) return std::numeric_limits<double>::infinity();
  const Vec3 xr = f_r / f_r.z(), xt = f_t / f_t.z();
  const Mat3 E = skew(T_Cr_Ct.translation()) * T_Cr_Ct.linear();
  const Vec3 Ex = E * xt, Etx = E.transpose() * xr;
  const double r = xr.dot(Ex);
  const double den = Ex.x() * Ex.x() + Ex.y() * Ex.y() + Etx.x() * Etx.x() + Etx.y() * Etx.y();
  if (!(den > 0)) return std::numeric_limits<double>::infinity();
  return std::abs(r) / std::sqrt(den);
}

ThetaRansacResult estimateThetaRansac(const std::vector<Vec3>& f_r, const std::vector<Vec3>& f_t,
                                      double s_m, const Pose3& T_base_cam, double theta_max,
                                      double threshold_norm, int max_hypotheses, int min_inliers,
                                      uint64_t seed) {
  if (f_r.size() != f_t.size())
    throw std::invalid_argument("estimateThetaRansac: " + std::to_string(f_r.size()) + " vs " +
                                std::to_string(f_t.size()) + " bearings");
  ThetaRansacResult res;
  const size_t n = f_r.size();
  std::vector<double> candidates, roots;
  for (size_t i = 0; i < n; ++i) {
    solveTheta1Point(f_r[i], f_t[i], s_m, T_base_cam, theta_max, &roots);
    candidates.insert(candidates.end(), roots.begin(), roots.end());  // every root is a hypothesis
  }
  if (candidates.empty()) return res;
  if (candidates.size() > static_cast<size_t>(max_hypotheses)) {
    std::mt19937_64 rng(seed);
    std::shuffle(candidates.begin(), candidates.end(), rng);
    candidates.resize(max_hypotheses);
  }
  const double thr2 = threshold_norm * threshold_norm;
  // MSAC score: sum of truncated squared Sampson distances (lower is better).
  auto score = [&](double th, std::vector<int>* inl) {
    const Pose3 T = cameraMotion(th, s_m, T_base_cam);
    double c = 0;
    if (inl) inl->clear();
    for (size_t i = 0; i < n; ++i) {
      const double d = sampsonDistance(T, f_r[i], f_t[i]);
      const double d2 = std::isfinite(d) ? d * d : thr2;
      if (d2 < thr2) {
        c += d2;
        if (inl) inl->push_back(static_cast<int>(i));
      } else {
        c += thr2;
      }
    }
    return c;
  };
  double best = std::numeric_limits<double>::infinity(), best_th = 0;
  for (double th : candidates) {
    const double c = score(th, nullptr);
    if (c < best) best = c, best_th = th;
  }
  // Refinement: Gauss-Newton on the inliers' Sampson distances (numeric derivative), twice with
  // the inlier set recomputed in between; a step is kept only if it lowers the cost.
  std::vector<int> inl;
  double th = best_th;
  for (int round = 0; round < 3; ++round) {
    score(th, &inl);
    if (round == 2) {
      // Last round without the inliers beyond 3 robust sigmas (MAD) of the inliers' distances:
      // an outlier that fell within the threshold by chance no longer biases theta.
      const Pose3 T = cameraMotion(th, s_m, T_base_cam);
      std::vector<double> d(inl.size());
      for (size_t k = 0; k < inl.size(); ++k) d[k] = sampsonDistance(T, f_r[inl[k]], f_t[inl[k]]);
      std::vector<double> sorted = d;
      std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
      const double cut = 3.0 * 1.4826 * (sorted.empty() ? 0.0 : sorted[sorted.size() / 2]);
      std::vector<int> kept;
      for (size_t k = 0; k < inl.size(); ++k)
        if (d[k] <= cut) kept.push_back(inl[k]);
      if (kept.size() * 2 < inl.size() || static_cast<int>(kept.size()) < min_inliers) break;
      inl.swap(kept);
    }
    if (inl.size() < 2) break;
    auto cost = [&](double x, std::vector<double>* r) {
      const Pose3 T = cameraMotion(x, s_m, T_base_cam);
      double c = 0;
      r->resize(inl.size());
      for (size_t k = 0; k < inl.size(); ++k) {
        // Signed residual keeps Gauss-Newton well defined through zero.
        const Vec3 &a = f_r[inl[k]], &b = f_t[inl[k]];
        const double d = sampsonDistance(T, a, b);
        const double sgn = epipolar(T, a, b) >= 0 ? 1.0 : -1.0;
        (*r)[k] = std::isfinite(d) ? sgn * d : 0.0;
        c += (*r)[k] * (*r)[k];
      }
      return c;
    };
    std::vector<double> r0, r1;
    double c0 = cost(th, &r0);
    for (int it = 0; it < 20; ++it) {
      const double h = 1e-7;
      cost(th + h, &r1);
      double jtj = 0, jtr = 0;
      for (size_t k = 0; k < r0.size(); ++k) {
        const double J = (r1[k] - r0[k]) / h;
        jtj += J * J;
        jtr += J * r0[k];
      }
      if (!(jtj > 0)) break;
      const double step = -jtr / jtj;
      std::vector<double> rn;
      const double cn = cost(th + step, &rn);
      if (!(cn < c0)) break;
      th += step;
      c0 = cn;
      r0.swap(rn);
      if (std::abs(step) < 1e-12) break;
    }
  }
  score(th, &inl);  // inliers reported at the full threshold
  res.theta = th;
  res.inliers = inl;
  res.ok = static_cast<int>(inl.size()) >= min_inliers && std::isfinite(th);
  return res;
}

// ------------------------------------------------------------------------------------------------
// FrameBaseline

FrameBaseline::FrameBaseline(const FrameBaselineOptions& options, const CameraModel& camera,
                             const Pose3& T_base_cam)
    : options_(options), camera_(camera), T_base_cam_(T_base_cam), chain_(Pose3::Identity(), 0) {
  options_.validate();
  focal_px_ = 0.5 * (camera.calibration().fx + camera.calibration().fy);
}

void FrameBaseline::addOdometry(int64_t t_ns, double v_mps, double /*yaw_rate_rad_s*/) {
  if (!std::isfinite(v_mps)) return;
  odom_.emplace_back(t_ns, v_mps);
  while (odom_.size() > 2 && odom_.front().first < t_ns - secToNs(10 * options_.odom_max_age_s))
    odom_.pop_front();
}

double FrameBaseline::speedAt(int64_t t_ns) const {
  const int64_t max_age = secToNs(options_.odom_max_age_s);
  double best_v = options_.nominal_speed_mps;
  int64_t best_d = max_age + 1;
  for (const auto& o : odom_) {
    const int64_t d = std::abs(o.first - t_ns);
    if (d < best_d) best_d = d, best_v = o.second;
  }
  return best_v;
}

void FrameBaseline::detectFeatures(const cv::Mat& image) {
  const int want = options_.max_features - static_cast<int>(prev_points_.size());
  if (want <= 0) return;
  cv::Mat mask(image.size(), CV_8U, cv::Scalar(0));
  const int b = options_.border_px;
  if (image.cols > 2 * b && image.rows > 2 * b)
    mask(cv::Rect(b, b, image.cols - 2 * b, image.rows - 2 * b)).setTo(255);
  for (const auto& p : prev_points_)
    cv::circle(mask, p, static_cast<int>(std::ceil(options_.min_distance_px)), cv::Scalar(0), -1);
  std::vector<cv::Point2f> fresh;
  cv::goodFeaturesToTrack(image, fresh, want, options_.quality_level, options_.min_distance_px,
                          mask, 3);
  prev_points_.insert(prev_points_.end(), fresh.begin(), fresh.end());
}

FrameEstimate FrameBaseline::finish(FrameEstimate e) {
  ++stats_.frames;
  if (e.status == FrameStatus::kOk) ++stats_.ok;
  if (e.status == FrameStatus::kStandstill) ++stats_.standstill;
  if (e.status == FrameStatus::kLost) ++stats_.lost;
  if (e.status == FrameStatus::kFirst) {
    chain_ = ArcChain(Pose3::Identity(), e.t_ns);
    started_ = true;
    trajectory_.push_back({e.t_ns, chain_.T_odom_base(e.t_ns)});
  } else {
    const bool good = e.status == FrameStatus::kOk || e.status == FrameStatus::kStandstill;
    if (good) last_omega_ = e.omega;
    // LOST coasts on the last yaw rate so the chain stays continuous; it is not output.
    chain_.append(good ? e.omega : last_omega_, good ? e.v : speedAt(e.t_ns), e.t_ns);
    if (good) trajectory_.push_back({e.t_ns, chain_.T_odom_base(e.t_ns)});
  }
  estimates_.push_back(e);
  return e;
}

FrameEstimate FrameBaseline::addFrame(int64_t t_ns, const cv::Mat& image) {
  const auto wall0 = std::chrono::steady_clock::now();
  struct Timer {
    std::chrono::steady_clock::time_point t0;
    double* acc;
    ~Timer() {
      *acc += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    }
  } timer{wall0, &stats_.processing_s};

  if (image.empty() || image.type() != CV_8UC1)
    throw std::invalid_argument(
        "FrameBaseline: frame must be 8-bit single channel (mono8), got type " +
        std::to_string(image.type()) + (image.empty() ? " (empty)" : ""));
  if (image.cols != camera_.width() || image.rows != camera_.height())
    throw std::invalid_argument("FrameBaseline: frame is " + std::to_string(image.cols) + "x" +
                                std::to_string(image.rows) + " but the calibration is " +
                                std::to_string(camera_.width()) + "x" +
                                std::to_string(camera_.height()));
  if (started_ && t_ns <= chain_.endTime())
    throw std::invalid_argument("FrameBaseline: frame stamp " + fmt("%.6f", nsToSec(t_ns)) +
                                " s is not after the previous " +
                                fmt("%.6f", nsToSec(chain_.endTime())) + " s");
  FrameEstimate e;
  e.t_ns = t_ns;
  e.t_prev_ns = prev_t_ns_;
  dbg_from_.clear(), dbg_to_.clear(), dbg_inlier_.clear();

  // Image quality: black, saturated or flat frames carry nothing to track.
  cv::Scalar mean, stddev;
  cv::meanStdDev(image, mean, stddev);
  const double saturated = static_cast<double>(cv::countNonZero(image >= 255)) / image.total();
  std::string bad;
  if (saturated > options_.max_saturated_fraction)
    bad = fmt("over-exposed (%.0f %% saturated)", 100 * saturated);
  else if (stddev[0] < options_.min_contrast_dn)
    bad = fmt("low contrast (std dev %.2f DN, mean %.1f DN)", stddev[0], mean[0]);
  if (!bad.empty()) {
    prev_image_.release();
    prev_points_.clear();
    prev_t_ns_ = -1;
    e.status = FrameStatus::kLost;
    e.reason = bad;
    if (!started_) {  // nothing to anchor the chain to yet
      ++stats_.frames, ++stats_.lost;
      estimates_.push_back(e);
      return e;
    }
    return finish(e);
  }

  const bool restart = prev_image_.empty() || dtSec(t_ns, prev_t_ns_) > options_.max_frame_gap_s;
  if (restart) {
    const bool gap = !prev_image_.empty();
    prev_points_.clear();
    prev_image_ = image.clone();
    prev_t_ns_ = t_ns;
    detectFeatures(prev_image_);
    e.status = started_ ? FrameStatus::kLost : FrameStatus::kFirst;
    if (started_) e.reason = gap ? "frame gap: tracks restarted" : "tracks restarted";
    return finish(e);
  }

  // Sensor noise makes two real frames differ: an identical one is a repeated frame. LOST, and the
  // previous frame stays the reference with its stamp, so that the next real frame measures the
  // motion over the time that really passed.
  if (cv::norm(image, prev_image_, cv::NORM_INF) == 0) {
    e.status = FrameStatus::kLost;
    e.reason = "frame identical to the previous one";
    return finish(e);
  }

  const double dt = dtSec(t_ns, prev_t_ns_);
  e.v = speedAt(t_ns);
  auto lose = [&](const std::string& why) {
    e.status = FrameStatus::kLost;
    e.reason = why;
  };

  std::vector<cv::Point2f> cur, back;
  std::vector<uchar> st_f, st_b;
  std::vector<float> err;
  const cv::Size win(options_.klt_window_px, options_.klt_window_px);
  const cv::TermCriteria term(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.01);
  std::vector<cv::Point2f> p0, p1;
  if (!prev_points_.empty()) {
    cv::calcOpticalFlowPyrLK(prev_image_, image, prev_points_, cur, st_f, err, win,
                             options_.klt_levels, term);
    cv::calcOpticalFlowPyrLK(image, prev_image_, cur, back, st_b, err, win, options_.klt_levels,
                             term);
    const float b = static_cast<float>(options_.border_px);
    for (size_t i = 0; i < prev_points_.size(); ++i) {
      if (!st_f[i] || !st_b[i]) continue;
      const cv::Point2f& q = cur[i];
      if (!(q.x >= b && q.y >= b && q.x < image.cols - 1 - b && q.y < image.rows - 1 - b)) continue;
      if (cv::norm(back[i] - prev_points_[i]) > options_.max_fb_error_px) continue;
      p0.push_back(prev_points_[i]);
      p1.push_back(q);
    }
  }
  e.tracks = static_cast<int>(p0.size());
  std::vector<float> flow(p0.size());
  for (size_t i = 0; i < p0.size(); ++i) flow[i] = static_cast<float>(cv::norm(p1[i] - p0[i]));
  double median_flow = 0;
  if (!flow.empty()) {
    std::nth_element(flow.begin(), flow.begin() + flow.size() / 2, flow.end());
    median_flow = flow[flow.size() / 2];
  }
  std::vector<bool> inlier(p0.size(), false);
  if (e.tracks < options_.min_tracks) {
    lose(fmt("%.0f tracks survive (< %.0f)", e.tracks, options_.min_tracks));
  } else if (e.v < options_.standstill_speed_mps) {
    e.status = FrameStatus::kStandstill;
    e.v = 0.0;
  } else if (median_flow < options_.min_median_flow_px) {
    lose(fmt("no parallax (median flow %.3f px) while moving at %.2f m/s", median_flow, e.v));
  } else {
    std::vector<Vec3> fr(p0.size()), ft(p0.size());
    for (size_t i = 0; i < p0.size(); ++i) {
      fr[i] = camera_.bearingAt(p0[i].x, p0[i].y);
      ft[i] = camera_.bearingAt(p1[i].x, p1[i].y);
    }
    const ThetaRansacResult r =
        estimateThetaRansac(fr, ft, e.v * dt, T_base_cam_, options_.omega_max_rad_s * dt,
                            options_.inlier_threshold_px / focal_px_, options_.max_hypotheses,
                            options_.min_inliers, options_.seed + rng_counter_++);
    e.inliers = static_cast<int>(r.inliers.size());
    for (int i : r.inliers) inlier[i] = true;
    if (!r.ok || e.inliers < options_.min_inlier_fraction * e.tracks) {
      lose(fmt("%.0f inliers of %.0f tracks", e.inliers, e.tracks));
    } else {
      e.status = FrameStatus::kOk;
      e.theta = r.theta;
      e.omega = r.theta / dt;
    }
  }
  dbg_from_ = p0;
  dbg_to_ = p1;
  dbg_inlier_ = inlier;

  // Keep the tracks (without RANSAC outliers when there was a model) and top up.
  const bool have_model = e.status == FrameStatus::kOk;
  prev_points_.clear();
  for (size_t i = 0; i < p1.size(); ++i)
    if (!have_model || inlier[i]) prev_points_.push_back(p1[i]);
  prev_image_ = image.clone();
  prev_t_ns_ = t_ns;
  detectFeatures(prev_image_);
  return finish(e);
}

cv::Mat FrameBaseline::debugImage() const {
  cv::Mat out;
  if (prev_image_.empty()) return out;
  cv::cvtColor(prev_image_, out, cv::COLOR_GRAY2BGR);
  for (size_t i = 0; i < dbg_to_.size(); ++i) {
    const cv::Scalar c = dbg_inlier_[i] ? cv::Scalar(0, 255, 0) : cv::Scalar(0, 0, 255);
    cv::line(out, dbg_from_[i], dbg_to_[i], c, 1, cv::LINE_AA);
    cv::circle(out, dbg_to_[i], 2, c, -1, cv::LINE_AA);
  }
  return out;
}

}  // namespace vwe_vo
