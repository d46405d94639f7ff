/* Modbus TCP load client for bench/modbus_server_speed.py: FC16 write + FC3 read pairs on one
 * connection, as fast as the server answers, for a fixed time.
 *
 * Raw sockets and nothing else, so the client costs a few microseconds per transaction and the
 * server is what is measured (a pymodbus client tops out near 10,000 transactions/s, below
 * either server). Every read is checked against the values just written, and every reply's
 * transaction id, function code and length against the request, so a fast wrong answer cannot
 * count.
 *
 *   modbus_pairs HOST PORT SECONDS ADDRESS COUNT
 *
 * writes COUNT (1..123) holding registers at ADDRESS with FC16, reads them back with FC3, and
 * prints one line:  pairs=N transactions=2N seconds=S tps=T
 * Exit 0 on success; 1 with a message on stderr for a wrong, exceptional or missing reply;
 * 2 for bad arguments.
 */
#define _POSIX_C_SOURCE 200809L
#include <arpa/inet.h>
#include <errno.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

#define WARMUP_PAIRS 200
#define CHECK_EVERY 64 /* pairs between two clock reads */

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static void fail(const char *what) {
    fprintf(stderr, "modbus_pairs: %s\n", what);
    exit(1);
}

static void send_all(int fd, const uint8_t *buf, size_t n) {
    while (n > 0) {
        ssize_t k = send(fd, buf, n, 0);
        if (k < 0) {
            if (errno == EINTR) continue;
            perror("modbus_pairs: send");
            exit(1);
        }
        buf += k;
        n -= (size_t)k;
    }
}

static void recv_all(int fd, uint8_t *buf, size_t n) {
    while (n > 0) {
        ssize_t k = recv(fd, buf, n, 0);
        if (k == 0) fail("the server closed the connection");
        if (k < 0) {
            if (errno == EINTR) continue;
            if (errno == EAGAIN || errno == EWOULDBLOCK) fail("no reply within 3 s");
            perror("modbus_pairs: recv");
            exit(1);
        }
        buf += k;
        n -= (size_t)k;
    }
}

/* One reply: MBAP header, then the PDU; checks transaction id, protocol and unit. Returns the
 * PDU length. */
static size_t read_reply(int fd, uint16_t tid, uint8_t *pdu, size_t cap) {
    uint8_t h[7];
    recv_all(fd, h, 7);
    uint16_t rtid = (uint16_t)(h[0] << 8 | h[1]);
    uint16_t proto = (uint16_t)(h[2] << 8 | h[3]);
    uint16_t len = (uint16_t)(h[4] << 8 | h[5]);
    if (rtid != tid || proto != 0 || h[6] != 1 || len < 2 || (size_t)(len - 1) > cap) {
        fprintf(stderr, "modbus_pairs: bad MBAP header (tid %u for %u, protocol %u, unit %u, "
                "length %u)\n", rtid, tid, proto, h[6], len);
        exit(1);
    }
    recv_all(fd, pdu, (size_t)(len - 1));
    if (pdu[0] & 0x80) {
        fprintf(stderr, "modbus_pairs: exception %u to function %u\n", pdu[1], pdu[0] & 0x7f);
        exit(1);
    }
    return (size_t)(len - 1);
}

int main(int argc, char **argv) {
    if (argc != 6) {
        fprintf(stderr, "usage: modbus_pairs HOST PORT SECONDS ADDRESS COUNT\n");
        return 2;
    }
    const char *host = argv[1];
    const char *port = argv[2];
    double seconds = atof(argv[3]);
    long address = strtol(argv[4], NULL, 10);
    long count = strtol(argv[5], NULL, 10);
    if (!(seconds > 0.0) || address < 0 || count < 1 || count > 123 || address + count > 65536) {
        fprintf(stderr, "modbus_pairs: SECONDS > 0, 0 <= ADDRESS, 1 <= COUNT <= 123\n");
        return 2;
    }

    struct addrinfo hints, *ai;
    memset(&hints, 0, sizeof hints);
    hints.ai_family = AF_INET;
    hints.ai_socktype = SOCK_STREAM;
    int rc = getaddrinfo(host, port, &hints, &ai);
    if (rc != 0) {
        fprintf(stderr, "modbus_pairs: %s:%s: %s\n", host, port, gai_strerror(rc));
        return 1;
    }
    int fd = socket(ai->ai_family, ai->ai_socktype, ai->ai_protocol);
    if (fd < 0 || connect(fd, ai->ai_addr, ai->ai_addrlen) != 0) {
        perror("modbus_pairs: connect");
        return 1;
    }
    freeaddrinfo(ai);
    int one = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    struct timeval tv = {3, 0};
    setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);

    uint8_t wreq[7 + 6 + 2 * 123], rreq[7 + 5], pdu[300];
    const size_t wlen = 7 + 6 + 2 * (size_t)count;
    uint16_t tid = 0;
    uint16_t value = 0;
    long pairs = 0;
    double start = 0.0, end = 0.0;

    for (long i = 0;; i++) {
        if (i == WARMUP_PAIRS) start = now_s();
        if (i > WARMUP_PAIRS && (i - WARMUP_PAIRS) % CHECK_EVERY == 0) {
            end = now_s();
            if (end - start >= seconds) {
                pairs = i - WARMUP_PAIRS;
                break;
            }
        }
        /* FC16: a fresh value in every register, so a stale read cannot pass */
        tid++;
        uint16_t len = (uint16_t)(wlen - 6);
        uint8_t w[13] = {tid >> 8, tid & 0xff, 0, 0, len >> 8, len & 0xff, 1, 16,
                         (uint8_t)(address >> 8), (uint8_t)(address & 0xff),
                         0, (uint8_t)count, (uint8_t)(2 * count)};
        memcpy(wreq, w, sizeof w);
        uint16_t first = value;
        for (long r = 0; r < count; r++) {
            wreq[13 + 2 * r] = (uint8_t)(value >> 8);
            wreq[14 + 2 * r] = (uint8_t)(value & 0xff);
            value++;
        }
        send_all(fd, wreq, wlen);
        size_t n = read_reply(fd, tid, pdu, sizeof pdu);
        if (n != 5 || pdu[0] != 16 || (pdu[1] << 8 | pdu[2]) != address ||
            (pdu[3] << 8 | pdu[4]) != count)
            fail("bad FC16 reply");

        tid++;
        uint8_t r[12] = {tid >> 8, tid & 0xff, 0, 0, 0, 6, 1, 3, (uint8_t)(address >> 8),
                         (uint8_t)(address & 0xff), 0, (uint8_t)count};
        memcpy(rreq, r, sizeof r);
        send_all(fd, rreq, sizeof r);
        n = read_reply(fd, tid, pdu, sizeof pdu);
        if (n != 2 + 2 * (size_t)count || pdu[0] != 3 || pdu[1] != 2 * count)
            fail("bad FC3 reply");
        for (long k = 0; k < count; k++) {
            uint16_t got = (uint16_t)(pdu[2 + 2 * k] << 8 | pdu[3 + 2 * k]);
            if (got != (uint16_t)(first + k)) {
                fprintf(stderr, "modbus_pairs: register %ld read %u after writing %u\n",
                        address + k, got, (uint16_t)(first + k));
                return 1;
            }
        }
    }
    close(fd);
    double dt = end - start;
    printf("pairs=%ld transactions=%ld seconds=%.3f tps=%.0f\n", pairs, 2 * pairs, dt,
           2.0 * (double)pairs / dt);
    return 0;
}
