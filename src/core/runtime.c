/* Process-wide settings of the C runtime, made once at program start
 * (ellroll and the benchmarks call it).
 *
 * Keep freed memory in the process instead of handing it back to the system
 * at once. Every case allocates its output buffers and frees them once they
 * are written, and a campaign block its journal records (over 128 KiB for
 * 8 cases). With glibc's defaults the heap shrinks after each batch (trim
 * threshold 128 KiB) and blocks over 128 KiB are mapped and unmapped each
 * time (setting the trim threshold also fixes the mmap threshold at its
 * default): the next batch page-faults its memory in again, about 6 ns per
 * case-step of a batch storing every field at 100 Hz (bench/throughput) and
 * 4 % of a campaign (perf, when the writer's windows were still freed and
 * allocated; they are recycled now, src/output). Up to 256 MiB of freed
 * heap is kept for reuse and blocks up to 32 MiB come from the heap; peak
 * memory does not change. Other C libraries (no M_TRIM_THRESHOLD): nothing.
 *
 * Ignore SIGXFSZ: past a file-size limit (ulimit -f, as batch systems set
 * it) a write then fails with EFBIG, which the program reports like any
 * other write error; the signal's default action would end it with a core. */
#ifdef __linux__
#include <malloc.h>
#endif
#include <signal.h>

void ellroll_crc32c_init(void);

void ellroll_tune_runtime(void)
{
#ifdef M_TRIM_THRESHOLD
    mallopt(M_TRIM_THRESHOLD, 256 * 1024 * 1024);
#endif
#ifdef M_MMAP_THRESHOLD
    mallopt(M_MMAP_THRESHOLD, 32 * 1024 * 1024);
#endif
    signal(SIGXFSZ, SIG_IGN);
    ellroll_crc32c_init(); /* before threads compute checksums */
}
