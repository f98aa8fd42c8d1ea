#include "vwe_vo/ros/process_priority.h"

#include <pthread.h>
#include <ros/console.h>
#include <sys/resource.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <string>

namespace vwe_vo {

void lowerCpuPriority(int nice, const char* node, Hosting hosting) {
  if (nice <= 0) return;
  // Linux: PRIO_PROCESS with who = 0 sets the calling thread's nice; new threads inherit it.
  if (setpriority(PRIO_PROCESS, 0, nice) != 0) {
    ROS_WARN("%s: cannot lower the CPU priority to nice %d: %s", node, nice, std::strerror(errno));
    return;
  }
  // With autogroups (one per session; roslaunch starts every node in its own), the CPU is first
  // shared among the groups: the group's nice is what ranks this node against the others.
  // In a shared process (a nodelet manager) the group is every node's: only the thread is lowered.
  bool group = false;
  std::ifstream enabled("/proc/sys/kernel/sched_autogroup_enabled");
  int on = 0;
  if (hosting == Hosting::kOwnProcess && enabled >> on && on == 1) {
    std::ofstream autogroup("/proc/self/autogroup");
    group = bool(autogroup << nice << std::flush);
    if (!group) ROS_WARN("%s: cannot set the nice of its scheduler autogroup to %d", node, nice);
  }
  ROS_INFO(
      "%s: its worker runs at nice %d%s (~nice): the front-end goes first when the CPU is short",
      node, nice, group ? ", and its autogroup" : "");
}

void nameThisThread(const char* name) {
  pthread_setname_np(pthread_self(), std::string(name).substr(0, 15).c_str());
}

}  // namespace vwe_vo
