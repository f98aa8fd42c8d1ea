#include "vwe_vo/io/trajectory_io.h"

#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string_view>

namespace vwe_vo {
namespace {

/// Reads text lines from a plain or gzip-compressed file (zlib reads both) in large blocks; a
/// line is a view into the block buffer, valid until the next call, and NUL-terminated in place.
/// Blocks grow from 64 KiB to 4 MiB; a line longer than that grows the buffer.
class LineReader {
 public:
  static constexpr size_t kBlockBytes = size_t(1) << 22;
  static constexpr size_t kFirstBlockBytes = size_t(1) << 16;  // small files stay cheap

  explicit LineReader(const std::string& path)
      : path_(path), file_(gzopen(path.c_str(), "rb")), buf_(kFirstBlockBytes + 1) {
    if (!file_) throw std::runtime_error("cannot open " + path + ": " + std::strerror(errno));
    gzbuffer(file_, 1 << 18);
  }
  ~LineReader() { gzclose(file_); }
  LineReader(const LineReader&) = delete;
  LineReader& operator=(const LineReader&) = delete;

  /// Next line without its end-of-line; false at the end of the file.
  bool next(std::string_view* line) {
    const char* nl = nullptr;
    while (true) {
      const size_t avail = end_ - pos_;
      nl = avail > 0 ? static_cast<const char*>(std::memchr(buf_.data() + pos_, '\n', avail))
                     : nullptr;
      if (nl || eof_) break;
      refill();
    }
    char* begin = buf_.data() + pos_;
    char* stop;
    if (nl) {
      stop = const_cast<char*>(nl);
      pos_ = (nl - buf_.data()) + 1;
    } else {
      if (pos_ == end_) return false;
      stop = buf_.data() + end_;  // the last line without a final newline
      pos_ = end_;
    }
    while (stop > begin && (stop[-1] == '\n' || stop[-1] == '\r')) --stop;
    *stop = '\0';  // the buffer holds one byte more than a block: always writable
    *line = std::string_view(begin, stop - begin);
    ++line_number_;
    return true;
  }
  int lineNumber() const { return line_number_; }
  [[noreturn]] void fail(const std::string& what) const {
    throw std::runtime_error(path_ + ":" + std::to_string(line_number_) + ": " + what);
  }

 private:
  /// Moves the unfinished line to the front and reads the next block behind it.
  void refill() {
    const size_t tail = end_ - pos_;
    if (pos_ > 0 && tail > 0) std::memmove(buf_.data(), buf_.data() + pos_, tail);
    pos_ = 0;
    end_ = tail;
    if (buf_.size() - 1 - end_ < block_) buf_.resize(end_ + block_ + 1);
    block_ = std::min(2 * block_, kBlockBytes);  // blocks double up to kBlockBytes
    const size_t room = buf_.size() - 1 - end_;
    const int n = gzread(file_, buf_.data() + end_, static_cast<unsigned>(room));
    if (n < 0) {
      int code = 0;
      const char* msg = gzerror(file_, &code);
      throw std::runtime_error("cannot read " + path_ + ": " +
                               (code == Z_ERRNO ? std::strerror(errno) : msg));
    }
    if (n == 0) eof_ = true;
    end_ += static_cast<size_t>(n);
  }

  std::string path_;
  gzFile file_;
  std::vector<char> buf_;
  size_t block_ = kFirstBlockBytes;
  size_t pos_ = 0, end_ = 0;
  bool eof_ = false;
  int line_number_ = 0;
};

bool isSpace(char c) {
  return std::isspace(static_cast<unsigned char>(c)) != 0;
}

bool isBlankOrComment(std::string_view line) {
  for (char c : line) {
    if (c == '#') return true;
    if (!isSpace(c)) return false;
  }
  return true;
}

/// Parses n_min..n_max finite numbers separated by white space; false otherwise. The line must
/// be NUL-terminated right after its end (LineReader does so).
bool parseNumbers(std::string_view line, int n_min, int n_max, std::vector<double>* out) {
  out->clear();
  const char* p = line.data();
  const char* const line_end = p + line.size();
  char* end = nullptr;
  while (true) {
    while (p < line_end && isSpace(*p)) ++p;
    if (p >= line_end) break;
    errno = 0;
    const double v = std::strtod(p, &end);
    if (end == p || errno == ERANGE || !std::isfinite(v)) return false;
    if (end < line_end && !isSpace(*end)) return false;
    if (end > line_end) return false;
    out->push_back(v);
    p = end;
  }
  return static_cast<int>(out->size()) >= n_min && static_cast<int>(out->size()) <= n_max;
}

bool isDigit(char c) {
  return static_cast<unsigned>(c - '0') < 10u;
}

/// The common event line `S[.F] X Y P` (S, F, X, Y decimal digits, P 0 or 1) parsed by hand:
/// the time exactly to nanoseconds (digits beyond the ninth round half up). False on anything
/// else, which the general parser then reads (or reports) as before. The line must be
/// NUL-terminated right after its end: no digit or blank is read past it.
bool parseEventFast(std::string_view line, PixelEvent* e) {
  const char* p = line.data();
  if (!isDigit(*p)) return false;
  int64_t sec = 0;
  const char* const sec_begin = p;
  while (isDigit(*p) && p - sec_begin < 11) sec = sec * 10 + (*p++ - '0');
  if (p - sec_begin > 10 || sec > 9000000000LL) return false;
  int64_t frac = 0;
  if (*p == '.') {
    ++p;
    const char* const frac_begin = p;
    while (isDigit(*p) && p - frac_begin < 9) frac = frac * 10 + (*p++ - '0');
    static constexpr int64_t kScale[10] = {1000000000, 100000000, 10000000, 1000000, 100000,
                                           10000,      1000,      100,      10,      1};
    frac *= kScale[p - frac_begin];
    if (isDigit(*p)) {
      frac += *p >= '5' ? 1 : 0;
      while (isDigit(*p)) ++p;
    }
  }
  if (*p != ' ' && *p != '\t') return false;
  unsigned xy[2];
  for (unsigned& v : xy) {
    while (*p == ' ' || *p == '\t') ++p;
    const char* const begin = p;
    v = 0;
    while (isDigit(*p) && p - begin < 6) v = v * 10 + unsigned(*p++ - '0');
    if (p == begin || v > 65535 || (*p != ' ' && *p != '\t')) return false;
  }
  while (*p == ' ' || *p == '\t') ++p;
  if (*p != '0' && *p != '1') return false;
  const char pol = *p++;
  while (isSpace(*p)) ++p;
  if (p != line.data() + line.size()) return false;
  e->t_ns = sec * kNsPerSec + frac;
  e->x = static_cast<uint16_t>(xy[0]);
  e->y = static_cast<uint16_t>(xy[1]);
  e->polarity = pol == '1' ? 1 : -1;
  return true;
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
  std::string_view line;
  std::vector<double> v;
  while (in.next(&line)) {
    if (isBlankOrComment(line)) continue;
    if (!parseNumbers(line, 8, 8, &v))
      in.fail("expected 8 numbers 't px py pz qx qy qz qw', got '" + std::string(line) + "'");
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
  std::string_view line;
  std::vector<double> v;
};

EcdEventReader::EcdEventReader(const std::string& path, int width, int height)
    : impl_(std::make_unique<Impl>(path, width, height)) {}
EcdEventReader::~EcdEventReader() = default;

size_t EcdEventReader::read(size_t max_events, EventVector* out) {
  out->clear();
  out->reserve(std::min(max_events, size_t(1) << 20));
  Impl& r = *impl_;
  while (out->size() < max_events && r.in.next(&r.line)) {
    const std::string_view line = r.line;
    std::vector<double>& v = r.v;
    PixelEvent e;
    if (parseEventFast(line, &e)) {
      if ((r.width > 0 && e.x >= r.width) || (r.height > 0 && e.y >= r.height))
        r.in.fail("event at (" + std::to_string(e.x) + ", " + std::to_string(e.y) +
                  ") is outside the " + std::to_string(r.width) + "x" + std::to_string(r.height) +
                  " sensor");
      if (e.t_ns < r.last_t_ns)
        r.in.fail("time goes backwards at " + std::to_string(std::strtod(line.data(), nullptr)) +
                  " s");
      r.last_t_ns = e.t_ns;
      out->push_back(e);
      continue;
    }
    if (isBlankOrComment(line)) continue;
    if (!parseNumbers(line, 4, 4, &v))
      r.in.fail("expected 4 numbers 't x y p', got '" + std::string(line) + "'");
    if (v[1] < 0 || v[2] < 0 || v[1] != std::floor(v[1]) || v[2] != std::floor(v[2]) ||
        v[1] > 65535 || v[2] > 65535)
      r.in.fail("pixel coordinates must be non-negative integers, got '" + std::string(line) + "'");
    if ((r.width > 0 && v[1] >= r.width) || (r.height > 0 && v[2] >= r.height))
      r.in.fail("event at (" + std::to_string(int(v[1])) + ", " + std::to_string(int(v[2])) +
                ") is outside the " + std::to_string(r.width) + "x" + std::to_string(r.height) +
                " sensor");
    if (v[3] != 0 && v[3] != 1 && v[3] != -1)
      r.in.fail("polarity must be 0 or 1, got '" + std::string(line) + "'");
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

EcdEventWriter::EcdEventWriter(const std::string& path) : path_(path) {
  const bool gz = path.size() > 3 && path.compare(path.size() - 3, 3, ".gz") == 0;
  if (gz)
    gz_ = gzopen(path.c_str(), "wb");
  else
    file_ = std::fopen(path.c_str(), "w");
  if (!file_ && !gz_)
    throw std::runtime_error("cannot write " + path + ": " + std::strerror(errno));
}

EcdEventWriter::~EcdEventWriter() {
  if (gz_) gzclose(gz_);
  if (file_) std::fclose(file_);
}

void EcdEventWriter::write(const EventVector& events) {
  std::string text;
  text.reserve(std::min<size_t>(events.size(), 1 << 16) * 32);
  const auto flush = [&] {
    const bool ok = gz_ ? gzwrite(gz_, text.data(), static_cast<unsigned>(text.size())) ==
                              static_cast<int>(text.size())
                        : std::fwrite(text.data(), 1, text.size(), file_) == text.size();
    if (!ok) throw std::runtime_error("cannot write " + path_ + ": " + std::strerror(errno));
    text.clear();
  };
  char line[64];
  for (const PixelEvent& e : events) {
    // The time exactly, as seconds with nine decimals.
    const unsigned long long abs_ns =
        e.t_ns < 0 ? 0ULL - static_cast<unsigned long long>(e.t_ns) : e.t_ns;
    const int n = std::snprintf(line, sizeof(line), "%s%llu.%09llu %u %u %d\n",
                                e.t_ns < 0 ? "-" : "", abs_ns / 1000000000ULL,
                                abs_ns % 1000000000ULL, e.x, e.y, e.polarity > 0 ? 1 : 0);
    text.append(line, static_cast<size_t>(n));
    if (text.size() > (size_t(1) << 20)) flush();
  }
  if (!text.empty()) flush();
}

void writeEcdEvents(const std::string& path, const EventVector& events) {
  EcdEventWriter(path).write(events);
}

EcdCalibration readEcdCalibration(const std::string& path) {
  LineReader in(path);
  std::string_view line;
  std::vector<double> v;
  while (in.next(&line)) {
    if (isBlankOrComment(line)) continue;
    if (!parseNumbers(line, 4, 9, &v))
      in.fail("expected 'fx fy cx cy [k1 k2 p1 p2 k3]', got '" + std::string(line) + "'");
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
  std::string_view line;
  std::vector<double> v;
  while (in.next(&line)) {
    if (isBlankOrComment(line)) continue;
    if (!parseNumbers(line, 7, 7, &v))
      in.fail("expected 7 numbers 't ax ay az gx gy gz', got '" + std::string(line) + "'");
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
  std::string_view line;
  std::vector<double> v;
  while (in.next(&line)) {
    if (isBlankOrComment(line)) continue;
    if (!parseNumbers(line, 7, 7, &v))
      in.fail("expected 'px py pz qx qy qz qw', got '" + std::string(line) + "'");
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
