/* Process-wide settings of the C runtime, made once at program start
 * (ellroll and the benchmarks call it).
 *
 * Keep freed memory in the process instead of handing it back to the system
 * at once. Every case allocates its output buffers and frees them once they
 * are written; with glibc's default trim threshold (128 KiB) the heap shrinks
 * after each batch or window, and the next one page-faults its buffers in
 * again: about 6 ns per case-step of a batch storing every field at 100 Hz
 * (bench/throughput). Up to 256 MiB of freed heap is kept for reuse; peak
 * memory does not change. Other C libraries (no M_TRIM_THRESHOLD): nothing. */
#ifdef __linux__
#include <malloc.h>
#endif

void ellroll_tune_runtime(void)
{
#ifdef M_TRIM_THRESHOLD
    mallopt(M_TRIM_THRESHOLD, 256 * 1024 * 1024);
#endif
}
