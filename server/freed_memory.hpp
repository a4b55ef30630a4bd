// Private to server: handing back what a job or a recomputed window freed.
#pragma once

namespace cutload::server {

// On scope exit, returns the memory the process has freed but glibc still holds to the system.
// glibc keeps freed blocks in the arena of the thread that allocated them, and a run's motion
// model is made of blocks it serves from those arenas once its mmap threshold has risen, so a
// server whose threads each served one job or window kept about that much per thread:
// bench_long's 30-minute run held 1.66 GB after twelve recomputed windows, 292 MB once trimmed
// (docs/api.md, "Memory after a job or a recomputed window"). Declared first in a job or a
// handler, it runs after everything else there is gone.
class ReleaseFreedMemoryOnExit {
public:
    ReleaseFreedMemoryOnExit() = default;
    ReleaseFreedMemoryOnExit(const ReleaseFreedMemoryOnExit&) = delete;
    ReleaseFreedMemoryOnExit& operator=(const ReleaseFreedMemoryOnExit&) = delete;
    ~ReleaseFreedMemoryOnExit();
};

}  // namespace cutload::server
