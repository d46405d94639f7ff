#ifndef ARMBENCH_SEMIHOST_H
#define ARMBENCH_SEMIHOST_H
#include <stdint.h>
void bench_puts(const char *s);
void bench_put_hex(uint32_t v);
void bench_put_dec(int32_t v);
void bench_exit(int code) __attribute__((noreturn));
void bench_mark_begin(int32_t i);
void bench_mark_end(int32_t i);
#endif
