#include "vwe_vo/io/trajectory_io.h"

#include <zlib.h>

#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <sstream>
#include <stdexcept>

namespace vwe_vo {
namespace {

/// Reads text lines from a plain or gzip-compressed file (zlib reads both).
class LineReader {
 public:
  explicit LineReader(const std::string& path) : path_(path), file_(gzopen(path.c_str(), "rb")) {
    if (!file_) throw std::runtime_error("cannot open " + path + ": " + std::strerror(errno));
    gzbuffer(file_, 1 << 20);
  }
  ~LineReader() { gzclose(file_); }
  LineReader(const LineReader&) = delete;
  LineReader& operator=(const LineReader&) = delete;

  /// Next line without its end-of-line; false at the end of the file.
  bool next(std::string* line) {
    line->clear();
    char buf[4096];
    while (gzgets(file_, buf, sizeof(buf))) {
      line->append(buf);
      if (!line->empty() && line->back() == '\n') break;
    }
    if (line->empty()) return false;
    ++line_number_;
    while (!line->empty() && (line->back() == '\n' || line->back() == '\r')) line->pop_back();
    return true;
  }
  int lineNumber() const { return line_number_; }
  [[noreturn]] void fail(const std::string& what) const {
    throw std::runtime_error(path_ + ":" + std::to_string(line_number_) + ": " + what);
  }

 private:
  std::string path_;
  gzFile file_;
  int line_number_ = 0;
};

bool isBlankOrComment(const std::string& line) {
  for (char c : line) {
    if (c == '#') return true;
    if (!std::isspace(static_cast<unsigned char>(c))) return false;
  }
  return true;
}

/// Parses exactly n finite numbers separated by white space; false otherwise.
bool parseNumbers(const std::string& line, int n_min, int n_max, std::vector<double>* out) {
  out->clear();
  const char* p = line.c_str();
  char* end = nullptr;
  while (true) {
    while (*p && std::isspace(static_cast<unsigned char>(*p))) ++p;
    if (!*p) break;
    errno = 0;
    const double v = std::strtod(p, &end);
    if (end == p || errno == ERANGE || !std::isfinite(v)) return false;
    if (*end && !std::isspace(static_cast<unsigned char>(*end))) return false;
    out->push_back(v);
    p = end;
  }
  return static_cast<int>(out->size()) >= n_min && static_cast<int>(out->size()) <= n_max;
}

std::unique_ptr<FILE, int (*)(FILE*)> openForWriting(const std::string& path) {
  FILE* f = std::fopen(path.c_str(), "w");
  if (!f) throw std::runtime_error("cannot write " + path + ": " + std::strerror(errno));
  return {f, &std::fclose};
}

Pose3 poseFromTumNumbers(const double* v) {
  const Quat q(v[6], v[3], v[4], v[5]);  // Eigen: (w, x, y, z)
  return makePose(q, Vec3(v[0], v[1], v[2]));
}

std::string poseToTumNumbers(const Pose3& T) {
  const Quat q(T.linear());
  char buf[256];
  std::snprintf(buf, sizeof(buf), "%.9f %.9f %.9f %.9f %.9f %.9f %.9f", T.translation().x(),
                T.translation().y(), T.translation().z(), q.x(), q.y(), q.z(), q.w());
  return buf;
}

}  // namespace

Trajectory3 readTum(const std::string& path) {
  LineReader in(path);
  Trajectory3 traj;
  std::string line;
  std::vector<double> v;
  while (in.next(&line)) {
    if (isBlankOrComment(line)) continue;
    if (!parseNumbers(line, 8, 8, &v))
      in.fail("expected 8 numbers 't px py pz qx qy qz qw', got '" + line + "'");
    const double qn = std::sqrt(v[4] * v[4] + v[5] * v[5] + v[6] * v[6] + v[7] * v[7]);
    if (std::abs(qn - 1.0) > 1e-3)
      in.fail("quaternion is not unit length (norm " + std::to_string(qn) + ")");
    StampedPose sp;
    sp.t_ns = secToNs(v[0]);
    sp.T = poseFromTumNumbers(v.data() + 1);
    if (!traj.empty() && sp.t_ns <= traj.back().t_ns)
      in.fail("time " + std::to_string(v[0]) + " s is not after the previous pose's");
    traj.push_back(sp);
  }
  if (traj.empty()) throw std::runtime_error(path + ": no poses (empty file or only comments)");
  return traj;
}

void writeTum(const std::string& path, const Trajectory3& trajectory) {
  auto f = openForWriting(path);
  for (const StampedPose& sp : trajectory)
    std::fprintf(f.get(), "%.9f %s\n", nsToSec(sp.t_ns), poseToTumNumbers(sp.T).c_str());
}

struct EcdEventReader::Impl {
  Impl(const std::string& path, int w, int h) : in(path), width(w), height(h) {}
  LineReader in;
  int width, height;
  int64_t last_t_ns = INT64_MIN;
  std::string line;
  std::vector<double> v;
};

EcdEventReader::EcdEventReader(const std::string& path, int width, int height)
    : impl_(std::make_unique<Impl>(path, width, height)) {}
EcdEventReader::~EcdEventReader() = default;

size_t EcdEventReader::read(size_t max_events, EventVector* out) {
  out->clear();
  Impl& r = *impl_;
  while (out->size() < max_events && r.in.next(&r.line)) {
    const std::string& line = r.line;
    std::vector<double>& v = r.v;
    if (isBlankOrComment(line)) continue;
    if (!parseNumbers(line, 4, 4, &v))
      r.in.fail("expected 4 numbers 't x y p', got '" + line + "'");
    if (v[1] < 0 || v[2] < 0 || v[1] != std::floor(v[1]) || v[2] != std::floor(v[2]) ||
        v[1] > 65535 || v[2] > 65535)
      r.in.fail("pixel coordinates must be non-negative integers, got '" + line + "'");
    if ((r.width > 0 && v[1] >= r.width) || (r.height > 0 && v[2] >= r.height))
      r.in.fail("event at (" + std::to_string(int(v[1])) + ", " + std::to_string(int(v[2])) +
                ") is outside the " + std::to_string(r.width) + "x" + std::to_string(r.height) +
                " sensor");
    if (v[3] != 0 && v[3] != 1 && v[3] != -1)
      r.in.fail("polarity must be 0 or 1, got '" + line + "'");
    PixelEvent e;
    e.t_ns = secToNs(v[0]);
    e.x = static_cast<uint16_t>(v[1]);
    e.y = static_cast<uint16_t>(v[2]);
    e.polarity = v[3] > 0 ? 1 : -1;
    if (e.t_ns < r.last_t_ns) r.in.fail("time goes backwards at " + std::to_string(v[0]) + " s");
    r.last_t_ns = e.t_ns;
    out->push_back(e);
  }
  return out->size();
}

EventVector readEcdEvents(const std::string& path, int width, int height) {
  EcdEventReader reader(path, width, height);
  EventVector all, chunk;
  while (reader.read(1 << 20, &chunk) > 0) all.insert(all.end(), chunk.begin(), chunk.end());
  return all;
}

EcdEventWriter::EcdEventWriter(const std::string& path)
    : path_(path), file_(std::fopen(path.c_str(), "w")) {
  if (!file_) throw std::runtime_error("cannot write " + path + ": " + std::strerror(errno));
}

EcdEventWriter::~EcdEventWriter() {
  std::fclose(file_);
}

void EcdEventWriter::write(const EventVector& events) {
  for (const PixelEvent& e : events)
    if (std::fprintf(file_, "%.9f %u %u %d\n", nsToSec(e.t_ns), e.x, e.y, e.polarity > 0 ? 1 : 0) <
        0)
      throw std::runtime_error("cannot write " + path_ + ": " + std::strerror(errno));
}

void writeEcdEvents(const std::string& path, const EventVector& events) {
  EcdEventWriter(path).write(events);
}

EcdCalibration readEcdCalibration(const std::string& path) {
  LineReader in(path);
  std::string line;
  std::vector<double> v;
  while (in.next(&line)) {
    if (isBlankOrComment(line)) continue;
    if (!parseNumbers(line, 4, 9, &v))
      in.fail("expected 'fx fy cx cy [k1 k2 p1 p2 k3]', got '" + line + "'");
    v.resize(9, 0.0);
    EcdCalibration c{v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8]};
    if (c.fx <= 0 || c.fy <= 0) in.fail("focal lengths must be positive");
    return c;
  }
  throw std::runtime_error(path + ": empty calibration file");
}

void writeEcdCalibration(const std::string& path, const EcdCalibration& c) {
  auto f = openForWriting(path);
  std::fprintf(f.get(), "%.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g\n", c.fx, c.fy, c.cx, c.cy,
               c.k1, c.k2, c.p1, c.p2, c.k3);
}

std::vector<ImuSample> readEcdImu(const std::string& path) {
  LineReader in(path);
  std::vector<ImuSample> out;
  std::string line;
  std::vector<double> v;
  while (in.next(&line)) {
    if (isBlankOrComment(line)) continue;
    if (!parseNumbers(line, 7, 7, &v))
      in.fail("expected 7 numbers 't ax ay az gx gy gz', got '" + line + "'");
    // Times are int64 nanoseconds: a stamp beyond +-9.2e9 s cannot be held.
    if (!(std::abs(v[0]) < 9.2e9))
      in.fail("time " + std::to_string(v[0]) + " s is outside the representable range");
    ImuSample s;
    s.t_ns = secToNs(v[0]);
    s.accel = Vec3(v[1], v[2], v[3]);
    s.gyro = Vec3(v[4], v[5], v[6]);
    if (!out.empty() && s.t_ns < out.back().t_ns)
      in.fail("time goes backwards at " + std::to_string(v[0]) + " s");
    out.push_back(s);
  }
  return out;
}

EcdImuWriter::EcdImuWriter(const std::string& path)
    : path_(path), file_(std::fopen(path.c_str(), "w")) {
  if (!file_) throw std::runtime_error("cannot write " + path + ": " + std::strerror(errno));
}

EcdImuWriter::~EcdImuWriter() {
  std::fclose(file_);
}

void EcdImuWriter::write(const ImuSample& s) {
  if (std::fprintf(file_, "%.9f %.9g %.9g %.9g %.9g %.9g %.9g\n", nsToSec(s.t_ns), s.accel.x(),
                   s.accel.y(), s.accel.z(), s.gyro.x(), s.gyro.y(), s.gyro.z()) < 0)
    throw std::runtime_error("cannot write " + path_ + ": " + std::strerror(errno));
}

void writeEcdImu(const std::string& path, const std::vector<ImuSample>& samples) {
  EcdImuWriter w(path);
  for (const ImuSample& s : samples) w.write(s);
}

Pose3 readPoseLine(const std::string& path) {
  LineReader in(path);
  std::string line;
  std::vector<double> v;
  while (in.next(&line)) {
    if (isBlankOrComment(line)) continue;
    if (!parseNumbers(line, 7, 7, &v))
      in.fail("expected 'px py pz qx qy qz qw', got '" + line + "'");
    const double qn = std::sqrt(v[3] * v[3] + v[4] * v[4] + v[5] * v[5] + v[6] * v[6]);
    if (std::abs(qn - 1.0) > 1e-3) in.fail("quaternion is not unit length");
    return poseFromTumNumbers(v.data());
  }
  throw std::runtime_error(path + ": empty pose file");
}

void writePoseLine(const std::string& path, const Pose3& T) {
  auto f = openForWriting(path);
  std::fprintf(f.get(), "%s\n", poseToTumNumbers(T).c_str());
}

}  // namespace vwe_vo
