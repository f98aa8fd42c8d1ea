// vwe_vo_eval: accuracy of an estimated TUM trajectory against ground truth
// (docs/evaluation.md); prints a table, optionally writes JSON and a per-pair CSV for plots.
#include <cmath>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <string>

#include "vwe_vo/eval/evaluation.h"
#include "vwe_vo/io/trajectory_io.h"

namespace {

const char* kUsage =
    "usage: vwe_vo_eval --gt GT.tum --est EST.tum [--delta 1.0] [--json OUT.json] [--series "
    "OUT.csv]\n"
    "                   [--segment 10] [--arcs ARCS.csv]\n"
    "  --gt FILE       ground-truth TUM trajectory (t px py pz qx qy qz qw)\n"
    "  --est FILE      estimated TUM trajectory\n"
    "  --delta S       relative pose error interval in seconds (default 1.0; 0.5 s is also "
    "reported)\n"
    "  --json FILE     write the metrics as JSON\n"
    "  --series FILE   write the per-pair errors as CSV (for scripts/plot_trajectory.py)\n"
    "  --segment M     ground-truth distance per scale-drift segment in metres (default 10)\n"
    "  --arcs FILE     also score the front-end's arcs.csv: yaw rate per window vs ground truth\n"
    "  --help          this text\n";

double parsePositive(const std::string& option, const std::string& text) {
  size_t used = 0;
  double v = 0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != text.size() || !(v > 0) || !std::isfinite(v))
    throw std::invalid_argument(option + " expects a positive number, got '" + text + "'");
  return v;
}

}  // namespace

int main(int argc, char** argv) {
  std::string gt_path, est_path, json_path, series_path, arcs_path;
  vwe_vo::EvaluationOptions options;
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string arg = argv[i];
      if (arg == "--help" || arg == "-h") {
        std::cout << kUsage;
        return 0;
      }
      if (arg != "--gt" && arg != "--est" && arg != "--delta" && arg != "--json" &&
          arg != "--series" && arg != "--segment" && arg != "--arcs")
        throw std::invalid_argument("unknown option '" + arg + "'");
      if (i + 1 >= argc) throw std::invalid_argument(arg + " needs a value");
      const std::string value = argv[++i];
      if (arg == "--gt")
        gt_path = value;
      else if (arg == "--est")
        est_path = value;
      else if (arg == "--json")
        json_path = value;
      else if (arg == "--series")
        series_path = value;
      else if (arg == "--arcs")
        arcs_path = value;
      else if (arg == "--delta")
        options.delta_s = parsePositive(arg, value);
      else
        options.segment_m = parsePositive(arg, value);
    }
    if (gt_path.empty()) throw std::invalid_argument("--gt is required");
    if (est_path.empty()) throw std::invalid_argument("--est is required");
    options.validate();
  } catch (const std::exception& e) {
    std::cerr << "vwe_vo_eval: " << e.what() << "\n" << kUsage;
    return 2;
  }

  try {
    const vwe_vo::Trajectory3 gt = vwe_vo::readTum(gt_path);
    const vwe_vo::Trajectory3 est = vwe_vo::readTum(est_path);
    const vwe_vo::EvaluationResult result = vwe_vo::evaluate(gt, est, options);
    std::cout << "vwe_vo_eval: " << est_path << " against " << gt_path << "\n"
              << vwe_vo::formatTable(result);
    nlohmann::json j = vwe_vo::toJson(result);
    if (!arcs_path.empty()) {
      const vwe_vo::WindowYawRateResult w =
          vwe_vo::evaluateWindowYawRates(gt, vwe_vo::readArcsCsv(arcs_path));
      std::printf(
          "  window yaw rate (arcs)        RMSE %.3f deg/s, median |err| %.3f, max %.3f (%zu "
          "windows, %zu standstill)\n",
          w.rmse_deg_s, w.median_abs_deg_s, w.max_abs_deg_s, w.windows, w.standstill_windows);
      j["window_yaw_rate"] = vwe_vo::toJson(w);
    }
    if (!json_path.empty()) {
      std::ofstream out(json_path);
      out << j.dump(2) << "\n";
      if (!out) throw std::runtime_error("cannot write " + json_path);
    }
    if (!series_path.empty()) vwe_vo::writeSeriesCsv(series_path, result);
  } catch (const std::exception& e) {
    std::cerr << "vwe_vo_eval: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
