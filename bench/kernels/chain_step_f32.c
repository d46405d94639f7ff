/* Hand-written C of the REAL (float32) version of ChainResolvedRateFixed's step: the same
   algorithm as st/KinematicsChainFixed.st (FK, 3x4 Jacobian, A = J J^T, its adjugate and
   determinant, dq = J^T adj(A) dX / det) in float32, the yardstick of
   bench/cortex_m3/chain_line.py (soft-float on a Cortex-M3). Its host twin is
   armbench.plant.redundant_chain.track_float32. */
#include <math.h>
#include <stdint.h>

typedef struct { float a1, a2, a3, a4, a5; } chain_geo_f32;

static void chain_fk_f32(const chain_geo_f32 *g, const float q[4], float p[3], float jac[3][4]) {
    float c1 = cosf(q[0]), s1 = sinf(q[0]);
    float phi[3] = {q[1], q[1] + q[2], q[1] + q[2] + q[3]};
    float len[3] = {g->a3, g->a4, g->a5};
    float sr = 0.0f, sz = 0.0f;
    for (int k = 2; k >= 0; k--) {           /* partial sums from the outer link inwards */
        sr += len[k] * cosf(phi[k]);
        sz += len[k] * sinf(phi[k]);
        jac[0][k + 1] = -c1 * sz;
        jac[1][k + 1] = -s1 * sz;
        jac[2][k + 1] = sr;
    }
    float r = g->a2 + sr;
    p[0] = r * c1;
    p[1] = r * s1;
    p[2] = g->a1 + sz;
    jac[0][0] = -p[1];
    jac[1][0] = p[0];
    jac[2][0] = 0.0f;
}

/* One step towards target (m); q (rad) updated in place. Returns 0, or 1 if det <= 0. */
int chain_step_f32(const chain_geo_f32 *g, float q[4], const float target[3]) {
    float p[3], jac[3][4], a[3][3], adj[3][3], e[3], v[3];
    chain_fk_f32(g, q, p, jac);
    for (int i = 0; i < 3; i++) {
        e[i] = target[i] - p[i];
        for (int j = 0; j < 3; j++) {
            float s = 0.0f;
            for (int k = 0; k < 4; k++) s += jac[i][k] * jac[j][k];
            a[i][j] = s;
        }
    }
    adj[0][0] = a[1][1] * a[2][2] - a[1][2] * a[1][2];
    adj[0][1] = a[0][2] * a[1][2] - a[0][1] * a[2][2];
    adj[0][2] = a[0][1] * a[1][2] - a[0][2] * a[1][1];
    adj[1][1] = a[0][0] * a[2][2] - a[0][2] * a[0][2];
    adj[1][2] = a[0][1] * a[0][2] - a[0][0] * a[1][2];
    adj[2][2] = a[0][0] * a[1][1] - a[0][1] * a[0][1];
    adj[1][0] = adj[0][1];
    adj[2][0] = adj[0][2];
    adj[2][1] = adj[1][2];
    float det = a[0][0] * adj[0][0] + a[0][1] * adj[0][1] + a[0][2] * adj[0][2];
    if (!(det > 0.0f)) return 1;
    for (int i = 0; i < 3; i++) v[i] = adj[i][0] * e[0] + adj[i][1] * e[1] + adj[i][2] * e[2];
    for (int k = 0; k < 4; k++)
        q[k] += (jac[0][k] * v[0] + jac[1][k] * v[1] + jac[2][k] * v[2]) / det;
    return 0;
}
