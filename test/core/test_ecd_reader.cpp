// The block-buffered text reader behind the ECD and TUM readers: lines across block boundaries,
// line ends, gzip, exact times and the line numbers of errors far into a file.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <stdexcept>
#include <string>

#include "../common/expect_error.h"
#include "vwe_vo/io/trajectory_io.h"

using namespace vwe_vo;

namespace {

std::string tempPath(const std::string& name) {
  return ::testing::TempDir() + "vwe_vo_test_ecd_reader_" + name;
}

std::string writeText(const std::string& name, const std::string& text) {
  const std::string path = tempPath(name);
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

using test::errorOf;
using test::expectContains;

// Enough events for a file several times the reader's 4 MiB block (~23 bytes a line).
EventVector manyEvents(size_t n) {
  EventVector events(n);
  std::mt19937 rng(7);
  int64_t t = 1403636580LL * kNsPerSec;  // a Unix-epoch stamp as in the Event Camera Dataset
  for (size_t i = 0; i < n; ++i) {
    t += rng() % 2000;
    events[i].t_ns = t;
    events[i].x = static_cast<uint16_t>(rng() % 346);
    events[i].y = static_cast<uint16_t>(rng() % 260);
    events[i].polarity = rng() % 2 ? 1 : -1;
  }
  return events;
}

void expectSameEvents(const EventVector& a, const EventVector& b) {
  ASSERT_EQ(a.size(), b.size());
  size_t bad = 0;
  for (size_t i = 0; i < a.size(); ++i)
    bad += a[i].t_ns != b[i].t_ns || a[i].x != b[i].x || a[i].y != b[i].y ||
           a[i].polarity != b[i].polarity;
  EXPECT_EQ(bad, 0u);
}

}  // namespace

TEST(EcdReader, RoundTripAcrossBlocksPlainAndGzip) {
  const EventVector events = manyEvents(600000);  // ~14 MB of text: lines straddle 3 blocks
  const std::string plain = tempPath("many_events.txt");
  const std::string gz = tempPath("many_events.txt.gz");
  writeEcdEvents(plain, events);
  writeEcdEvents(gz, events);
  std::ifstream plain_in(plain, std::ios::binary | std::ios::ate);
  std::ifstream gz_in(gz, std::ios::binary | std::ios::ate);
  EXPECT_GT(static_cast<long>(plain_in.tellg()), 3L << 22);
  EXPECT_LT(static_cast<long>(gz_in.tellg()), static_cast<long>(plain_in.tellg()) / 2);
  expectSameEvents(readEcdEvents(plain, 346, 260), events);
  expectSameEvents(readEcdEvents(gz, 346, 260), events);

  // Streamed in odd chunks, the same events.
  EcdEventReader reader(gz, 346, 260);
  EventVector all, chunk;
  while (reader.read(77777, &chunk) > 0) all.insert(all.end(), chunk.begin(), chunk.end());
  expectSameEvents(all, events);
}

TEST(EcdReader, TimesAreExactNanosecondsAndMatchTheDoubleRounding) {
  // Up to nine decimals the time equals llround(t * 1e9) of the double for stamps of a
  // recording's length (what the reader gave when it parsed times as doubles).
  std::mt19937 rng(3);
  std::string text;
  std::vector<double> t_s;
  for (int i = 0; i < 20000; ++i) {
    const int digits = 1 + i % 9;
    const long long sec = i;  // one line a second: in time order
    long long frac = rng() % 1000000000LL;
    for (int d = digits; d < 9; ++d) frac /= 10;
    char buf[64];
    std::snprintf(buf, sizeof(buf), "%lld.%0*lld", sec, digits, frac);
    text += std::string(buf) + " 1 2 1\n";
    t_s.push_back(std::strtod(buf, nullptr));
  }
  // Nanoseconds needing more than a double near the epoch stamps, and rounding beyond 9 digits.
  text += "30000.1234567894 1 2 0\n30000.1234567895 1 2 0\n1403636580.123456789 1 2 0\n";
  const EventVector e = readEcdEvents(writeText("times.txt", text));
  ASSERT_EQ(e.size(), t_s.size() + 3);
  size_t bad = 0;
  for (size_t i = 0; i < t_s.size(); ++i) bad += e[i].t_ns != std::llround(t_s[i] * 1e9);
  EXPECT_EQ(bad, 0u);
  EXPECT_EQ(e[t_s.size()].t_ns, 30000123456789LL);
  EXPECT_EQ(e[t_s.size() + 1].t_ns, 30000123456790LL);
  EXPECT_EQ(e[t_s.size() + 2].t_ns, 1403636580123456789LL);
}

TEST(EcdReader, LineEndsAndTheLessCommonSpellings) {
  // CRLF, no final newline, tabs, leading blanks, exponents, 13.0 pixels and -1 polarity.
  const std::string text =
      "# t x y p\r\n0.001 10 20 1\r\n\r\n  0.002\t11 21 0\r\n2.5e-3 12 22 -1\n"
      "0.004 13.0 23 1.0\n0.005 14 24 0";
  const EventVector e = readEcdEvents(writeText("spellings_ok.txt", text), 346, 260);
  ASSERT_EQ(e.size(), 5u);
  EXPECT_EQ(e[0].t_ns, 1000000);
  EXPECT_EQ(e[1].t_ns, 2000000);
  EXPECT_EQ(e[1].polarity, -1);
  EXPECT_EQ(e[2].t_ns, 2500000);
  EXPECT_EQ(e[2].polarity, -1);
  EXPECT_EQ(e[3].x, 13);
  EXPECT_EQ(e[3].polarity, 1);
  EXPECT_EQ(e[4].t_ns, 5000000);  // the last line had no newline
  EXPECT_EQ(e[4].y, 24);
}

TEST(EcdReader, ErrorsNameTheRightLineAfterBlockBoundaries) {
  const EventVector events = manyEvents(400000);  // ~9 MB: two block boundaries
  const std::string good = tempPath("good_prefix.txt");
  writeEcdEvents(good, events);
  std::ifstream in(good, std::ios::binary);
  const std::string prefix((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string line = std::to_string(events.size() + 1);

  const std::string polarity = writeText("late_polarity.txt", prefix + "1403636999.0 1 2 2\n");
  const std::string m1 = errorOf([&] { readEcdEvents(polarity, 346, 260); });
  expectContains(m1, polarity + ":" + line + ": polarity must be 0 or 1");

  const std::string back = writeText("late_back.txt", prefix + "\r\n# c\r\n1.0 1 2 1\r\n");
  const std::string m2 = errorOf([&] { readEcdEvents(back, 346, 260); });
  expectContains(m2, back + ":" + std::to_string(events.size() + 3) + ": time goes backwards");

  const std::string outside = writeText("late_outside.txt", prefix + "1403636999.0 346 2 1");
  const std::string m3 = errorOf([&] { readEcdEvents(outside, 346, 260); });
  expectContains(m3, outside + ":" + line + ": event at (346, 2) is outside the 346x260 sensor");

  const std::string malformed = writeText("late_malformed.txt", prefix + "1403636999.0 1 2\n");
  expectContains(errorOf([&] { readEcdEvents(malformed, 346, 260); }),
                 malformed + ":" + line + ": expected 4 numbers 't x y p', got '1403636999.0 1 2'");

  const std::string nul = writeText("nul.txt", std::string("0.001 1 2 1\n0.002 1 2 1\0x\n", 26));
  expectContains(errorOf([&] { readEcdEvents(nul); }), nul + ":2: expected 4 numbers");
}

TEST(EcdReader, LineLongerThanABlock) {
  const std::string text = "# " + std::string(9 << 20, 'c') + "\n0.001 1 2 1\n";
  const std::string path = writeText("long_line.txt", text);
  const EventVector e = readEcdEvents(path);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(e[0].t_ns, 1000000);
  const std::string bad = writeText("long_bad.txt", text + "0.0 1 2 1\n");
  expectContains(errorOf([&] { readEcdEvents(bad); }), bad + ":3: time goes backwards");
}

TEST(EcdReader, TumAcrossBlocksWithCrlf) {
  std::string text = "# t px py pz qx qy qz qw\r\n";
  const int n = 100000;  // ~5 MB
  for (int i = 0; i < n; ++i) {
    char buf[128];
    std::snprintf(buf, sizeof(buf), "%.9f %.6f 0.5 0.25 0 0 0 1\r\n", 0.01 * i, 0.001 * i);
    text += buf;
  }
  const std::string path = writeText("long.tum", text);
  const Trajectory3 traj = readTum(path);
  ASSERT_EQ(traj.size(), size_t(n));
  EXPECT_EQ(traj.back().t_ns, 10 * int64_t(n - 1) * 1000000);
  EXPECT_NEAR(traj.back().T.translation().x(), 0.001 * (n - 1), 1e-9);
  const std::string bad = writeText("long_bad.tum", text + "1.0 0 0 0 0 0 0 1\r\n");
  expectContains(errorOf([&] { readTum(bad); }), bad + ":" + std::to_string(n + 2) + ": time");
}
