// NodeInput, the input of every node: the calibration gate, the event-packet checks and
// conversion, the timestamp policy, per-kind bounds (event packets never starve the other kinds),
// the overload policy's time-uniform thinning, the counters and the status line.
#include <gtest/gtest.h>
#include <ros/time.h>

#include "vwe_vo/ros/conversions.h"
#include "vwe_vo/ros/node_input.h"

namespace vwe_vo {
namespace {

struct Item {
  InputKind kind = InputKind::kEvents;
  EventVector events;
  std::string reset_why;
  int id = 0;
};

class NodeInputTest : public testing::Test {
 protected:
  static void SetUpTestSuite() { ros::Time::init(); }  // the throttled warnings read the clock

  static CameraCalibration calibration() {
    CameraCalibration c;
    c.width = 346;
    c.height = 260;
    c.fx = c.fy = 250;
    c.cx = 173;
    c.cy = 130;
    c.distortion = {0, 0, 0, 0, 0};
    return c;
  }
  /// A packet of n events inside a width x height sensor, header.seq = seq, 1 us apart from
  /// t = seq ms on (consecutive seqs: consecutive times).
  static EventArray packet(size_t n, uint32_t seq, uint32_t width = 346, uint32_t height = 260) {
    EventVector ev;
    for (size_t i = 0; i < n; ++i)
      ev.push_back({int64_t(seq) * 1000000 + int64_t(i) * 1000, uint16_t(i % width),
                    uint16_t(i % height), 1});
    EventArray msg = eventsToMsg(ev, 0, ev.size(), int(width), int(height), "davis");
    msg.header.seq = seq;
    return msg;
  }
  static bool pushPacket(NodeInput<Item>& input, const EventArray& msg) {
    return input.pushEventPacket(msg, [](EventVector&& e) {
      Item item;
      item.events = std::move(e);
      return item;
    });
  }
  static NodeInputBase::Push pushOther(NodeInput<Item>& input, InputKind kind, int id) {
    Item item;
    item.kind = kind;
    item.id = id;
    return input.push(kind, std::move(item));
  }
  static std::deque<Item> takeAll(NodeInput<Item>& input) {
    std::deque<Item> batch;
    EXPECT_TRUE(input.takeAll(&batch, std::chrono::milliseconds(0)));
    return batch;
  }
};

TEST_F(NodeInputTest, NothingIsQueuedBeforeAValidCameraInfo) {
  NodeInput<Item> input("test_node");
  EXPECT_FALSE(pushPacket(input, packet(10, 1)));
  EXPECT_EQ(pushOther(input, InputKind::kImu, 1), NodeInputBase::Push::kNoCalibration);
  sensor_msgs::CameraInfo bad = calibrationToMsg(calibration());
  bad.K[0] = 0;
  EXPECT_FALSE(input.acceptCameraInfo(bad));
  EXPECT_FALSE(input.hasCalibration());
  EXPECT_TRUE(takeAll(input).empty());

  EXPECT_TRUE(input.acceptCameraInfo(calibrationToMsg(calibration())));
  EXPECT_TRUE(input.hasCalibration());
  // Another size afterwards is refused, the first kept; the same size again is not a refusal.
  sensor_msgs::CameraInfo other = calibrationToMsg(calibration());
  other.width = 240;
  other.height = 180;
  EXPECT_FALSE(input.acceptCameraInfo(other));
  EXPECT_FALSE(input.acceptCameraInfo(calibrationToMsg(calibration())));
  CameraCalibration used;
  ASSERT_TRUE(input.waitForCalibration(&used));
  EXPECT_EQ(used.width, 346);

  const NodeInputCounters c = input.counters();
  EXPECT_EQ(c[InputKind::kEvents].in, 1u);
  EXPECT_EQ(c[InputKind::kEvents].before_calibration, 1u);
  EXPECT_EQ(c[InputKind::kImu].in, 1u);
  EXPECT_EQ(c[InputKind::kImu].before_calibration, 1u);
  EXPECT_EQ(c.camera_info_refused, 2u);
}

TEST_F(NodeInputTest, EventPacketsAreCheckedConvertedAndCounted) {
  NodeInput<Item> input("test_node");
  input.setCalibration(calibration());
  EXPECT_TRUE(pushPacket(input, packet(5, 1)));
  EXPECT_FALSE(pushPacket(input, packet(0, 2)));            // empty
  EXPECT_FALSE(pushPacket(input, packet(5, 3, 240, 180)));  // another size than the calibration
  EventArray outside = packet(4, 7);                        // seq 4..6 never arrived
  outside.events[1].x = 400;
  outside.events[2].y = 300;
  EXPECT_TRUE(pushPacket(input, outside));

  const std::deque<Item> batch = takeAll(input);
  ASSERT_EQ(batch.size(), 2u);
  ASSERT_EQ(batch[0].events.size(), 5u);
  EXPECT_EQ(batch[0].events[3].x, 3);
  EXPECT_EQ(batch[1].events.size(), 2u);
  const NodeInputCounters c = input.counters();
  EXPECT_EQ(c[InputKind::kEvents].in, 4u);
  EXPECT_EQ(c[InputKind::kEvents].refused, 2u);
  EXPECT_EQ(c.packets_empty, 1u);
  EXPECT_EQ(c.packets_wrong_size, 1u);
  EXPECT_EQ(c.events_outside, 2u);
  EXPECT_EQ(c.packets_lost, 3u);
  EXPECT_EQ(c[InputKind::kEvents].dropped, 0u);
}

TEST_F(NodeInputTest, EventPacketsAreBoundedByEventsAndNeverStarveTheOtherKinds) {
  NodeInput<Item> input("test_node");
  input.setCalibration(calibration());
  input.setBound(InputKind::kEvents, 1000);
  input.setBound(InputKind::kImu, 3);
  input.setBound(InputKind::kTrajectory, 2);
  for (uint32_t k = 0; k < 5; ++k) pushPacket(input, packet(300, k + 1));  // thinned, all kept
  for (int k = 0; k < 5; ++k) pushOther(input, InputKind::kImu, k);        // 3 fit, 2 dropped
  EXPECT_EQ(pushOther(input, InputKind::kTrajectory, 10), NodeInputBase::Push::kQueued);
  EXPECT_EQ(pushOther(input, InputKind::kTrajectory, 11), NodeInputBase::Push::kQueued);
  EXPECT_EQ(pushOther(input, InputKind::kTrajectory, 12), NodeInputBase::Push::kFull);

  NodeInputCounters c = input.counters();
  EXPECT_EQ(c[InputKind::kEvents].in, 5u);
  EXPECT_EQ(c[InputKind::kEvents].dropped, 0u);
  EXPECT_EQ(c[InputKind::kImu].in, 5u);
  EXPECT_EQ(c[InputKind::kImu].dropped, 2u);
  EXPECT_EQ(c[InputKind::kTrajectory].dropped, 1u);
  EXPECT_LE(c.max_queued_events, 1000u);
  std::deque<Item> batch = takeAll(input);
  ASSERT_EQ(batch.size(), 10u);  // 5 packets, 3 IMU, 2 trajectories, in arrival order
  EXPECT_EQ(batch[0].kind, InputKind::kEvents);
  EXPECT_EQ(batch[4].kind, InputKind::kEvents);
  EXPECT_EQ(batch[5].kind, InputKind::kImu);
  EXPECT_EQ(batch[5].id, 0);
  EXPECT_EQ(batch[9].id, 11);

  // Taking the batch frees the bounds. A packet larger than the bound alone still passes.
  EXPECT_TRUE(pushPacket(input, packet(3000, 6)));
  EXPECT_EQ(pushOther(input, InputKind::kImu, 5), NodeInputBase::Push::kQueued);
  batch = takeAll(input);
  ASSERT_EQ(batch.size(), 2u);
  EXPECT_GE(batch[0].events.size(), 3000u / kMaxThinning);
}

TEST_F(NodeInputTest, AFullEventQueueThinsEveryPacketTimeUniformlyAndRecovers) {
  NodeInput<Item> input("test_node");
  input.setCalibration(calibration());
  const size_t bound = 2000, n = 400;  // 5 packets fill the queue
  input.setBound(InputKind::kEvents, bound);
  // 20 packets of 400 events, 1 ms each, while the worker takes nothing: 8000 events > bound.
  for (uint32_t k = 1; k <= 20; ++k) ASSERT_TRUE(pushPacket(input, packet(n, k)));
  NodeInputCounters c = input.counters();
  EXPECT_EQ(c[InputKind::kEvents].dropped, 0u) << "thinning, not dropping, up to 1/kMaxThinning";
  EXPECT_EQ(c.thinning, 4u);  // 8000 events in 2000: 1/4
  EXPECT_EQ(c.thinning_episodes, 2u);
  EXPECT_LE(c.max_queued_events, bound);
  std::deque<Item> batch = takeAll(input);
  ASSERT_EQ(batch.size(), 20u) << "every packet (every slice of data time) is still there";
  size_t kept = 0;
  for (const Item& item : batch) {
    // Each packet keeps between 1/4 and 1/2 of its events, spread over its whole millisecond.
    EXPECT_GE(item.events.size(), n / 4 - 1);
    EXPECT_LE(item.events.size(), n / 2 + 1);
    ASSERT_FALSE(item.events.empty());
    EXPECT_GE(item.events.back().t_ns - item.events.front().t_ns, int64_t(0.9 * n * 1000));
    kept += item.events.size();
  }
  EXPECT_EQ(kept + input.counters().events_thinned, 20 * n);
  EXPECT_LE(kept, bound);
  // The worker caught up (it took more than a quarter of the bound: no recovery yet).
  EXPECT_EQ(input.counters().thinning, 4u);
  ASSERT_TRUE(pushPacket(input, packet(n, 21)));
  batch = takeAll(input);  // 100 events < bound / 4: half as much thinning
  EXPECT_EQ(input.counters().thinning, 2u);
  ASSERT_TRUE(pushPacket(input, packet(n, 22)));
  batch = takeAll(input);
  EXPECT_EQ(batch.at(0).events.size(), n / 2);
  EXPECT_EQ(input.counters().thinning, 1u);
  ASSERT_TRUE(pushPacket(input, packet(n, 23)));
  batch = takeAll(input);
  EXPECT_EQ(batch.at(0).events.size(), n) << "recovered: nothing thinned";
}

TEST_F(NodeInputTest, AQueueFullAtTheCoarsestThinningDropsTheOldestPackets) {
  NodeInput<Item> input("test_node");
  input.setCalibration(calibration());
  const size_t bound = 1000, n = 400;
  input.setBound(InputKind::kEvents, bound);
  for (uint32_t k = 1; k <= 60; ++k) ASSERT_TRUE(pushPacket(input, packet(n, k)));
  const NodeInputCounters c = input.counters();
  EXPECT_EQ(c.thinning, kMaxThinning);
  EXPECT_GT(c[InputKind::kEvents].dropped, 0u);
  EXPECT_LE(c.max_queued_events, bound);  // the memory bound: bound x sizeof(PixelEvent)
  const std::deque<Item> batch = takeAll(input);
  ASSERT_FALSE(batch.empty());
  ASSERT_FALSE(batch.back().events.empty());
  EXPECT_GE(batch.back().events.front().t_ns, secToNs(0.060)) << "the newest packet is kept";
}

TEST_F(NodeInputTest, TimestampJumpsAreAbsorbedAndCountedLargeOnesReset) {
  NodeInput<Item> input("test_node");
  input.setCalibration(calibration());
  TimestampPolicyOptions policy;
  policy.max_backward_jump_s = 0.5;
  input.setTimestampPolicy(policy);
  ASSERT_TRUE(pushPacket(input, packet(100, 1000)));  // t = 1.0 s on
  ASSERT_TRUE(pushPacket(input, packet(100, 1100)));  // 1.1 s on
  // A duplicate of the first packet: 0.1 s back, absorbed (every event older than the newest).
  EXPECT_FALSE(pushPacket(input, packet(100, 1000)));
  ASSERT_TRUE(pushPacket(input, packet(100, 1200)));
  std::deque<Item> batch = takeAll(input);
  ASSERT_EQ(batch.size(), 3u);
  for (const Item& i : batch) EXPECT_TRUE(i.reset_why.empty());
  NodeInputCounters c = input.counters();
  EXPECT_EQ(c.timestamps.backward_jumps, 1u);
  EXPECT_EQ(c.timestamps.events_absorbed, 100u);
  EXPECT_EQ(c.timestamps.resets, 0u);
  // 1.1 s back (> max_backward_jump_s): a reset, said in the item and the counters.
  ASSERT_TRUE(pushPacket(input, packet(100, 100)));
  batch = takeAll(input);
  ASSERT_EQ(batch.size(), 1u);
  EXPECT_NE(batch[0].reset_why.find("jump back"), std::string::npos) << batch[0].reset_why;
  EXPECT_EQ(batch[0].events.size(), 100u);
  c = input.counters();
  EXPECT_EQ(c.timestamps.resets, 1u);
  EXPECT_EQ(c.timestamps.resets_backward, 1u);
  EXPECT_NE(input.statusLine().find("timestamps jumps=1 late=100 largest_jump_ms=100 resets=1 "
                                    "resets_backward=1 resets_gap=0 last_reset=\"events jump back"),
            std::string::npos)
      << input.statusLine();
}

TEST_F(NodeInputTest, DropOldestKeepsTheNewestInArrivalOrder) {
  NodeInput<Item> input("test_node");
  input.setCalibration(calibration());
  input.setBound(InputKind::kFrame, 2, Overflow::kDropOldest);
  input.setBound(InputKind::kTrajectory, 1, Overflow::kReplaceOldest);
  pushOther(input, InputKind::kFrame, 1);
  pushOther(input, InputKind::kOdometry, 100);  // unbounded
  pushOther(input, InputKind::kTrajectory, 50);
  pushOther(input, InputKind::kFrame, 2);
  EXPECT_EQ(pushOther(input, InputKind::kFrame, 3), NodeInputBase::Push::kQueuedDroppedOldest);
  EXPECT_EQ(pushOther(input, InputKind::kTrajectory, 51),
            NodeInputBase::Push::kQueuedDroppedOldest);
  const std::deque<Item> batch = takeAll(input);
  std::vector<int> ids;
  for (const Item& i : batch) ids.push_back(i.id);
  EXPECT_EQ(ids, (std::vector<int>{100, 2, 3, 51}));
  const NodeInputCounters c = input.counters();
  EXPECT_EQ(c[InputKind::kFrame].in, 3u);
  EXPECT_EQ(c[InputKind::kFrame].dropped, 1u);
  // Only the newest trajectory matters: the one it replaced is superseded, not lost.
  EXPECT_EQ(c[InputKind::kTrajectory].dropped, 0u);
  EXPECT_EQ(c[InputKind::kTrajectory].superseded, 1u);
  EXPECT_NE(input.statusLine().find("trajectory in=2 refused=0 before_calibration=0 dropped=0 "
                                    "superseded=1; "),
            std::string::npos)
      << input.statusLine();
}

TEST_F(NodeInputTest, StatusLineHasTheCountersOfEveryKindInUse) {
  NodeInput<Item> input("test_node");
  input.setBound(InputKind::kArc, 10);
  pushPacket(input, packet(3, 1));  // before the calibration
  input.setCalibration(calibration());
  pushPacket(input, packet(0, 2));
  input.countRefused(InputKind::kArc);
  EXPECT_EQ(
      input.statusLine(),
      "events in=2 lost=0 empty=1 wrong_size=0 outside=0 refused=1 before_calibration=1 dropped=0; "
      "arc in=1 refused=1 before_calibration=0 dropped=0; camera_info refused=0; overload "
      "thinned=0 episodes=0 keep=1/1 max_queued=0; timestamps jumps=0 late=0 largest_jump_ms=0 "
      "resets=0 resets_backward=0 resets_gap=0");
}

TEST_F(NodeInputTest, StopEndsTheWaits) {
  NodeInput<Item> input("test_node");
  input.stop();
  CameraCalibration c;
  EXPECT_FALSE(input.waitForCalibration(&c));
  std::deque<Item> batch;
  EXPECT_FALSE(input.takeAll(&batch, std::chrono::milliseconds(10)));
}

}  // namespace
}  // namespace vwe_vo
