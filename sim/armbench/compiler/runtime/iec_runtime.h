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
#include <ctype.h>

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

/* STRING as MatIEC (OpenPLC v3) stores and computes it: every STRING is a signed length
 * byte and a 126-byte body (STRING[n] is not built by OpenPLC v3), results are cut at 126
 * bytes, comparisons compare the common prefix only ('ab' = 'abc'), and the standard
 * functions keep MatIEC's edge cases (measured in its runtime, see docs/matiec-facts.md).
 * Where MatIEC's C copies a negative or out-of-range byte count (a crash or memory damage
 * on the PLC) the bench faults instead. */
#include <stdio.h>
#include <stdlib.h>
#define PLC__STR_MAX 126
typedef struct { int8_t len; uint8_t body[PLC__STR_MAX]; } plc_string_t;

static inline plc_string_t plc__str_empty(void) { plc_string_t r; memset(&r, 0, sizeof r); return r; }
/* n bytes of s from body index i (i >= -1: byte -1 is the length, which MID with P = 0
 * reads) to r->body[at]: only what MatIEC's memcpy copies without harm */
static inline void plc__str_put(plc_string_t *r, int at, const plc_string_t *s, int i, int n,
                                const char *pos) {
    if (n < 0 || at < 0 || at + n > PLC__STR_MAX || i < -1 || i + n > PLC__STR_MAX)
        plc__fault(pos, "STRING function argument out of range: MatIEC's C copies a negative "
                        "or oversized byte count here (the PLC crashes or corrupts memory)");
    if (n > 0) memcpy(&r->body[at], (const uint8_t *)s + 1 + i, (size_t)n);
}
static inline int plc__str_cmp(plc_string_t a, plc_string_t b) {
    return memcmp(a.body, b.body, (size_t)(a.len < b.len ? a.len : b.len));
}
static inline plc_string_t plc__str_left(plc_string_t in, int64_t l, const char *pos) {
    plc_string_t r = plc__str_empty();
    if (l < 0) return r;
    if (l > in.len) l = in.len;
    plc__str_put(&r, 0, &in, 0, (int)l, pos);
    r.len = (int8_t)l;
    return r;
}
static inline plc_string_t plc__str_right(plc_string_t in, int64_t l, const char *pos) {
    plc_string_t r = plc__str_empty();
    if (l < 0) return r;
    if (l > in.len) l = in.len;
    plc__str_put(&r, 0, &in, (int)(in.len - l), (int)l, pos);
    r.len = (int8_t)l;
    return r;
}
static inline plc_string_t plc__str_mid(plc_string_t in, int64_t l, int64_t p, const char *pos) {
    plc_string_t r = plc__str_empty();
    if (l < 0 || p < 0) return r;
    if (p <= in.len) {
        p -= 1;
        if (l + p > in.len) l = in.len - p;
        plc__str_put(&r, 0, &in, (int)p, (int)l, pos);
        r.len = (int8_t)l;
    }
    return r;
}
static inline void plc__str_cat(plc_string_t *r, plc_string_t s) {
    if (r->len >= PLC__STR_MAX) return;
    int room = PLC__STR_MAX - r->len;
    int n = s.len > room ? room : s.len;
    if (n > 0) memcpy(&r->body[r->len], s.body, (size_t)n);
    r->len = (int8_t)(r->len + n);
}
static inline plc_string_t plc__str_insert(plc_string_t a, plc_string_t b, int64_t p64, const char *pos) {
    plc_string_t r = plc__str_empty();
    if (p64 < 0) return r;
    int8_t p = (int8_t)p64;  /* MatIEC narrows the position to its length type */
    int n = p > a.len ? a.len : p;
    plc__str_put(&r, 0, &a, 0, n, pos);
    r.len = (int8_t)n; p = (int8_t)n;
    n = b.len + r.len > PLC__STR_MAX ? PLC__STR_MAX - r.len : b.len;
    plc__str_put(&r, r.len, &b, 0, n, pos);
    r.len = (int8_t)(r.len + n);
    n = a.len - p < PLC__STR_MAX - r.len ? a.len - p : PLC__STR_MAX - r.len;
    plc__str_put(&r, r.len, &a, p, n, pos);
    r.len = (int8_t)(r.len + n);
    return r;
}
static inline plc_string_t plc__str_delete(plc_string_t in, int64_t l64, int64_t p64, const char *pos) {
    plc_string_t r = plc__str_empty();
    if (l64 < 0 || p64 < 0) return r;
    int8_t l = (int8_t)l64, p = (int8_t)p64;
    int n = p > in.len ? in.len : p - 1;
    plc__str_put(&r, 0, &in, 0, n, pos);
    r.len = (int8_t)n; p = (int8_t)n;
    if (in.len > p + l) {
        n = in.len - p - l;
        plc__str_put(&r, r.len, &in, p + l, n, pos);
        r.len = (int8_t)(r.len + n);
    }
    return r;
}
static inline plc_string_t plc__str_replace(plc_string_t a, plc_string_t b, int64_t l64, int64_t p64, const char *pos) {
    plc_string_t r = plc__str_empty();
    if (l64 < 0 || p64 < 0) return r;
    int8_t l = (int8_t)l64, p = (int8_t)p64;
    int n = p > a.len ? a.len : p - 1;
    plc__str_put(&r, 0, &a, 0, n, pos);
    r.len = (int8_t)n; p = (int8_t)n;
    n = b.len < l ? b.len : l;
    if (n + r.len > PLC__STR_MAX) n = PLC__STR_MAX - r.len;
    plc__str_put(&r, r.len, &b, 0, n, pos);
    r.len = (int8_t)(r.len + n);
    p = (int8_t)(p + l);
    if (r.len < PLC__STR_MAX && p < a.len) {
        n = a.len - p;
        plc__str_put(&r, r.len, &a, p, n, pos);
        r.len = (int8_t)(r.len + n);
    }
    return r;
}
/* MatIEC's FIND, mismatch skips and all: FIND('Hello', 'lo') is 6 there, and so here */
static inline int8_t plc__str_find(plc_string_t a, plc_string_t b) {
    uint16_t i = 0, k = 0;
    while (i + k < a.len && k < b.len) {
        if (a.body[i + k] != b.body[k]) { i = (uint16_t)(i + k + 1); k = 0; }
        else k++;
    }
    return (int8_t)(k == b.len - 1 ? 0 : i + 1);
}
static inline plc_string_t plc__str_fmt_s(int64_t v) {
    plc_string_t r = plc__str_empty();
    int n = snprintf((char *)r.body, PLC__STR_MAX, "%lld", (long long)v);
    r.len = (int8_t)(n > PLC__STR_MAX ? PLC__STR_MAX : n);
    return r;
}
static inline plc_string_t plc__str_fmt_u(uint64_t v) {
    plc_string_t r = plc__str_empty();
    int n = snprintf((char *)r.body, PLC__STR_MAX, "%llu", (unsigned long long)v);
    r.len = (int8_t)(n > PLC__STR_MAX ? PLC__STR_MAX : n);
    return r;
}
static inline plc_string_t plc__str_fmt_bits(uint64_t v) {
    plc_string_t r = plc__str_empty();
    int n = snprintf((char *)r.body, PLC__STR_MAX, "16#%llx", (unsigned long long)v);
    r.len = (int8_t)(n > PLC__STR_MAX ? PLC__STR_MAX : n);
    return r;
}
static inline plc_string_t plc__str_fmt_real(double v) {
    plc_string_t r = plc__str_empty();
    int n = snprintf((char *)r.body, PLC__STR_MAX, "%.10g", v);
    r.len = (int8_t)(n > PLC__STR_MAX ? PLC__STR_MAX : n);
    return r;
}
static inline plc_string_t plc__str_fmt_bool(int v) {
    plc_string_t r = plc__str_empty();
    memcpy(r.body, v ? "TRUE" : "FALSE", v ? 4 : 5);
    r.len = (int8_t)(v ? 4 : 5);
    return r;
}
/* TIME as MatIEC prints its (seconds, nanoseconds) pair: T#<d>d<h>h<m>m<s>s<ms>ms */
static inline plc_string_t plc__str_fmt_time(int64_t ns) {
    plc_string_t r = plc__str_empty();
    int32_t sec = (int32_t)(ns / 1000000000LL), nsec = (int32_t)(ns % 1000000000LL);
    int d = sec / 86400, dr = sec % 86400, h = dr / 3600, hr = dr % 3600, m = hr / 60, s = hr % 60;
    char *b = (char *)r.body;
    int n;
    if (!dr && !nsec) n = snprintf(b, PLC__STR_MAX, "T#%dd", d);
    else if (!hr && !nsec) n = snprintf(b, PLC__STR_MAX, "T#%dd%dh", d, h);
    else if (!s && !nsec) n = snprintf(b, PLC__STR_MAX, "T#%dd%dh%dm", d, h, m);
    else if (!nsec) n = snprintf(b, PLC__STR_MAX, "T#%dd%dh%dm%ds", d, h, m, s);
    else n = snprintf(b, PLC__STR_MAX, "T#%dd%dh%dm%ds%gms", d, h, m, s, (double)nsec / 1000000);
    r.len = (int8_t)(n > PLC__STR_MAX ? PLC__STR_MAX : n);
    return r;
}
static inline int plc__str_to_bool(plc_string_t in) {
    if (in.len == 1) return in.body[0] == '1';
    if (in.len != 4) return 0;
    for (int i = 0; i < 4; i++)
        if (toupper(in.body[i]) != (unsigned char)"TRUE"[i]) return 0;
    return 1;
}
/* MatIEC's reading of an integer: 2#, 8#, 16# prefixes, else decimal digits read from the
 * right (at most 20), a character at or above '.' that is no digit restarting the number */
static inline int64_t plc__str_to_int(plc_string_t in) {
    int64_t r = 0;
    unsigned shift = 0;
    const uint8_t *s = in.body;
    if (s[0] == '2' && s[1] == '#') {
        for (int l = in.len - 1; l >= 2 && shift < 64; l--) {
            char c = (char)s[l];
            if (c >= '0' && c <= '1') { r |= (c - '0') << shift; shift += 1; }
        }
    } else if (s[0] == '8' && s[1] == '#') {
        for (int l = in.len - 1; l >= 2 && shift < 64; l--) {
            char c = (char)s[l];
            if (c >= '0' && c <= '7') { r |= (c - '0') << shift; shift += 3; }
        }
    } else if (s[0] == '1' && s[1] == '6' && s[2] == '#') {
        for (int l = in.len - 1; l >= 3 && shift < 64; l--) {
            char c = (char)s[l];
            if (c >= '0' && c <= '9') { r |= (int64_t)((uint64_t)(c - '0') << shift); shift += 4; }
            else if (c >= 'a' && c <= 'f') { r |= (int64_t)((uint64_t)(c - 'a' + 10) << shift); shift += 4; }
            else if (c >= 'A' && c <= 'F') { r |= (int64_t)((uint64_t)(c - 'A' + 10) << shift); shift += 4; }
        }
    } else {
        int64_t fac = s[0] == '-' ? -1 : 1;
        for (int l = in.len - 1; l >= 0 && shift < 20; l--) {
            char c = (char)s[l];
            if (c >= '0' && c <= '9') { r += (c - '0') * fac; fac *= 10; shift += 1; }
            else if (c >= '.') { r = 0; fac = s[0] == '-' ? -1 : 1; shift = 0; }
        }
    }
    return r;
}
/* the body up to its 126th byte as a C string, as atof reads it */
static inline double plc__str_atof(plc_string_t in) {
    char b[PLC__STR_MAX + 1];
    memcpy(b, in.body, PLC__STR_MAX);
    b[PLC__STR_MAX] = 0;
    return atof(b);
}
static inline int plc__str_has_dot(plc_string_t in) {
    int8_t l = in.len;
    while (--l > 0 && in.body[l] != '.') {}
    return l != 0;
}
static inline double plc__str_to_real(plc_string_t in) {
    return plc__str_has_dot(in) ? plc__str_atof(in) : (double)plc__str_to_int(in);
}
/* MatIEC keeps whole seconds only (its fraction is multiplied after a cast to integer) */
static inline int64_t plc__str_to_time(plc_string_t in) {
    int32_t sec = plc__str_has_dot(in) ? (int32_t)(long)plc__str_atof(in)
                                       : (int32_t)(long)plc__str_to_int(in);
    return (int64_t)sec * 1000000000LL;
}
#endif
