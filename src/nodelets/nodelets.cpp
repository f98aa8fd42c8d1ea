// The vwe_vo nodes as nodelets (vwe_vo/FrontendNodelet, vwe_vo/BackendNodelet,
// vwe_vo/MappingNodelet, vwe_vo/FrameBaselineNodelet; nodelet_plugins.xml): each constructs the
// node class of its standalone executable on the nodelet's handles. In one manager the event
// packets are deserialised once and every stage gets the same EventArray by ConstPtr, and the
// messages between stages (arcs, trajectories, odometry) are handed on by pointer. The nodes'
// callbacks only convert and enqueue (NodeInput is thread-safe, each subscription's callbacks run
// in order): they take the manager's multi-threaded queue; each node runs its own worker thread.
#include <nodelet/nodelet.h>

#include <exception>
#include <memory>
#include <pluginlib/class_list_macros.hpp>

#include "vwe_vo/ros/backend_node.h"
#include "vwe_vo/ros/frame_baseline_node.h"
#include "vwe_vo/ros/frontend_node.h"
#include "vwe_vo/ros/mapping_node.h"

namespace vwe_vo {

namespace {

/// Runs `make` and keeps the node it returns; a node that cannot start (bad parameters or
/// configuration) is logged as fatal and fails the load, which ends the `nodelet load` process.
template <typename Node, typename Make>
void startNode(const char* name, std::unique_ptr<Node>* node, Make&& make) {
  try {
    *node = make();
  } catch (const std::exception& e) {
    ROS_FATAL("%s: %s", name, e.what());
    throw;
  }
}

}  // namespace

class FrontendNodelet : public nodelet::Nodelet {
  void onInit() override {
    startNode("frontend_node", &node_, [this] {
      return std::make_unique<FrontendNode>(getMTNodeHandle(), getMTPrivateNodeHandle());
    });
  }
  std::unique_ptr<FrontendNode> node_;
};

class BackendNodelet : public nodelet::Nodelet {
  void onInit() override {
    startNode("backend_node", &node_, [this] {
      return std::make_unique<BackendNode>(getMTNodeHandle(), getMTPrivateNodeHandle(),
                                           Hosting::kSharedProcess);
    });
  }
  std::unique_ptr<BackendNode> node_;
};

class MappingNodelet : public nodelet::Nodelet {
  void onInit() override {
    startNode("mapping_node", &node_, [this] {
      return std::make_unique<MappingNode>(getMTNodeHandle(), getMTPrivateNodeHandle(),
                                           Hosting::kSharedProcess);
    });
  }
  std::unique_ptr<MappingNode> node_;
};

class FrameBaselineNodelet : public nodelet::Nodelet {
  void onInit() override {
    startNode("frame_baseline_node", &node_, [this] {
      return std::make_unique<FrameBaselineNode>(getMTNodeHandle(), getMTPrivateNodeHandle());
    });
  }
  std::unique_ptr<FrameBaselineNode> node_;
};

}  // namespace vwe_vo

PLUGINLIB_EXPORT_CLASS(vwe_vo::FrontendNodelet, nodelet::Nodelet)
PLUGINLIB_EXPORT_CLASS(vwe_vo::BackendNodelet, nodelet::Nodelet)
PLUGINLIB_EXPORT_CLASS(vwe_vo::MappingNodelet, nodelet::Nodelet)
PLUGINLIB_EXPORT_CLASS(vwe_vo::FrameBaselineNodelet, nodelet::Nodelet)
