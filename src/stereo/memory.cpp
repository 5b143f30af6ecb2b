#include "massage_cell/stereo/memory.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace massage_cell::stereo {

void retainFreedMemory() {
#if defined(__GLIBC__)
  mallopt(M_MMAP_THRESHOLD, 512 << 20);  // blocks below 512 MB come from the heap...
  mallopt(M_TRIM_THRESHOLD, 1 << 30);    // ...which is not trimmed below 1 GB of free space
#endif
}

}  // namespace massage_cell::stereo
