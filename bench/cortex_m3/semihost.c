/* ARM semihosting (bkpt 0xab) for QEMU's -semihosting-config enable=on,target=native. */
#include <stdint.h>
#include "semihost.h"

static int semihost_call(int op, void *arg) {
    register int r0 __asm__("r0") = op;
    register void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

void bench_puts(const char *s) { semihost_call(0x04, (void *)s); } /* SYS_WRITE0 */

void bench_put_hex(uint32_t v) {
    char buf[9];
    for (int k = 7; k >= 0; k--) { buf[k] = "0123456789abcdef"[v & 15u]; v >>= 4; }
    buf[8] = 0;
    bench_puts(buf);
}

void bench_put_dec(int32_t v) {
    char buf[12];
    int k = 11;
    uint32_t u = v < 0 ? (uint32_t)(-(v + 1)) + 1u : (uint32_t)v;
    buf[k] = 0;
    do { buf[--k] = (char)('0' + u % 10u); u /= 10u; } while (u);
    if (v < 0) buf[--k] = '-';
    bench_puts(&buf[k]);
}

void bench_exit(int code) {
    uint32_t block[2] = {0x20026u, (uint32_t)code}; /* ADP_Stopped_ApplicationExit, code */
    semihost_call(0x20, block);                       /* SYS_EXIT_EXTENDED */
    for (;;) {}
}

/* Markers around each measured IK call; compiled in their own unit so that no optimisation
 * level can move work across them. The driver counts executed instructions between them. */
volatile int32_t bench_marker_index;
void bench_mark_begin(int32_t i) { bench_marker_index = i; }
void bench_mark_end(int32_t i) { bench_marker_index = i; }
