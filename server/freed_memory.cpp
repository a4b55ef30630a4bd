#include "freed_memory.hpp"

#include <cstdlib>   // any C library header defines __GLIBC__ under glibc

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace cutload::server {

ReleaseFreedMemoryOnExit::~ReleaseFreedMemoryOnExit() {
#if defined(__GLIBC__)
    malloc_trim(0);
#endif
}

}  // namespace cutload::server
