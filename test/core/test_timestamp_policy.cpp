// The input's timestamp policy on synthetic packet streams whose glitches are known exactly:
// packets of 1 ms with 10 events 0.1 ms apart, as a DAVIS driver sends them.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include "vwe_vo/common/math.h"
#include "vwe_vo/sensor/timestamp_policy.h"

namespace vwe_vo {
namespace {

constexpr int64_t kMs = 1000000;
constexpr size_t kPerPacket = 10;

/// Packet k: events at k ms + j * 0.1 ms (j = 0..9), shifted by shift_ns.
EventVector packet(int64_t k, int64_t shift_ns = 0) {
  EventVector p;
  for (size_t j = 0; j < kPerPacket; ++j) {
    PixelEvent e;
    e.t_ns = k * kMs + int64_t(j) * kMs / 10 + shift_ns;
    e.x = uint16_t(j);
    e.y = uint16_t(k % 100);
    p.push_back(e);
  }
  return p;
}

/// Feeds packets through the policy, checks the output is ordered, returns the actions.
struct Stream {
  TimestampPolicy policy;
  std::vector<TimestampAction> actions;
  size_t passed_events = 0;
  int64_t newest = -1;
  bool ordered = true;
  explicit Stream(const TimestampPolicyOptions& o = {}) : policy(o) {}
  TimestampAction feed(const EventVector& in) {
    EventVector out;
    const TimestampAction a = policy.process(in, &out);
    if (a == TimestampAction::kReset) newest = -1;
    for (const PixelEvent& e : out) {
      if (newest >= 0 && e.t_ns < newest) ordered = false;
      newest = e.t_ns;
    }
    passed_events += out.size();
    actions.push_back(a);
    return a;
  }
  size_t count(TimestampAction a) const {
    return size_t(std::count(actions.begin(), actions.end(), a));
  }
};

TEST(TimestampPolicy, CleanStreamPassesUntouched) {
  Stream r;
  for (int64_t k = 0; k < 2000; ++k) EXPECT_EQ(r.feed(packet(k)), TimestampAction::kPass);
  EXPECT_EQ(r.passed_events, 2000 * kPerPacket);
  EXPECT_EQ(r.policy.stats().backward_jumps, 0u);
  EXPECT_EQ(r.policy.stats().resets, 0u);
  EXPECT_TRUE(r.policy.lastEvent().empty());
  EXPECT_TRUE(r.policy.takeWarning().empty());
}

// The measured driver glitch: one packet every 0.5 s stamped 99 ms in the past, over 11 s.
TEST(TimestampPolicy, DriverGlitchEveryHalfSecondIsAbsorbedWithExactCounts) {
  Stream r;
  size_t warnings = 0, warned_jumps = 0;
  for (int64_t k = 0; k < 11000; ++k) {
    const bool glitch = k > 0 && k % 500 == 0;
    const TimestampAction a = r.feed(packet(k, glitch ? -99 * kMs : 0));
    EXPECT_EQ(a, glitch ? TimestampAction::kAbsorb : TimestampAction::kPass) << "packet " << k;
    const std::string w = r.policy.takeWarning();
    if (!w.empty()) ++warnings, warned_jumps += size_t(std::atoi(w.c_str()));
  }
  const TimestampPolicyStats& s = r.policy.stats();
  EXPECT_EQ(s.packets, 11000u);
  EXPECT_EQ(s.backward_jumps, 21u);  // k = 500, 1000, ..., 10500
  // Every event of a glitched packet is older than the newest one before it: all dropped.
  EXPECT_EQ(s.events_absorbed, 21 * kPerPacket);
  EXPECT_EQ(s.resets, 0u);
  EXPECT_EQ(r.passed_events, (11000 - 21) * kPerPacket);
  EXPECT_TRUE(r.ordered);
  // Newest before packet k is (k - 1) ms + 0.9 ms, the glitched packet's oldest k ms - 99 ms.
  EXPECT_NEAR(s.largest_backward_jump_s, 0.0989, 1e-12);
  EXPECT_NE(r.policy.lastEvent().find("dropped"), std::string::npos);
  // Throttled to one line per second of data (11 s), and together they name every jump.
  warned_jumps += size_t(std::atoi(r.policy.takeSummary().c_str()));
  EXPECT_LE(warnings, 11u);
  EXPECT_GE(warnings, 9u);
  EXPECT_EQ(warned_jumps, 21u);
}

// A looped bag or a restarted driver: from 5 s on every stamp is 2 s earlier.
TEST(TimestampPolicy, TwoSecondJumpBackResetsOnceAndSaysSo) {
  Stream r;
  for (int64_t k = 0; k < 10000; ++k) r.feed(packet(k, k >= 5000 ? -2000 * kMs : 0));
  const TimestampPolicyStats& s = r.policy.stats();
  EXPECT_EQ(s.resets, 1u);
  EXPECT_EQ(s.resets_backward, 1u);
  EXPECT_EQ(s.resets_gap, 0u);
  EXPECT_EQ(s.backward_jumps, 0u);
  EXPECT_EQ(s.events_dropped_at_reset, 0u);
  EXPECT_EQ(r.actions[5000], TimestampAction::kReset);
  EXPECT_EQ(r.count(TimestampAction::kReset), 1u);
  EXPECT_EQ(r.passed_events, 10000 * kPerPacket);  // nothing lost: after the reset all is in order
  EXPECT_TRUE(r.ordered);
  EXPECT_NE(r.policy.lastEvent().find("jump back 2.000 s"), std::string::npos)
      << r.policy.lastEvent();
  const std::string w = r.policy.takeWarning();
  EXPECT_NE(w.find("reset"), std::string::npos) << w;
  EXPECT_TRUE(r.policy.takeWarning().empty());  // said once
}

TEST(TimestampPolicy, JumpJustInsideTheLimitIsAbsorbedJustBeyondResets) {
  TimestampPolicyOptions o;
  o.max_backward_jump_s = 0.5;
  Stream in(o), out(o);
  for (int64_t k = 0; k < 1000; ++k) in.feed(packet(k)), out.feed(packet(k));
  // Newest is 999.9 ms; the first event 0.5 s back is absorbed, 0.5001 s back resets.
  in.feed(packet(0, 499 * kMs + 9 * kMs / 10));
  out.feed(packet(0, 499 * kMs + 9 * kMs / 10 - kMs / 10));
  EXPECT_EQ(in.actions.back(), TimestampAction::kAbsorb);
  EXPECT_EQ(in.policy.stats().resets, 0u);
  EXPECT_EQ(out.actions.back(), TimestampAction::kReset);
  EXPECT_EQ(out.policy.stats().resets, 1u);
}

TEST(TimestampPolicy, JumpInsideAPacketResetsThereAndDropsWhatCameBefore) {
  Stream r;
  for (int64_t k = 3000; k < 4000; ++k) r.feed(packet(k));
  EventVector p = packet(4000);
  EventVector restart = packet(0);
  p.insert(p.end(), restart.begin(), restart.end());  // 10 events at 4 s, then 10 at 0 s
  EXPECT_EQ(r.feed(p), TimestampAction::kReset);
  EXPECT_EQ(r.policy.stats().events_dropped_at_reset, kPerPacket);
  EXPECT_EQ(r.policy.newestNs(), restart.back().t_ns);
  EXPECT_EQ(r.feed(packet(1)), TimestampAction::kPass);
  EXPECT_TRUE(r.ordered);
}

TEST(TimestampPolicy, ForwardGapLongerThanMaxGapResetsShorterPasses) {
  Stream r;
  for (int64_t k = 0; k < 100; ++k) r.feed(packet(k));
  EXPECT_EQ(r.feed(packet(100 + 1500)), TimestampAction::kPass);    // 1.5 s of silence
  EXPECT_EQ(r.feed(packet(1601 + 3000)), TimestampAction::kReset);  // 3 s of silence
  const TimestampPolicyStats& s = r.policy.stats();
  EXPECT_EQ(s.resets, 1u);
  EXPECT_EQ(s.resets_gap, 1u);
  EXPECT_NEAR(s.largest_gap_s, 3.0001, 1e-9);
  EXPECT_NE(r.policy.takeWarning().find("max_gap_s"), std::string::npos);
  // max_gap_s = 0: never.
  TimestampPolicyOptions o;
  o.max_gap_s = 0;
  Stream never(o);
  never.feed(packet(0));
  EXPECT_EQ(never.feed(packet(100000)), TimestampAction::kPass);
}

TEST(TimestampPolicy, DuplicatedPacketsLeaveOnlyTheEventsAtTheNewestTime) {
  Stream r;
  for (int64_t k = 0; k < 1000; ++k) {
    r.feed(packet(k));
    if (k % 100 == 99) r.feed(packet(k));  // sent twice
  }
  const TimestampPolicyStats& s = r.policy.stats();
  // 10 duplicates; of each, the event stamped at the newest time passes, 9 are dropped.
  EXPECT_EQ(s.backward_jumps, 10u);
  EXPECT_EQ(s.events_absorbed, 10 * (kPerPacket - 1));
  EXPECT_EQ(r.passed_events, 1000 * kPerPacket + 10);
  EXPECT_EQ(s.resets, 0u);
  EXPECT_NEAR(s.largest_backward_jump_s, 0.0009, 1e-12);
  EXPECT_TRUE(r.ordered);
}

TEST(TimestampPolicy, ReorderedPacketsDropTheLateOne) {
  Stream r;
  for (int64_t k = 0; k < 1000; k += 2) {
    if (k % 100 == 50) {
      r.feed(packet(k + 1)), r.feed(packet(k));  // swapped
    } else {
      r.feed(packet(k)), r.feed(packet(k + 1));
    }
  }
  const TimestampPolicyStats& s = r.policy.stats();
  EXPECT_EQ(s.backward_jumps, 10u);
  EXPECT_EQ(s.events_absorbed, 10 * kPerPacket);
  EXPECT_EQ(s.resets, 0u);
  EXPECT_TRUE(r.ordered);
}

TEST(TimestampPolicy, UnorderedEventsInsideAPacketAreDroppedToKeepOrder) {
  Stream r;
  EventVector p = packet(0);
  std::swap(p[3], p[4]);  // event 4 before event 3: event 3 is now late by 0.1 ms
  EXPECT_EQ(r.feed(p), TimestampAction::kAbsorb);
  EXPECT_EQ(r.policy.stats().events_absorbed, 1u);
  EXPECT_EQ(r.passed_events, kPerPacket - 1);
}

TEST(TimestampPolicy, EmptyPacketsAndRestart) {
  Stream r;
  EXPECT_EQ(r.feed({}), TimestampAction::kPass);
  r.feed(packet(5000));
  r.policy.restart();
  EXPECT_EQ(r.policy.newestNs(), -1);
  EXPECT_EQ(r.feed(packet(0)), TimestampAction::kPass);  // no reference: nothing is a jump
  EXPECT_EQ(r.policy.stats().resets, 0u);
}

TEST(TimestampPolicy, OptionsRefusedNamingTheField) {
  const auto message = [](const TimestampPolicyOptions& o) {
    try {
      o.validate();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  TimestampPolicyOptions o;
  EXPECT_EQ(message(o), "");
  o.max_backward_jump_s = -1;
  EXPECT_NE(message(o).find("max_backward_jump_s"), std::string::npos);
  o = {};
  o.max_gap_s = 0.1;  // below the backward limit
  EXPECT_NE(message(o).find("max_gap_s"), std::string::npos);
  o = {};
  o.warn_interval_s = std::nan("");
  EXPECT_NE(message(o).find("warn_interval_s"), std::string::npos);
  o = {};
  o.max_backward_jump_s = -0.5;
  EXPECT_THROW(TimestampPolicy{o}, std::invalid_argument);
}

}  // namespace
}  // namespace vwe_vo
