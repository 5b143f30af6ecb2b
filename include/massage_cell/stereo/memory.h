// The allocator setting of programs that match many pairs. ROS-free.
#pragma once

namespace massage_cell::stereo {

/// Process-wide allocator setting for programs that match many pairs: glibc
/// then serves large blocks (cost volumes, max-flow graphs: 10-80 MB, made
/// and freed for every cut and frame) from its heap and keeps freed memory
/// for reuse instead of unmapping it, so later cuts and frames do not pay
/// the kernel's page faults again (HBDS + polish on Teddy 440 -> 380 ms).
/// The process keeps its peak heap. Called by the stereo tools and the
/// stand-alone hbds node's main, never by a nodelet (it may share its
/// manager's process); a no-op where glibc's mallopt is unavailable.
void retainFreedMemory();

}  // namespace massage_cell::stereo
