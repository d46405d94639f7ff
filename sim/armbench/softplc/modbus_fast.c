/* Compiled request path of the soft PLC's Modbus TCP server (softplc/fastpath.py loads it).
 *
 * The Python server (modbus_server.py) spends most of a request in the interpreter: framing,
 * dispatch, struct packing, the scan lock. This file does the same work for one connection
 * in C, with the GIL released for the connection's whole life (cffi releases it around every
 * call), so a request costs a few microseconds and never waits for another Python thread.
 *
 * It answers exactly like PduHandler in modbus_server.py, which answers like the OpenPLC v3
 * runtime (docs/modbus-parity.md): every quirk listed there is implemented once here and once
 * there, and tests/softplc/test_softplc_fastpath.py feeds both the same requests.
 *
 * Locking: mb_lock is the soft PLC's scan lock (SoftPlc.lock is an ImageLock wrapping one).
 * A request runs under it from its first image access to its last, so an FC16 write lands
 * whole between two scans, as on the runtime (bufferLock around every request).
 */
#define _GNU_SOURCE
#include <errno.h>
#include <pthread.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/types.h>
#include <time.h>

/* plc_image_t layout (image.py; the compiler's generated struct) */
#define IX_OFFSET 0
#define QX_OFFSET (IX_OFFSET + 8192)
#define IW_OFFSET (QX_OFFSET + 8192)
#define QW_OFFSET (IW_OFFSET + 2 * 1024)
#define MD_OFFSET (QW_OFFSET + 2 * 2048) /* %QW then %MW, 2048 registers */
#define ML_OFFSET (MD_OFFSET + 4 * 1024)

/* OpenPLC's address map and limits (modbus_map.py, modbus_server.py) */
#define COIL_COUNT 8192
#define DISCRETE_INPUT_COUNT 8192
#define INPUT_REGISTER_COUNT 1024
#define HOLDING_REGISTER_COUNT 8192
#define MD_BASE 2048
#define ML_BASE 4096
#define MAX_DATA_BYTES 255
#define MAX_REGISTERS 127
#define MAX_MBAP_LENGTH (10000 - 6)

#define ILLEGAL_FUNCTION 1
#define ILLEGAL_DATA_ADDRESS 2
#define ILLEGAL_DATA_VALUE 3

#define MB_REPLY_MAX 260 /* function + byte count + 255 data bytes, rounded up */

/* ---- the scan lock: a binary semaphore, so it may be released by another thread than the
 * one that took it (threading.Lock allows that, and ImageLock stands in for one) ---------- */

typedef struct {
    pthread_mutex_t m;
    pthread_cond_t c;
    int held;
} mb_lock;

mb_lock *mb_lock_new(void) {
    mb_lock *l = calloc(1, sizeof *l);
    if (l == NULL) return NULL;
    pthread_condattr_t attr;
    pthread_condattr_init(&attr);
    pthread_condattr_setclock(&attr, CLOCK_MONOTONIC);
    pthread_mutex_init(&l->m, NULL);
    pthread_cond_init(&l->c, &attr);
    pthread_condattr_destroy(&attr);
    return l;
}

void mb_lock_free(mb_lock *l) {
    if (l == NULL) return;
    pthread_cond_destroy(&l->c);
    pthread_mutex_destroy(&l->m);
    free(l);
}

/* timeout_s < 0: wait for ever; 0: try once. Returns 1 when taken, 0 when not. */
int mb_lock_acquire(mb_lock *l, double timeout_s) {
    pthread_mutex_lock(&l->m);
    if (l->held && timeout_s != 0.0) {
        if (timeout_s < 0.0) {
            while (l->held) pthread_cond_wait(&l->c, &l->m);
        } else {
            struct timespec until;
            clock_gettime(CLOCK_MONOTONIC, &until);
            double whole = (double)(long)timeout_s;
            until.tv_sec += (time_t)whole;
            until.tv_nsec += (long)((timeout_s - whole) * 1e9);
            if (until.tv_nsec >= 1000000000L) {
                until.tv_sec++;
                until.tv_nsec -= 1000000000L;
            }
            while (l->held) {
                if (pthread_cond_timedwait(&l->c, &l->m, &until) == ETIMEDOUT) break;
            }
        }
    }
    int taken = !l->held;
    if (taken) l->held = 1;
    pthread_mutex_unlock(&l->m);
    return taken;
}

/* Returns 0, or -1 when the lock was not held (Python raises RuntimeError then). */
int mb_lock_release(mb_lock *l) {
    pthread_mutex_lock(&l->m);
    int was = l->held;
    l->held = 0;
    pthread_mutex_unlock(&l->m);
    if (!was) return -1;
    pthread_cond_signal(&l->c);
    return 0;
}

int mb_lock_locked(mb_lock *l) {
    pthread_mutex_lock(&l->m);
    int held = l->held;
    pthread_mutex_unlock(&l->m);
    return held;
}

/* ---- one PDU -------------------------------------------------------------------------- */

static uint16_t be16(const uint8_t *p) { return (uint16_t)(p[0] << 8 | p[1]); }

static size_t exception(uint8_t *out, uint8_t function, uint8_t code) {
    out[0] = function | 0x80;
    out[1] = code;
    return 2;
}

static size_t echo5(uint8_t *out, const uint8_t *pdu) {
    memcpy(out, pdu, 5);
    return 5;
}

/* Holding register r (0..8191) as the wire word: %QW/%MW one uint16 each, %MD/%ML the words
 * of a native uint32/uint64, most significant first. */
static uint16_t holding_get(const uint8_t *img, unsigned r) {
    if (r < MD_BASE) {
        uint16_t v;
        memcpy(&v, img + QW_OFFSET + 2 * r, 2);
        return v;
    }
    if (r < ML_BASE) {
        uint32_t v;
        unsigned rel = r - MD_BASE;
        memcpy(&v, img + MD_OFFSET + 4 * (rel / 2), 4);
        return (uint16_t)(v >> (16 * (1 - rel % 2)));
    }
    uint64_t v;
    unsigned rel = r - ML_BASE;
    memcpy(&v, img + ML_OFFSET + 8 * (rel / 4), 8);
    return (uint16_t)(v >> (16 * (3 - rel % 4)));
}

/* Writes one word and keeps the other words of a wider value (FC6 on half a REAL). */
static void holding_set(uint8_t *img, unsigned r, uint16_t word) {
    if (r < MD_BASE) {
        memcpy(img + QW_OFFSET + 2 * r, &word, 2);
        return;
    }
    if (r < ML_BASE) {
        uint32_t v;
        unsigned rel = r - MD_BASE;
        uint8_t *p = img + MD_OFFSET + 4 * (rel / 2);
        unsigned shift = 16 * (1 - rel % 2);
        memcpy(&v, p, 4);
        v = (v & ~((uint32_t)0xFFFF << shift)) | ((uint32_t)word << shift);
        memcpy(p, &v, 4);
        return;
    }
    uint64_t v;
    unsigned rel = r - ML_BASE;
    uint8_t *p = img + ML_OFFSET + 8 * (rel / 4);
    unsigned shift = 16 * (3 - rel % 4);
    memcpy(&v, p, 8);
    v = (v & ~((uint64_t)0xFFFF << shift)) | ((uint64_t)word << shift);
    memcpy(p, &v, 8);
}

/* FC1/FC2: whole bytes of bits from start, padding bits included (OpenPLC). */
static size_t read_bits(uint8_t *img, mb_lock *lock, const uint8_t *pdu, size_t n,
                        uint8_t *out, unsigned offset, unsigned size) {
    if (n < 5) return exception(out, pdu[0], ILLEGAL_DATA_VALUE);
    unsigned start = be16(pdu + 1), count = be16(pdu + 3);
    unsigned nbytes = (count + 7) / 8;
    out[0] = pdu[0];
    out[1] = 0;
    if (nbytes == 0) return 2;
    if (nbytes > MAX_DATA_BYTES || start + 8 * nbytes > size)
        return exception(out, pdu[0], ILLEGAL_DATA_ADDRESS);
    const uint8_t *bits = img + offset + start;
    mb_lock_acquire(lock, -1.0);
    for (unsigned b = 0; b < nbytes; b++) {
        uint8_t byte = 0;
        for (unsigned j = 0; j < 8; j++) byte |= (uint8_t)((bits[8 * b + j] != 0) << j);
        out[2 + b] = byte;
    }
    mb_lock_release(lock);
    out[1] = (uint8_t)nbytes;
    return 2 + nbytes;
}

static size_t write_coil(uint8_t *img, mb_lock *lock, const uint8_t *pdu, size_t n,
                         uint8_t *out) {
    if (n < 5) return exception(out, pdu[0], ILLEGAL_DATA_VALUE);
    unsigned address = be16(pdu + 1);
    if (address >= COIL_COUNT) return exception(out, pdu[0], ILLEGAL_DATA_ADDRESS);
    mb_lock_acquire(lock, -1.0);
    img[QX_OFFSET + address] = be16(pdu + 3) != 0; /* any non-zero value is TRUE */
    mb_lock_release(lock);
    return echo5(out, pdu);
}

static size_t write_coils(uint8_t *img, mb_lock *lock, const uint8_t *pdu, size_t n,
                          uint8_t *out) {
    if (n < 5) return exception(out, pdu[0], ILLEGAL_DATA_VALUE);
    unsigned start = be16(pdu + 1), count = be16(pdu + 3);
    unsigned nbytes = (count + 7) / 8;
    if (n < 6 + (size_t)nbytes || pdu[5] != nbytes)
        return exception(out, pdu[0], ILLEGAL_DATA_VALUE);
    if (nbytes == 0) return echo5(out, pdu);
    unsigned end = start + 8 * nbytes;
    unsigned stop = end < COIL_COUNT ? end : COIL_COUNT;
    if (stop > start) {
        /* the padding bits are written too (OpenPLC) */
        const uint8_t *data = pdu + 6;
        uint8_t *coils = img + QX_OFFSET;
        mb_lock_acquire(lock, -1.0);
        for (unsigned a = start; a < stop; a++) {
            unsigned i = a - start;
            coils[a] = (data[i / 8] >> (i % 8)) & 1;
        }
        mb_lock_release(lock);
    }
    if (end > COIL_COUNT) return exception(out, pdu[0], ILLEGAL_DATA_ADDRESS);
    return echo5(out, pdu);
}

static uint16_t input_get(const uint8_t *img, unsigned r) {
    uint16_t w;
    memcpy(&w, img + IW_OFFSET + 2 * r, 2);
    return w;
}

/* FC3/FC4: registers start..start+count-1 of a table of `size`, read by `get`. */
static size_t read_words(uint8_t *img, mb_lock *lock, const uint8_t *pdu, size_t n,
                         uint8_t *out, unsigned size,
                         uint16_t (*get)(const uint8_t *, unsigned)) {
    if (n < 5) return exception(out, pdu[0], ILLEGAL_DATA_VALUE);
    unsigned start = be16(pdu + 1), count = be16(pdu + 3);
    out[0] = pdu[0];
    out[1] = 0;
    if (count == 0) return 2;
    if (count > MAX_REGISTERS || start + count > size)
        return exception(out, pdu[0], ILLEGAL_DATA_ADDRESS);
    mb_lock_acquire(lock, -1.0);
    for (unsigned i = 0; i < count; i++) {
        uint16_t w = get(img, start + i);
        out[2 + 2 * i] = (uint8_t)(w >> 8);
        out[3 + 2 * i] = (uint8_t)w;
    }
    mb_lock_release(lock);
    out[1] = (uint8_t)(2 * count);
    return 2 + 2 * count;
}

static size_t write_register(uint8_t *img, mb_lock *lock, const uint8_t *pdu, size_t n,
                             uint8_t *out) {
    if (n < 5) return exception(out, pdu[0], ILLEGAL_DATA_VALUE);
    unsigned address = be16(pdu + 1);
    if (address >= HOLDING_REGISTER_COUNT) return exception(out, pdu[0], ILLEGAL_DATA_ADDRESS);
    mb_lock_acquire(lock, -1.0);
    holding_set(img, address, be16(pdu + 3));
    mb_lock_release(lock);
    return echo5(out, pdu);
}

static size_t write_registers(uint8_t *img, mb_lock *lock, const uint8_t *pdu, size_t n,
                              uint8_t *out) {
    if (n < 5) return exception(out, pdu[0], ILLEGAL_DATA_VALUE);
    unsigned start = be16(pdu + 1), count = be16(pdu + 3);
    unsigned nbytes = 2 * count;
    /* the byte count is one byte, so this also limits count to 127 */
    if (n < 6 + (size_t)nbytes || pdu[5] != nbytes)
        return exception(out, pdu[0], ILLEGAL_DATA_VALUE);
    if (count == 0) return echo5(out, pdu);
    unsigned end = start + count;
    unsigned stop = end < HOLDING_REGISTER_COUNT ? end : HOLDING_REGISTER_COUNT;
    if (stop > start) {
        const uint8_t *data = pdu + 6;
        /* one lock hold for the whole request: a scan sees all of it or none of it */
        mb_lock_acquire(lock, -1.0);
        for (unsigned a = start; a < stop; a++) holding_set(img, a, be16(data + 2 * (a - start)));
        mb_lock_release(lock);
    }
    if (end > HOLDING_REGISTER_COUNT) return exception(out, pdu[0], ILLEGAL_DATA_ADDRESS);
    return echo5(out, pdu);
}

/* One request PDU (n >= 1 bytes) -> the reply PDU in out (MB_REPLY_MAX bytes); its length. */
size_t mb_handle(uint8_t *img, mb_lock *lock, const uint8_t *pdu, size_t n, uint8_t *out) {
    switch (pdu[0]) {
    case 1: return read_bits(img, lock, pdu, n, out, QX_OFFSET, COIL_COUNT);
    case 2: return read_bits(img, lock, pdu, n, out, IX_OFFSET, DISCRETE_INPUT_COUNT);
    case 3: return read_words(img, lock, pdu, n, out, HOLDING_REGISTER_COUNT, holding_get);
    case 4: return read_words(img, lock, pdu, n, out, INPUT_REGISTER_COUNT, input_get);
    case 5: return write_coil(img, lock, pdu, n, out);
    case 6: return write_register(img, lock, pdu, n, out);
    case 15: return write_coils(img, lock, pdu, n, out);
    case 16: return write_registers(img, lock, pdu, n, out);
    default: return exception(out, pdu[0], ILLEGAL_FUNCTION);
    }
}

/* ---- one connection ------------------------------------------------------------------- */

#define RECV_CHUNK 4096
#define IN_CAP (6 + MAX_MBAP_LENGTH + RECV_CHUNK) /* a partial frame + one more chunk */
#define OUT_CAP 65536

static double monotonic_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts); /* the clock of Python's time.monotonic() */
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static int send_all(int fd, const uint8_t *buf, size_t n) {
    while (n > 0) {
        ssize_t k = send(fd, buf, n, MSG_NOSIGNAL);
        if (k < 0) {
            if (errno == EINTR) continue;
            return -errno;
        }
        buf += k;
        n -= (size_t)k;
    }
    return 0;
}

/* Serves requests on the blocking socket fd until the peer closes it (0), the framing is
 * lost (0: a protocol id other than 0 or an MBAP length outside 2..9994, after answering
 * the frames before it), or a socket error (-errno; also how the server's shutdown() of the
 * socket ends it). *last_request gets the monotonic time whenever a read completed at least
 * one request, for the server's idle timeout. Several pipelined frames in one read are
 * answered with one send, as the Python path does. */
int mb_serve(int fd, uint8_t *img, mb_lock *lock, double *last_request) {
    uint8_t *in = malloc(IN_CAP);
    uint8_t *outbuf = malloc(OUT_CAP);
    if (in == NULL || outbuf == NULL) {
        free(in);
        free(outbuf);
        return -ENOMEM;
    }
    size_t have = 0;
    int rc = 0;
    for (;;) {
        ssize_t k = recv(fd, in + have, RECV_CHUNK, 0);
        if (k == 0) break;
        if (k < 0) {
            if (errno == EINTR) continue;
            rc = -errno;
            break;
        }
        have += (size_t)k;
        size_t pos = 0, out = 0;
        int lost = 0, answered = 0;
        while (have - pos >= 7) {
            const uint8_t *h = in + pos;
            unsigned protocol = be16(h + 2), length = be16(h + 4);
            if (protocol != 0 || length < 2 || length > MAX_MBAP_LENGTH) {
                lost = 1; /* nothing after this can be trusted on this stream */
                break;
            }
            size_t end = pos + 6 + length;
            if (end > have) break;
            if (OUT_CAP - out < 7 + MB_REPLY_MAX) {
                rc = send_all(fd, outbuf, out);
                out = 0;
                if (rc != 0) goto done;
            }
            uint8_t *reply = outbuf + out;
            size_t m = mb_handle(img, lock, h + 7, length - 1, reply + 7);
            memcpy(reply, h, 4); /* transaction id, protocol 0 */
            reply[4] = (uint8_t)((m + 1) >> 8);
            reply[5] = (uint8_t)(m + 1);
            reply[6] = h[6]; /* unit id */
            out += 7 + m;
            answered = 1;
            pos = end;
        }
        if (answered) *last_request = monotonic_s();
        if (out > 0) {
            rc = send_all(fd, outbuf, out);
            if (rc != 0) break;
        }
        if (lost) break;
        memmove(in, in + pos, have - pos);
        have -= pos;
    }
done:
    free(in);
    free(outbuf);
    return rc;
}
