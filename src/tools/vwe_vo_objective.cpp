// vwe_vo_objective: the front-end objective (the VWE's contrast) over the yaw rate for one window
// of a recording, to see why a window's omega came out where it did.
//
//   vwe_vo_objective --bag FILE --t S [--gt GT.tum] [--config YAML] [--duration S] [--v V]
//                    [--range DEG_S] [--step DEG_S] [--out CSV] [--dump-events F] [--events F]
//
// Reads the events of [t - duration/2, t + duration/2) (t in seconds, the bag's time base),
// leaves out the ground mask's pixels and subsamples them as the front-end does, and writes
// `omega_deg_s,contrast` for omega in [centre - range, centre + range]. With --gt the speed and the
// true yaw rate over the window come from the ground truth (TUM), the scan is centred on the truth
// and the header says where the objective peaks relative to it; without it the speed is --v
// (default: the config's nominal speed) and the scan is centred on 0. scripts/plot_objective.py
// draws the CSV.
// --dump-events writes the window's events (`t_ns x y p`, one a line) before subsampling;
// --events reads the window from such a file instead (e.g. a filtered dump), to find which
// events pull the peak.
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>

#include "vwe_vo/EventArray.h"
#include "vwe_vo/frontend/frontend.h"
#include "vwe_vo/io/files.h"
#include "vwe_vo/io/options_yaml.h"
#include "vwe_vo/io/trajectory_io.h"
#include "vwe_vo/ros/conversions.h"
#include "vwe_vo/sensor/subsample.h"

namespace {

constexpr const char* kUsage =
    "usage: vwe_vo_objective --bag FILE --t S [--gt GT.tum] [--config YAML] [--duration S]\n"
    "                        [--v V] [--range DEG_S] [--step DEG_S] [--events-topic T] [--out "
    "CSV]\n"
    "                        [--dump-events FILE] [--events FILE]\n"
    "  Writes the front-end objective (the VWE's contrast) over the yaw rate for the window of\n"
    "  --duration (default: the config's window_duration_s) centred at --t [s, bag time] as CSV\n"
    "  `omega_deg_s,contrast` (stdout unless --out). With --gt (TUM of base_link) the speed and\n"
    "  the true yaw rate come from the ground truth and the scan is centred on the truth.\n"
    "  --dump-events writes the window's events (`t_ns x y p`) before subsampling; --events\n"
    "  reads the window from such a file (events outside the window are ignored).\n";

}  // namespace

int main(int argc, char** argv) {
  std::map<std::string, std::string> args;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      std::cout << kUsage;
      return 0;
    }
    if (a.rfind("--", 0) == 0 && i + 1 < argc) {
      args[a] = argv[++i];
    } else {
      std::cerr << "vwe_vo_objective: unexpected argument '" << a << "'\n" << kUsage;
      return 2;
    }
  }
  if (!args.count("--bag") || !args.count("--t")) {
    std::cerr << "vwe_vo_objective: --bag and --t are required\n" << kUsage;
    return 2;
  }
  try {
    const vwe_vo::PipelineConfig cfg = vwe_vo::loadPipelineConfig(
        args.count("--config") ? args["--config"] : vwe_vo::defaultConfigDir() + "/vwe_vo.yaml");
    const double duration =
        args.count("--duration") ? std::stod(args["--duration"]) : cfg.frontend.window_duration_s;
    const double range =
        (args.count("--range") ? std::stod(args["--range"]) : 10.0) / vwe_vo::kDegPerRad;
    const double step =
        (args.count("--step") ? std::stod(args["--step"]) : 0.1) / vwe_vo::kDegPerRad;
    if (!(duration > 0) || !(range > 0) || !(step > 0) || range / step > 100000)
      throw std::invalid_argument(
          "--duration, --range and --step must be positive (range/step <= 1e5)");
    const int64_t t_ref = vwe_vo::secToNs(std::stod(args["--t"]));
    const int64_t t0 = t_ref - vwe_vo::secToNs(duration / 2),
                  t1 = t_ref + vwe_vo::secToNs(duration / 2);

    double v = args.count("--v") ? std::stod(args["--v"]) : cfg.frontend.nominal_speed_mps;
    double omega_true = std::nan("");
    if (args.count("--gt")) {
      const vwe_vo::Trajectory3 gt = vwe_vo::readTum(args["--gt"]);
      vwe_vo::Pose3 A, B;
      if (!vwe_vo::interpolateTrajectory(gt, t0, &A) || !vwe_vo::interpolateTrajectory(gt, t1, &B))
        throw std::runtime_error("--gt " + args["--gt"] + " does not cover the window [" +
                                 std::to_string(vwe_vo::nsToSec(t0)) + ", " +
                                 std::to_string(vwe_vo::nsToSec(t1)) + "] s");
      const vwe_vo::Pose3 rel = A.inverse() * B;
      omega_true = vwe_vo::wrapAngle(vwe_vo::yawOf(rel.linear())) / duration;
      if (!args.count("--v")) v = rel.translation().head<2>().norm() / duration;
    }

    const std::string topic = args.count("--events-topic") ? args["--events-topic"] : "/dvs/events";
    vwe_vo::EventVector window;
    if (args.count("--events")) {
      std::ifstream in(args["--events"]);
      if (!in) throw std::runtime_error("cannot read " + args["--events"]);
      std::string line;
      for (size_t line_no = 1; std::getline(in, line); ++line_no) {
        std::istringstream fields(line);
        long long t;
        int x, y, p;
        if (!(fields >> t >> x >> y >> p) || x < 0 || y < 0 || x > 65535 || y > 65535)
          throw std::runtime_error(args["--events"] + ":" + std::to_string(line_no) +
                                   ": expected `t_ns x y p`, got '" + line + "'");
        if (t >= t0 && t < t1) window.push_back({int64_t(t), uint16_t(x), uint16_t(y), int8_t(p)});
      }
    } else {
      rosbag::Bag bag(args["--bag"], rosbag::bagmode::Read);
      // Packets are stamped with their first event: start a little early.
      rosbag::View view(bag, rosbag::TopicQuery(topic),
                        vwe_vo::toRosTime(t0 - vwe_vo::secToNs(0.2)), vwe_vo::toRosTime(t1));
      vwe_vo::EventVector packet;
      vwe_vo::EventConversionStats conv;
      for (const rosbag::MessageInstance& m : view) {
        const auto msg = m.instantiate<vwe_vo::EventArray>();
        if (!msg) continue;
        vwe_vo::eventsFromMsg(*msg, &packet, &conv);
        for (const vwe_vo::PixelEvent& e : packet)
          if (e.t_ns >= t0 && e.t_ns < t1) window.push_back(e);
      }
    }
    if (window.empty()) throw std::runtime_error("no events on " + topic + " in the window");
    if (args.count("--dump-events")) {
      std::ofstream dump(args["--dump-events"]);
      if (!dump) throw std::runtime_error("cannot write " + args["--dump-events"]);
      for (const vwe_vo::PixelEvent& e : window)
        dump << e.t_ns << " " << e.x << " " << e.y << " " << int(e.polarity) << "\n";
    }

    const vwe_vo::CameraModel camera(cfg.camera);
    vwe_vo::Frontend frontend(cfg.frontend, camera, cfg.T_base_cam);
    vwe_vo::EventVector off_ground;
    const vwe_vo::EventVector& seen = frontend.offGround(window, &off_ground);
    const vwe_vo::EventVector sub =
        vwe_vo::subsampleEventsPerTimeSlice(seen, t0, t1, cfg.frontend.max_events_per_volume,
                                            cfg.frontend.subsample_time_slices, cfg.frontend.seed);
    const double centre = std::isfinite(omega_true) ? omega_true : 0.0;
    std::ofstream file;
    if (args.count("--out")) {
      file.open(args["--out"]);
      if (!file) throw std::runtime_error("cannot write " + args["--out"]);
    }
    std::ostream& out = args.count("--out") ? file : std::cout;
    out << "# window " << vwe_vo::nsToSec(t0) << " .. " << vwe_vo::nsToSec(t1) << " s, "
        << window.size() << " events (" << window.size() - seen.size() << " masked, " << sub.size()
        << " voted), v " << v << " m/s";
    if (std::isfinite(omega_true))
      out << ", true omega " << (omega_true * vwe_vo::kDegPerRad) << " deg/s";
    out << "\nomega_deg_s,contrast\n";
    double best = -1, best_omega = 0;
    for (double w = centre - range; w <= centre + range + 1e-12; w += step) {
      const double f = frontend.contrast(sub, t_ref, w, v);
      if (f > best) best = f, best_omega = w;
      out << (w * vwe_vo::kDegPerRad) << "," << f << "\n";
    }
    std::fprintf(stderr,
                 "[vwe_vo_objective] %zu events (%zu masked, %zu voted), v %.3f m/s: peak at "
                 "%.2f deg/s",
                 window.size(), window.size() - seen.size(), sub.size(), v,
                 (best_omega * vwe_vo::kDegPerRad));
    if (std::isfinite(omega_true))
      std::fprintf(stderr, ", truth %.2f deg/s (peak - truth %.2f deg/s)",
                   (omega_true * vwe_vo::kDegPerRad),
                   ((best_omega - omega_true) * vwe_vo::kDegPerRad));
    std::fprintf(stderr, "\n");
  } catch (const std::exception& e) {
    std::cerr << "vwe_vo_objective: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
