/* Hand-written C of kernels/ik_kernel.st, the yardstick of bench/compiler_bench.py. */
#include <math.h>
#include <stdint.h>

float ik_kernel(int32_t count) {
    float acc = 0.0f;
    for (int32_t i = 0; i < count; i++) {
        float x = 80.0f + (float)(i % 100) * 0.5f;
        float z = -40.0f + (float)(i % 37) * 2.0f;
        float q = x * x + z * z;
        float c2 = (q - 120.0f * 120.0f - 130.0f * 130.0f) / (2.0f * 120.0f * 130.0f);
        c2 = c2 < -1.0f ? -1.0f : (c2 > 1.0f ? 1.0f : c2);
        float t3 = acosf(c2);
        float t2 = atanf(z / x) - atanf(130.0f * sinf(t3) / (120.0f + 130.0f * cosf(t3)));
        acc = acc + t2 + sqrtf(q) * 0.001f + t3;
    }
    return acc;
}
