// friction-identify: identifies friction models from displacement-force records.
// The commands are in src/cli/; see cli.md for the contract.
#include <Eigen/Core>

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
  // Eigen sizes the blocks of its matrix products from the caches it finds on the CPU at run time,
  // and the blocks decide the order of the sums: the same build gave other last bits on an AMD
  // EPYC (caches 32 kB and 512 kB per core, 32 MB shared) than on an Intel Xeon (48 kB, 2 MB,
  // 60 MB), and the nonconvex fits carried them into other results (on the tribometer record
  // another DNLRX order and an NLR stiffness 11 % apart; every golden document of tests/golden
  // differed).  With the sizes fixed the two machines give the same numbers to the last bit; these
  // are the Xeon's, on which the golden documents were written.  Process-wide, so the program's
  // choice, not the library's (a controller's model evaluation does no matrix product).
  Eigen::setCpuCacheSizes(48 * 1024, 2 * 1024 * 1024, 60 * 1024 * 1024);
  return friction::cli::run(argc, argv);
}
