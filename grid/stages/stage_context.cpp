// What every stage shares (stages/stages.h StageContext): the job's progress and cancellation
// checked as a stage goes, and the heap's free pages given back between stages.
#include "stages/stages.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace facetree {

void checkJobProgress(const ClusterJob& job, const char* phase, uint64_t done, uint64_t total) {
  if ((job.progress && !job.progress(JobProgress{phase, done, total})) ||
      (job.build.cancelled && job.build.cancelled()))
    throw cancelledError();
}

void releaseFreeMemory() {
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

}  // namespace facetree
