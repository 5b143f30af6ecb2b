#include "massage_cell/stereo/memory.h"
#include "node_main.h"

int main(int argc, char** argv) {
  // The stand-alone node owns its process, so it may tune the allocator: every pair allocates and frees its cost
  // volume and graphs, and freed memory kept in the heap saves their page faults. The nodelet alone does not touch
  // a process-wide setting (it may share a nodelet manager with others).
  massage_cell::stereo::retainFreedMemory();
  return massage_cell::nodes::runNodelet(argc, argv, "hbds", "massage_cell/hbds");
}
