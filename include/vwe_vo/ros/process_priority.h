// CPU priority of a node's process. On a machine with fewer cores than the pipeline needs at
// full rate (2 cores: front-end ~0.9, back-end ~1.25, mapping ~0.4 core-seconds per second of
// indoor data), the scheduler would share the CPU evenly among the nodes and the front-end, whose
// arcs everything else is built on, would fall behind and skip windows. The back-end and the
// mapper can lag instead (they catch up in larger steps): they can run at a lower priority
// (~nice; off by default: with autogroups it also ranks them below every other session).
#pragma once

namespace vwe_vo {

/// Lowers the priority of the calling thread (and of every thread it creates afterwards) to
/// `nice` (0..19; 0 leaves it alone) and, where the kernel groups processes per session
/// (autogroup, where a thread's nice only ranks threads of one session), of the process's group.
/// Logs what it did, naming `node`; failures are warned about, never thrown.
void lowerCpuPriority(int nice, const char* node);

}  // namespace vwe_vo
