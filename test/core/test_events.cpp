// Event containers and input bookkeeping against known answers.
#include <gtest/gtest.h>

#include "vwe_vo/sensor/events.h"
#include "vwe_vo/sensor/subsample.h"

using namespace vwe_vo;

TEST(SequenceGapCounter, CountsSkippedNumbersAndRestartsWhenTheNumbersGoBack) {
  SequenceGapCounter c;
  EXPECT_EQ(c.observe(7), 0u);  // the first number seen: nothing known before it
  EXPECT_EQ(c.observe(8), 0u);
  EXPECT_EQ(c.observe(12), 3u);  // 9, 10, 11 never arrived
  EXPECT_EQ(c.missed(), 3u);
  EXPECT_EQ(c.observe(2), 0u);  // a looped bag or a restarted driver
  EXPECT_EQ(c.restarts(), 1u);
  EXPECT_EQ(c.observe(4), 1u);
  EXPECT_EQ(c.missed(), 4u);
  // Unnumbered messages (seq left at 0 by the publisher) count nothing.
  SequenceGapCounter z;
  for (int i = 0; i < 5; ++i) EXPECT_EQ(z.observe(0), 0u);
  EXPECT_EQ(z.missed(), 0u);
  EXPECT_EQ(z.restarts(), 0u);
  // The largest gap the numbers can express.
  SequenceGapCounter w;
  w.observe(0);
  EXPECT_EQ(w.observe(0xffffffffu), 0xfffffffeu);
}

TEST(EventBuffer, WindowsAndOutOfOrderEvents) {
  EventBuffer b;
  for (int64_t t : {10, 20, 30, 40}) EXPECT_TRUE(b.push(PixelEvent{t, 1, 2, 1}));
  EXPECT_FALSE(b.push(PixelEvent{25, 0, 0, 1}));
  EXPECT_EQ(b.outOfOrderCount(), 1u);
  const EventVector w = b.window(20, 40);
  ASSERT_EQ(w.size(), 2u);
  EXPECT_EQ(w[0].t_ns, 20);
  EXPECT_EQ(w[1].t_ns, 30);
  EXPECT_EQ(b.windowByCount(15, 3).size(), 3u);
  EXPECT_EQ(b.lowerBound(31), 3u);
  b.dropBefore(30);
  EXPECT_EQ(b.size(), 2u);
  EXPECT_EQ(b.oldestTime(), 30);
}

// The back-end subsamples its volumes straight out of the buffer: the same events, seed for seed,
// as copying the window out and subsampling the copy.
TEST(Subsample, RangeOfABufferKeepsTheEventsOfTheCopiedWindow) {
  EventBuffer buffer;
  for (int i = 0; i < 5000; ++i)
    buffer.push(PixelEvent{int64_t(i) * 1000, uint16_t(i % 346), uint16_t(i % 260),
                           int8_t(i % 2 ? 1 : -1)});
  const int64_t t0 = 1'234'500, t1 = 4'321'000;
  const size_t i0 = buffer.lowerBound(t0), i1 = buffer.lowerBound(t1);
  const EventVector window = buffer.window(t0, t1);
  ASSERT_EQ(window.size(), i1 - i0);
  for (size_t max_events : {size_t(0), size_t(100), size_t(777), window.size(), size_t(10000)}) {
    for (uint64_t seed : {0u, 3u, 41u}) {
      const EventVector a = subsampleEvents(window, max_events, seed);
      const EventVector b = subsampleRange(buffer, i0, i1, max_events, seed);
      ASSERT_EQ(a.size(), b.size()) << max_events << " " << seed;
      EXPECT_EQ(a.size(), max_events == 0 ? window.size() : std::min(max_events, window.size()));
      for (size_t k = 0; k < a.size(); ++k) ASSERT_EQ(a[k].t_ns, b[k].t_ns) << k;
      // Kept events stay in the window, in time order.
      EXPECT_GE(b.front().t_ns, t0);
      EXPECT_LT(b.back().t_ns, t1);
    }
  }
  EXPECT_TRUE(subsampleRange(buffer, 10, 10, 100, 1).empty());
}
