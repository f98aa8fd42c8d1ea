// Event containers and input bookkeeping against known answers.
#include <gtest/gtest.h>

#include "vwe_vo/sensor/events.h"

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
