/* Process-wide settings of the C runtime and the libraries below us, made
 * once at program start (ellroll and the benchmarks call it).
 *
 * Keep freed memory in the process instead of handing it back to the system
 * at once. Every case allocates its output buffers and frees them once they
 * are written; with glibc's default trim threshold (128 KiB) the heap shrinks
 * after each batch or window, and the next one page-faults its buffers in
 * again: about 6 ns per case-step of a batch storing every field at 100 Hz
 * (bench/throughput). Up to 256 MiB of freed heap is kept for reuse; peak
 * memory does not change. Other C libraries (no M_TRIM_THRESHOLD): nothing.
 *
 * One thread for OpenBLAS, when it is the BLAS linked: the LAPACK calls here
 * are on 4x4 matrices, and OpenBLAS's worker threads otherwise spin in
 * sched_yield beside our own threads (5 % of the CPU time of a 2-thread
 * campaign, measured with perf). A weak symbol: absent with other BLAS. */
#ifdef __linux__
#include <malloc.h>
#endif

#if defined(__GNUC__)
extern void openblas_set_num_threads(int) __attribute__((weak));
#endif

void ellroll_tune_runtime(void)
{
#ifdef M_TRIM_THRESHOLD
    mallopt(M_TRIM_THRESHOLD, 256 * 1024 * 1024);
#endif
#if defined(__GNUC__)
    if (openblas_set_num_threads) openblas_set_num_threads(1);
#endif
}
