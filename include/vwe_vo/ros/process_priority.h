// CPU priority of a node's worker. On a machine with fewer cores than the pipeline needs at
// full rate (2 cores: front-end ~0.9, back-end ~1.25, mapping ~0.4 core-seconds per second of
// indoor data), the scheduler would share the CPU evenly among the nodes and the front-end, whose
// arcs everything else is built on, would fall behind and skip windows. The back-end and the
// mapper can lag instead (they catch up in larger steps): they can run at a lower priority
// (~nice; off by default: with autogroups it also ranks them below every other session).
#pragma once

namespace vwe_vo {

/// Where a node class runs: alone in its process (the node executables) or beside other nodes in
/// one process (a nodelet manager), where it must not change what the whole process shares.
enum class Hosting { kOwnProcess, kSharedProcess };

/// Lowers the priority of the calling thread (and of every thread it creates afterwards) to
/// `nice` (0..19; 0 leaves it alone). With kOwnProcess, where the kernel groups processes per
/// session (autogroup, where a thread's nice only ranks threads of one session), the process's
/// group too; with kSharedProcess only the thread (it then ranks against the other nodes' threads
/// of the same group). Logs what it did, naming `node`; failures are warned about, never thrown.
void lowerCpuPriority(int nice, const char* node, Hosting hosting);

/// Names the calling thread (at most 15 characters are kept) so that per-thread CPU accounting
/// (/proc/PID/task/TID/comm, top -H) tells the nodes of one process apart.
void nameThisThread(const char* name);

}  // namespace vwe_vo
