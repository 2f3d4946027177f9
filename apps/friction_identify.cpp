// friction-identify: identifies friction models from displacement-force records.
// The commands are in src/cli/; see cli.md for the contract.
#include "cli.hpp"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

int main(int argc, char** argv) {
#if defined(__GLIBC__)
  // The fits allocate and free record-length vectors and N x M matrices thousands of times (the
  // initial-state search of every validation, the trial points of every solver).  At these sizes
  // glibc serves each from a fresh mmap (the threshold starts at 128 kB) or returns the top of the
  // heap to the kernel after a free (trim at 128 kB), and every reuse then page-faults on zeroed
  // pages: `validate` of an NLR model on data/ spent 0.44 s of 0.96 s in the kernel.  Blocks up to
  // glibc's own dynamic ceiling (32 MB, 64-bit) stay in the heap and are reused; larger ones are
  // still mapped and returned.  A process-wide setting, so it belongs to the program, not to the
  // library: a controller linking friction keeps its own allocator's policy.
  mallopt(M_MMAP_THRESHOLD, 32 * 1024 * 1024);
  mallopt(M_TRIM_THRESHOLD, 64 * 1024 * 1024);
#endif
  return friction::cli::run(argc, argv);
}
