/* armbench IEC 61131-3 runtime for C emitted from ST: arithmetic as MatIEC/OpenPLC does it,
 * faults (division by zero, bounds, watchdog) as a longjmp back to the scan entry with the
 * ST position, never a signal. Written for this project; included once per generated unit. */
#ifndef ARMBENCH_IEC_RUNTIME_H
#define ARMBENCH_IEC_RUNTIME_H
#include <stdint.h>
#include <string.h>
#include <math.h>
#include <setjmp.h>
#include <time.h>

/* One program is one translation unit, or, for a faster build of a large one, several
 * compiled in parallel and linked into one library (ARMBENCH_SPLIT defined in each, and
 * ARMBENCH_SPLIT_MAIN in the one that owns the state below). The state and the POU bodies
 * the units share have hidden linkage then: one copy per library, invisible outside it. */
#ifndef ARMBENCH_SPLIT
#define PLC__INTERNAL static
#define PLC__STATE(decl, init) static decl = init
#else
#define PLC__INTERNAL __attribute__((visibility("hidden")))
#ifdef ARMBENCH_SPLIT_MAIN
#define PLC__STATE(decl, init) PLC__INTERNAL decl = init
#else
#define PLC__STATE(decl, init) extern PLC__INTERNAL decl
#endif
#endif

PLC__STATE(jmp_buf plc__jmp, {0});
PLC__STATE(const char *plc__fault_pos, "");
PLC__STATE(const char *plc__fault_msg, "");
PLC__STATE(int64_t plc__now_ns, 0);          /* the scan's time, set by the soft PLC */
PLC__STATE(int64_t plc__wd_limit_ns, 1000000000); /* watchdog budget of one scan */
PLC__STATE(int64_t plc__wd_start_ns, 0);
PLC__STATE(uint32_t plc__wd_count, 0);

#if !defined(ARMBENCH_SPLIT) || defined(ARMBENCH_SPLIT_MAIN)
const char *plc_fault_pos(void) { return plc__fault_pos; }
const char *plc_fault_msg(void) { return plc__fault_msg; }
void plc_set_time(int64_t ns) { plc__now_ns = ns; }
void plc_set_watchdog(int64_t ns) { plc__wd_limit_ns = ns; }
#endif

static __attribute__((noreturn, noinline, cold)) void plc__fault(const char *pos, const char *msg) {
    plc__fault_pos = pos;
    plc__fault_msg = msg;
    longjmp(plc__jmp, 1);
}

#ifdef ARMBENCH_NO_WATCHDOG
#define PLC__WD(pos) ((void)0)
#define PLC__WD_N(pos, n) ((void)0)
static void plc__wd_begin(void) {}
#else
static int64_t plc__mono_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000LL + ts.tv_nsec;
}
static void plc__wd_begin(void) { plc__wd_start_ns = plc__mono_ns(); plc__wd_count = 0; }
static __attribute__((noinline, cold)) void plc__wd_check(const char *pos) {
    if (plc__mono_ns() - plc__wd_start_ns > plc__wd_limit_ns)
        plc__fault(pos, "watchdog: the scan ran past its time budget (endless loop?)");
}
#define PLC__WD(pos) do { if (__builtin_expect((++plc__wd_count & 0xFFFFu) == 0u, 0)) plc__wd_check(pos); } while (0)
/* n (at most 65536) loop iterations counted at once, before a loop known to make exactly n:
 * the clock is read when the count passes a multiple of 65536, as n PLC__WD would */
#define PLC__WD_N(pos, n) do { uint32_t plc__wd_low = plc__wd_count & 0xFFFFu; plc__wd_count += (uint32_t)(n); if (__builtin_expect(plc__wd_low + (uint32_t)(n) > 0xFFFFu, 0)) plc__wd_check(pos); } while (0)
#endif

/* Copies and clears of STRUCTs and arrays: above PLC__BIG bytes through the C library's
 * memmove/memset (out of line, so that the compiler cannot expand them back inline), which
 * pick the fastest way the machine has; gcc's inline expansion of a struct copy (x86-64:
 * `rep movsq`) took several times as long for the few hundred bytes of a profile. */
#define PLC__BIG 128
static __attribute__((noinline, unused)) void plc__copy_big(void *d, const void *s, size_t n) { memmove(d, s, n); }
static __attribute__((noinline, unused)) void plc__zero_big(void *d, size_t n) { memset(d, 0, n); }
#define PLC__COPY(d, s) do { if (sizeof(d) > PLC__BIG) plc__copy_big(&(d), &(s), sizeof(d)); else (d) = (s); } while (0)
#define PLC__ZERO(x) do { if (sizeof(x) > PLC__BIG) plc__zero_big(&(x), sizeof(x)); else memset(&(x), 0, sizeof(x)); } while (0)

static inline __attribute__((always_inline)) int32_t plc__idx(int64_t i, int64_t lo, int64_t hi, const char *pos) {
    if (__builtin_expect(i < lo || i > hi, 0)) plc__fault(pos, "array index out of bounds");
    return (int32_t)(i - lo);
}
static inline __attribute__((always_inline)) int64_t plc__div_s(int64_t a, int64_t b, const char *pos) {
    if (__builtin_expect(b == 0, 0)) plc__fault(pos, "integer division by zero");
    if (b == -1) return (int64_t)(0 - (uint64_t)a);  /* INT64_MIN / -1 wraps */
    return a / b;
}
static inline __attribute__((always_inline)) uint64_t plc__div_u(uint64_t a, uint64_t b, const char *pos) {
    if (__builtin_expect(b == 0, 0)) plc__fault(pos, "integer division by zero");
    return a / b;
}
static inline __attribute__((always_inline)) int64_t plc__mod_s(int64_t a, int64_t b) {
    if (b == 0 || b == -1) return 0;  /* MatIEC: x MOD 0 = 0 */
    return a % b;
}
static inline __attribute__((always_inline)) uint64_t plc__mod_u(uint64_t a, uint64_t b) { return b == 0 ? 0 : a % b; }
/* 32-bit variants: the M3 divides 32-bit numbers in one instruction, 64-bit ones in libgcc */
static inline __attribute__((always_inline)) int32_t plc__div_s32(int32_t a, int32_t b, const char *pos) {
    if (__builtin_expect(b == 0, 0)) plc__fault(pos, "integer division by zero");
    if (b == -1) return (int32_t)(0u - (uint32_t)a);  /* INT32_MIN / -1 wraps */
    return a / b;
}
static inline __attribute__((always_inline)) uint32_t plc__div_u32(uint32_t a, uint32_t b, const char *pos) {
    if (__builtin_expect(b == 0, 0)) plc__fault(pos, "integer division by zero");
    return a / b;
}
static inline __attribute__((always_inline)) int32_t plc__mod_s32(int32_t a, int32_t b) {
    if (b == 0 || b == -1) return 0;
    return a % b;
}
static inline __attribute__((always_inline)) uint32_t plc__mod_u32(uint32_t a, uint32_t b) { return b == 0 ? 0 : a % b; }
static inline __attribute__((always_inline)) uint32_t plc__shl32(uint32_t v, int32_t n, int bits) {
    return (n < 0 || n >= bits) ? 0u : (v << n);
}
static inline __attribute__((always_inline)) uint32_t plc__shr32(uint32_t v, int32_t n, int bits) {
    return (n < 0 || n >= bits) ? 0u : (v >> n);
}
static inline __attribute__((always_inline)) int64_t plc__r2i(double x) { return (int64_t)nearbyint(x); } /* half to even */
static inline __attribute__((always_inline)) uint64_t plc__r2u(double x) { return x < 0.0 ? 0u : (uint64_t)(int64_t)nearbyint(x); }
static inline __attribute__((always_inline)) uint64_t plc__shl(uint64_t v, int64_t n, int bits) {
    return (n < 0 || n >= bits) ? 0u : (v << n);
}
static inline __attribute__((always_inline)) uint64_t plc__shr(uint64_t v, int64_t n, int bits) {
    return (n < 0 || n >= bits) ? 0u : (v >> n);
}
static inline __attribute__((always_inline)) uint64_t plc__rol(uint64_t v, int64_t n, int bits) {
    uint64_t mask = bits == 64 ? ~0ull : ((1ull << bits) - 1u);
    n %= bits; v &= mask;
    if (n == 0) return v;
    return ((v << n) | (v >> (bits - n))) & mask;
}
static inline __attribute__((always_inline)) uint64_t plc__ror(uint64_t v, int64_t n, int bits) {
    n %= bits;
    return plc__rol(v, n == 0 ? 0 : bits - n, bits);
}
#endif
