/* CRC-32C (Castagnoli), the checksum of the journal's header and records.
 *
 * It detects every error of up to 3 bits in a message of up to 2^31 bits
 * (Castagnoli, Braeuer and Herrmann 1993, Hamming distance 4), and every
 * burst up to 32 bits long. x86-64 computes it with the SSE4.2 instruction
 * crc32 (8 bytes an instruction); where the processor lacks it (checked
 * once, at run time, so that a portable build uses it too), with tables,
 * 8 bytes a step. Both give the same value: a journal reads back on any
 * machine. */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#define POLY 0x82F63B78u /* the Castagnoli polynomial, bits reversed */

static uint32_t table[8][256];
static int hardware = -1; /* unknown, no, yes */

static void make_tables(void)
{
    for (uint32_t n = 0; n < 256; n++) {
        uint32_t c = n;
        for (int k = 0; k < 8; k++)
            c = c & 1 ? (c >> 1) ^ POLY : c >> 1;
        table[0][n] = c;
    }
    for (uint32_t n = 0; n < 256; n++)
        for (int t = 1; t < 8; t++)
            table[t][n] = (table[t - 1][n] >> 8) ^ table[0][table[t - 1][n] & 0xff];
}

static uint32_t crc_tables(uint32_t crc, const unsigned char *p, size_t n)
{
    while (n >= 8) {
        uint64_t w;
        memcpy(&w, p, 8);
        w ^= crc;
        crc = table[7][w & 0xff] ^ table[6][(w >> 8) & 0xff] ^ table[5][(w >> 16) & 0xff] ^
              table[4][(w >> 24) & 0xff] ^ table[3][(w >> 32) & 0xff] ^ table[2][(w >> 40) & 0xff] ^
              table[1][(w >> 48) & 0xff] ^ table[0][w >> 56];
        p += 8;
        n -= 8;
    }
    while (n--)
        crc = (crc >> 8) ^ table[0][(crc ^ *p++) & 0xff];
    return crc;
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
__attribute__((target("sse4.2"))) static uint32_t crc_hardware(uint32_t crc, const unsigned char *p, size_t n)
{
    uint64_t c = crc;
    while (n >= 8) {
        uint64_t w;
        memcpy(&w, p, 8);
        c = __builtin_ia32_crc32di(c, w);
        p += 8;
        n -= 8;
    }
    crc = (uint32_t)c;
    while (n--)
        crc = __builtin_ia32_crc32qi(crc, *p++);
    return crc;
}
#define HAVE_HARDWARE_CRC 1
#endif

/* Make the tables and look for the instruction; once, before any thread
 * computes a checksum (the program's start). */
void ellroll_crc32c_init(void)
{
    if (hardware >= 0)
        return;
    make_tables();
#ifdef HAVE_HARDWARE_CRC
    __builtin_cpu_init();
    hardware = __builtin_cpu_supports("sse4.2") ? 1 : 0;
#else
    hardware = 0;
#endif
}

/* The CRC-32C of n bytes at data, continuing from crc (0 to start). */
uint32_t ellroll_crc32c(uint32_t crc, const void *data, size_t n)
{
    if (hardware < 0)
        ellroll_crc32c_init();
    crc = ~crc;
#ifdef HAVE_HARDWARE_CRC
    if (hardware)
        return ~crc_hardware(crc, data, n);
#endif
    return ~crc_tables(crc, data, n);
}

/* For the tests: the table path, whatever the processor. */
uint32_t ellroll_crc32c_tables(uint32_t crc, const void *data, size_t n)
{
    if (hardware < 0)
        ellroll_crc32c_init();
    return ~crc_tables(~crc, data, n);
}
