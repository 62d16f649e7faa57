/* Host test of the WTCU protocol core: every hex test vector of docs/wtcu-protocol.md in both directions
 * (encoded by the firmware's framing and byte-compared; decoded and, for requests, run through the core
 * with the answer byte-compared where the vector is a reply the unit gives), and the safety limits,
 * watchdog, queue, HEADING pacing and GPS chunking on a simulated millisecond clock.
 * Prints "N passed, M failed"; exits non-zero on any failure. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core.h"
#include "heading.h"
#include "proto.h"

static int passed, failed;

static void check(int ok, const char *fmt, ...)
{
    if (ok) {
        passed++;
        return;
    }
    failed++;
    va_list ap;
    va_start(ap, fmt);
    printf("FAIL: ");
    vprintf(fmt, ap);
    printf("\n");
    va_end(ap);
}

/* ------------------------------------------------------------------ board stubs */

static struct wtcu_plan plan;
static int publishes;
static uint8_t queue_at_publish;
static uint8_t levels[WTCU_TACTORS];
static uint16_t battery_mv = 3900;
static uint32_t gps_baud;
static int gps_open;

void wtcu_hw_publish(const struct wtcu_plan *p)
{
    plan = *p;
    publishes++;
    queue_at_publish = wtcu_queue_count();
}
void wtcu_hw_intensity(const uint8_t level[WTCU_TACTORS]) { memcpy(levels, level, sizeof levels); }
uint16_t wtcu_hw_battery_mv(void) { return battery_mv; }
void wtcu_hw_gps_open(uint32_t baud)
{
    gps_baud = baud;
    gps_open = 1;
}
void wtcu_hw_gps_close(void) { gps_open = 0; }

/* ------------------------------------------------------------------ helpers */

static size_t hex(const char *s, uint8_t *out)
{
    size_t n = 0;
    while (*s) {
        while (*s == ' ') {
            s++;
        }
        if (!*s) {
            break;
        }
        unsigned v;
        sscanf(s, "%2x", &v);
        out[n++] = (uint8_t)v;
        s += 2;
    }
    return n;
}

struct packet {
    uint8_t version, type, seq, len;
    uint8_t payload[256];
};

/* Decodes one complete wire frame (0x00 | COBS | 0x00); 0 on any error. */
static int decode_frame(const uint8_t *f, size_t n, struct packet *p)
{
    uint8_t buf[512];
    if (n < 3 || f[0] != 0 || f[n - 1] != 0) {
        return 0;
    }
    int16_t m = wtcu_cobs_decode(f + 1, (uint16_t)(n - 2), buf);
    if (m < 6) {
        return 0;
    }
    if (wtcu_crc16(buf, (uint16_t)(m - 2)) != wtcu_le16(buf + m - 2)) {
        return 0;
    }
    if (buf[3] != m - 6) {
        return 0;
    }
    p->version = buf[0];
    p->type = buf[1];
    p->seq = buf[2];
    p->len = buf[3];
    memcpy(p->payload, buf + 4, p->len);
    return 1;
}

static uint32_t now;

static void feed(const uint8_t *f, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        wtcu_rx_byte(f[i], now);
    }
}

static void send(uint8_t version, uint8_t type, uint8_t seq, const uint8_t *payload, uint8_t len)
{
    uint8_t f[300];
    uint16_t n = wtcu_build_frame(version, type, seq, payload, len, f);
    feed(f, n);
}

static void send_hex(const char *h)
{
    uint8_t f[300];
    size_t n = hex(h, f);
    feed(f, n);
}

#define MAXOUT 80
static struct packet out[MAXOUT];
static uint8_t out_raw[MAXOUT][300];
static uint16_t out_raw_len[MAXOUT];
static int nout;

static void drain(void)
{
    nout = 0;
    uint8_t f[300];
    uint16_t n;
    while ((n = wtcu_next_frame(f, sizeof f)) != 0) {
        if (nout < MAXOUT) {
            memcpy(out_raw[nout], f, n);
            out_raw_len[nout] = n;
            if (!decode_frame(f, n, &out[nout])) {
                out[nout].type = 0xEE;
            }
            nout++;
        }
    }
}

static void at(uint32_t t)
{
    now = t;
    wtcu_poll(now);
}

static const struct wtcu_features full = {1, 1};

static void reset(uint8_t version)
{
    now = 0;
    wtcu_init(&full, now);
    send(version, 0x01, 0, NULL, 0);
    drain();
}

/* One request answered: returns the answer's type, NAK reason in *reason, tactors_on in *on. */
static uint8_t ask(uint8_t type, uint8_t seq, const uint8_t *payload, uint8_t len, uint8_t *reason)
{
    send(wtcu_session_version(), type, seq, payload, len);
    drain();
    for (int i = 0; i < nout; i++) {
        if (out[i].seq == seq && (out[i].type == 0x82 || out[i].type == 0x83 || out[i].type == 0x84 ||
                                  out[i].type == 0x81)) {
            if (reason) {
                *reason = out[i].type == 0x83 ? out[i].payload[0] : 0;
            }
            return out[i].type;
        }
    }
    return 0;
}

static uint8_t seqn = 10;

static uint8_t fire(uint16_t mask, uint16_t ms)
{
    uint8_t p[4], reason;
    wtcu_put16(p, mask);
    wtcu_put16(p + 2, ms);
    uint8_t t = ask(0x03, seqn++, p, 4, &reason);
    return t == 0x82 ? 0 : (t == 0x83 ? reason : 0xFF);
}

static uint8_t play(uint8_t repeats, int count, const uint16_t *masks, const uint16_t *ms)
{
    uint8_t p[256], reason;
    p[0] = repeats;
    p[1] = (uint8_t)count;
    for (int i = 0; i < count; i++) {
        wtcu_put16(p + 2 + 4 * i, masks[i]);
        wtcu_put16(p + 4 + 4 * i, ms[i]);
    }
    uint8_t t = ask(0x04, seqn++, p, (uint8_t)(2 + 4 * count), &reason);
    return t == 0x82 ? 0 : (t == 0x83 ? reason : 0xFF);
}

static void heartbeat(void) { ask(0x02, seqn++, NULL, 0, NULL); }

/* Advances to t, with a HEARTBEAT at least every 1000 ms (the watchdog stays quiet). */
static void idle_until(uint32_t t)
{
    while (now + 1000 < t) {
        at(now + 1000);
        heartbeat();
    }
    at(t);
}

static int same(const uint8_t *a, uint16_t an, const char *h)
{
    uint8_t b[300];
    size_t bn = hex(h, b);
    return an == bn && memcmp(a, b, bn) == 0;
}

/* ------------------------------------------------------------------ test vectors */

struct vector {
    const char *name;
    const char *frame;
};

static const struct vector vectors[] = {
    {"HELLO seq 0", "00 03 01 01 01 03 44 c5 00"},
    {"HEARTBEAT seq 1", "00 04 01 02 01 03 25 af 00"},
    {"FIRE corners", "00 0b 01 03 02 04 09 90 f4 01 43 e8 00"},
    {"PLAY turn left",
     "00 0a 01 04 03 12 01 04 88 88 fa 04 44 44 fa 04 22 22 fa 04 11 11 fa 03 57 d6 00"},
    {"SET_INTENSITY", "00 0a 01 05 04 03 ff ff 80 60 45 00"},
    {"STOP_ALL", "00 04 01 06 05 03 21 bf 00"},
    {"GET_STATUS", "00 04 01 07 06 03 42 dd 00"},
    {"IDENTIFY v1", "00 03 01 81 03 11 01 01 11 10 03 d0 07 08 10 27 88 13 20 10 27 dc 05 4a 96 00"},
    {"ACK corners", "00 09 01 82 02 02 09 90 ca 97 00"},
    {"NAK too many", "00 06 01 83 07 03 06 01 03 c7 1d 00"},
    {"STATUS", "00 08 01 84 06 09 3c 0f 43 01 01 02 01 01 03 6e b4 00"},
    {"REPORT watchdog", "00 05 01 85 01 03 01 04 01 22 ff 00"},
    {"HELLO v2", "00 03 02 01 01 03 98 5e 00"},
    {"NAK version", "00 03 01 83 03 03 04 01 03 73 14 00"},
    {"IDENTIFY v2 2.0.0", "00 03 02 81 03 11 02 01 11 10 07 d0 07 08 10 27 88 13 20 10 27 dc 05 fa cc 00"},
    {"HEADING_START 5", "00 08 02 08 01 01 05 e8 84 00"},
    {"HEADING_STOP", "00 04 02 09 02 03 5b 91 00"},
    {"SET_CALIBRATION",
     "00 06 02 0a 03 1a 7b 04 d4 fe ff 01 02 10 01 01 01 01 01 01 02 10 01 01 01 01 01 01 06 10 f4 01 5a 82 00"},
    {"HEADING", "00 0a 02 86 09 0d 39 30 06 ff 64 03 57 b6 07 e1 ff 9a 01 79 41 00"},
    {"GPS_START 9600", "00 07 02 0b 04 04 80 25 01 03 1e ca 00"},
    {"GPS_STOP", "00 04 02 0c 05 03 3c e3 00"},
    {"GPS_DATA ZDA", "00 05 02 87 0c 0c 01 0d 24 47 50 5a 44 41 2c 31 0d 0a 5f 3c 00"},
    {"GPS_DATA lost 300", "00 0e 02 87 0d 07 2c 01 2a 35 42 0d 0a 09 16 00"},
    {"IDENTIFY v2 GPS", "00 03 02 81 03 11 01 01 11 10 0f d0 07 08 10 27 88 13 20 10 27 dc 05 86 f6 00"},
};

static void test_vectors_codec(void)
{
    for (size_t i = 0; i < sizeof vectors / sizeof vectors[0]; i++) {
        uint8_t f[300];
        size_t n = hex(vectors[i].frame, f);
        struct packet p;
        int ok = decode_frame(f, n, &p);
        check(ok, "decode vector %s", vectors[i].name);
        if (!ok) {
            continue;
        }
        uint8_t g[300];
        uint16_t m = wtcu_build_frame(p.version, p.type, p.seq, p.payload, p.len, g);
        check(m == n && memcmp(f, g, n) == 0, "re-encode vector %s", vectors[i].name);
    }
    /* CRC check value, COBS corner cases */
    check(wtcu_crc16((const uint8_t *)"123456789", 9) == 0x29B1, "crc check value");
    uint8_t z[300], e[310], d[310];
    for (int len = 0; len < 300; len += 7) {
        for (int k = 0; k < len; k++) {
            z[k] = (uint8_t)((k * 37) % 5 == 0 ? 0 : k + 1);
        }
        uint16_t el = wtcu_cobs_encode(z, (uint16_t)len, e);
        int zero_free = 1;
        for (int k = 0; k < el; k++) {
            zero_free &= e[k] != 0;
        }
        int16_t dl = wtcu_cobs_decode(e, el, d);
        check(zero_free && dl == len && memcmp(d, z, (size_t)len) == 0, "cobs round trip %d", len);
    }
    memset(z, 0x55, 254);
    uint16_t el = wtcu_cobs_encode(z, 254, e);
    check(el == 256 && e[0] == 0xFF, "cobs 254 non-zero bytes");
    check(wtcu_cobs_decode(e, el, d) == 254 && memcmp(d, z, 254) == 0, "cobs 254 decode");
    uint8_t bad[] = {0x05, 0x01, 0x02};
    check(wtcu_cobs_decode(bad, 3, d) < 0, "cobs truncated block refused");
}

/* The unit side of the vectors: requests run through the core, replies produced byte for byte. */
static void test_vectors_unit(void)
{
    /* HELLO v1 -> IDENTIFY v1 exactly (a v2 unit answers a v1 HELLO in v1, caps 0x03). */
    now = 0;
    wtcu_init(&full, 0);
    send_hex(vectors[0].frame);
    drain();
    check(nout == 1 && same(out_raw[0], out_raw_len[0], vectors[7].frame), "HELLO v1 -> IDENTIFY v1 vector");
    check(wtcu_session_version() == 1, "v1 session");
    /* HEARTBEAT seq 1 -> ACK */
    send_hex(vectors[1].frame);
    drain();
    check(nout == 1 && out[0].type == 0x82 && out[0].seq == 1 && out[0].version == 1, "HEARTBEAT -> ACK");
    /* FIRE corners seq 2 -> ACK corners vector */
    send_hex(vectors[2].frame);
    drain();
    check(nout == 1 && same(out_raw[0], out_raw_len[0], vectors[8].frame), "FIRE corners -> ACK vector");
    check(wtcu_tactors_on() == 0x9009 && plan.on == 0x9009 && plan.has_next && plan.next_at == 500,
          "FIRE corners drives 0x9009 until 500 ms");
    /* PLAY turn left seq 3 -> ACK with column 3 */
    at(100);
    send_hex(vectors[3].frame);
    drain();
    check(nout == 1 && out[0].type == 0x82 && out[0].seq == 3 && wtcu_le16(out[0].payload) == 0x8888,
          "PLAY turn left -> ACK 0x8888");
    at(350);
    drain();
    check(nout == 1 && out[0].type == 0x85 && wtcu_le16(out[0].payload) == 0x4444, "PLAY steps at 250 ms");
    /* SET_INTENSITY 128 seq 4 */
    send_hex(vectors[4].frame);
    drain();
    check(nout == 1 && out[0].type == 0x82 && out[0].seq == 4 && levels[0] == 128 && levels[15] == 128,
          "SET_INTENSITY 128 -> ACK, levels set");
    /* STOP_ALL seq 5: outputs cleared before the ACK is queued */
    send_hex(vectors[5].frame);
    check(plan.on == 0 && queue_at_publish == 0, "STOP_ALL clears outputs before queuing the ACK");
    drain();
    check(nout == 1 && out[0].type == 0x82 && out[0].seq == 5 && wtcu_le16(out[0].payload) == 0,
          "STOP_ALL -> ACK nothing on");
    /* GET_STATUS seq 6 -> STATUS vector (3900 mV, 67 %, no faults) */
    send_hex(vectors[6].frame);
    drain();
    check(nout == 1 && same(out_raw[0], out_raw_len[0], vectors[10].frame), "GET_STATUS -> STATUS vector");
    /* FIRE 9 tactors seq 7 -> NAK too many vector */
    uint8_t p[4] = {0xFF, 0x01, 0x64, 0x00};
    send(1, 0x03, 7, p, 4);
    drain();
    check(nout == 1 && same(out_raw[0], out_raw_len[0], vectors[9].frame), "FIRE 9 tactors -> NAK 0x06 vector");

    /* REPORT watchdog vector: a fresh v1 session, silence for 1500 ms -> REPORT seq 1, fault 0x01 */
    reset(1);
    at(1499);
    drain();
    check(nout == 0, "no watchdog before 1500 ms");
    at(1500);
    drain();
    check(nout == 1 && same(out_raw[0], out_raw_len[0], vectors[11].frame), "watchdog -> REPORT vector");

    /* A v3 HELLO -> NAK 0x04 in a v1 header (the vector) */
    now = 0;
    wtcu_init(&full, 0);
    send(3, 0x01, 0, NULL, 0);
    drain();
    check(nout == 1 && same(out_raw[0], out_raw_len[0], vectors[13].frame), "v3 HELLO -> NAK 0x04 vector");

    /* HELLO v2 -> IDENTIFY v2 with heading + GPS (vector, firmware 1.0.0) */
    send_hex(vectors[12].frame);
    drain();
    check(nout == 1 && same(out_raw[0], out_raw_len[0], vectors[23].frame), "HELLO v2 -> IDENTIFY v2 GPS vector");
    check(wtcu_session_version() == 2, "v2 session");
    /* Without the magnetometer: caps 0x0B */
    {
        struct wtcu_features nomag = {0, 1};
        wtcu_init(&nomag, 0);
        send_hex(vectors[12].frame);
        drain();
        check(nout == 1 && out[0].type == 0x81 && out[0].payload[4] == 0x0B, "no magnetometer: caps 0x0B");
        send_hex(vectors[15].frame);
        drain();
        check(nout == 1 && out[0].type == 0x83 && out[0].payload[0] == 0x09, "HEADING_START without mag: 0x09");
        struct wtcu_features none = {0, 0};
        wtcu_init(&none, 0);
        send_hex(vectors[12].frame);
        drain();
        check(nout == 1 && out[0].payload[4] == 0x03, "tactor-only unit: caps 0x03");
        send_hex(vectors[19].frame);
        drain();
        check(nout == 1 && out[0].type == 0x83 && out[0].payload[0] == 0x09, "GPS_START without GPS: 0x09");
    }
    wtcu_init(&full, 0);
    send_hex(vectors[12].frame);
    drain();
    /* HEADING_START 5 Hz, HEADING_STOP, SET_CALIBRATION, GPS_START 9600, GPS_STOP */
    send_hex(vectors[15].frame);
    drain();
    check(nout == 1 && out[0].type == 0x82 && out[0].seq == 1 && out[0].version == 2, "HEADING_START -> ACK");
    check(wtcu_heading_due(0) == 1 && wtcu_heading_due(199) == 0 && wtcu_heading_due(200) == 1,
          "HEADING due at 5 Hz");
    send_hex(vectors[16].frame);
    drain();
    check(nout == 1 && out[0].type == 0x82 && out[0].seq == 2 && wtcu_heading_due(400) == 0,
          "HEADING_STOP -> ACK, stream off");
    send_hex(vectors[17].frame);
    drain();
    check(nout == 1 && out[0].type == 0x82 && out[0].seq == 3, "SET_CALIBRATION (W = I) -> ACK");
    send_hex(vectors[19].frame);
    drain();
    check(nout == 1 && out[0].type == 0x82 && out[0].seq == 4 && gps_open && gps_baud == 9600,
          "GPS_START 9600 -> ACK, UART opened at 9600");
    /* GPS_DATA: `$GPZDA,1\r\n` forwarded in one chunk on its line feed */
    const char *zda = "$GPZDA,1\r\n";
    for (const char *c = zda; *c; c++) {
        wtcu_gps_byte((uint8_t)*c, now);
    }
    drain();
    check(nout == 1 && out[0].type == 0x87 && out[0].len == 12 && wtcu_le16(out[0].payload) == 0 &&
              memcmp(out[0].payload + 2, zda, 10) == 0,
          "GPS line forwarded as GPS_DATA");
    {
        /* The same frame as the vector, but for the seq (the unit's own report counter). */
        struct packet v;
        uint8_t f[64];
        size_t n = hex(vectors[21].frame, f);
        decode_frame(f, n, &v);
        check(v.len == out[0].len && memcmp(v.payload, out[0].payload, v.len) == 0 && out[0].version == 2,
              "GPS_DATA payload equals the vector's");
    }
    send_hex(vectors[20].frame);
    drain();
    check(nout == 1 && out[0].type == 0x82 && out[0].seq == 5 && !gps_open, "GPS_STOP -> ACK, UART closed");
}

/* ------------------------------------------------------------------ limits */

static void test_limits(void)
{
    reset(1);
    check(fire(0x0001, 0) == 0x05, "FIRE 0 ms -> 0x05");
    check(fire(0x0001, 2001) == 0x05, "FIRE 2001 ms -> 0x05");
    check(fire(0x01FF, 100) == 0x06, "FIRE 9 tactors -> 0x06");
    check(wtcu_faults() & WTCU_FAULT_LIMIT, "limit refusal raises fault 0x04");
    check(fire(0x00FF, 2000) == 0, "FIRE 8 tactors 2000 ms accepted");
    check(fire(0x0000, 0) == 0 && wtcu_tactors_on() == 0, "FIRE empty mask stops");

    /* Across commands: a run continued by a new FIRE */
    reset(1);
    check(fire(0x0001, 1500) == 0, "FIRE 1500");
    at(1000);
    check(fire(0x0001, 1001) == 0x05, "chained FIRE 1000 + 1001 -> 0x05");
    check(wtcu_tactors_on() == 1 && plan.next_at == 1500, "a NAKed command has no effect");
    check(fire(0x0001, 1000) == 0, "chained FIRE 1000 + 1000 accepted");
    at(2000);
    check(wtcu_tactors_on() == 0, "run ended at 2000");
    check(fire(0x0001, 1) == 0x05, "switching on again at the instant it ended continues the run");
    check(fire(0x0002, 2000) == 0, "another tactor is free");
    at(2001);
    check(fire(0x0001, 2000) == 0, "after a 1 ms break a new run starts");

    /* PLAY: the repeated pattern of the issue, closed form with wraps */
    reset(1);
    uint16_t m8[1] = {0x00FF}, d1000[1] = {1000};
    check(play(5, 1, m8, d1000) == 0x05, "PLAY 8 tactors 1000 ms x5 -> 0x05");
    check(play(2, 1, m8, d1000) == 0, "PLAY 1000 ms x2 = 2000 accepted");
    heartbeat();
    at(2000);
    drain();
    check(wtcu_tactors_on() == 0, "pattern x2 ended at 2000");
    reset(1);
    {
        uint16_t m[3] = {1, 0, 1}, d[3] = {1100, 100, 1000};
        check(play(2, 3, m, d) == 0x05, "wrap S + P = 2100 -> 0x05");
        check(play(1, 3, m, d) == 0, "no wrap with one repeat");
    }
    reset(1);
    {
        uint16_t m[3] = {1, 2, 1}, d[3] = {800, 200, 800};
        check(play(3, 3, m, d) == 0, "wrap S + P = 1600 accepted");
    }
    reset(1);
    {
        /* across commands with PLAY's leading run */
        check(fire(0x0001, 1500) == 0, "FIRE 1500 before PLAY");
        at(1000);
        uint16_t m[2] = {1, 0}, d[2] = {1001, 10};
        check(play(1, 2, m, d) == 0x05, "PLAY leading run 1001 after 1000 on -> 0x05");
        uint16_t m2[2] = {2, 1}, d2[2] = {500, 1500};
        check(play(1, 2, m2, d2) == 0, "PLAY not starting with the tactor is fine");
    }
    reset(1);
    {
        uint16_t m[33], d[33];
        for (int i = 0; i < 33; i++) {
            m[i] = 1u << (i % 16);
            d[i] = 10;
        }
        check(play(1, 33, m, d) == 0x08, "33 frames -> 0x08");
        check(play(0, 2, m, d) == 0x08, "0 repeats -> 0x08");
        check(play(1, 0, m, d) == 0x08, "no frames -> 0x08");
        uint16_t big[2] = {0, 0}, dl[2] = {5000, 5001};
        check(play(1, 2, big, dl) == 0x08, "10001 ms -> 0x08");
        uint16_t pz[2] = {1, 2}, dz[2] = {100, 0};
        check(play(1, 2, pz, dz) == 0x05, "0 ms frame -> 0x05");
        uint16_t p9[2] = {1, 0x01FF}, d9[2] = {100, 100};
        check(play(1, 2, p9, d9) == 0x06, "frame with 9 tactors -> 0x06");
        uint8_t bad[5] = {1, 2, 1, 0, 100}, reason = 0;
        check(ask(0x04, seqn++, bad, 5, &reason) == 0x83 && reason == 0x03, "PLAY length mismatch -> 0x03");
        uint8_t ff[3] = {1, 0, 100};
        check(ask(0x03, seqn++, ff, 3, &reason) == 0x83 && reason == 0x03, "FIRE 3 bytes -> 0x03");
        check(ask(0x02, seqn++, ff, 1, &reason) == 0x83 && reason == 0x03, "HEARTBEAT with payload -> 0x03");
    }

    /* Duty cycle: 5000 ms per 10 s */
    reset(1);
    check(fire(0x0001, 2000) == 0, "duty: 2000");
    idle_until(2001);
    check(fire(0x0001, 2000) == 0, "duty: 4000");
    idle_until(4002);
    check(fire(0x0001, 1000) == 0, "duty: 5000 exactly accepted");
    idle_until(5003);
    check(wtcu_duty_spent_ms(0, now) == 5000, "duty ledger books 5000 ms exactly (%u)",
          wtcu_duty_spent_ms(0, now));
    check(fire(0x0001, 1) == 0x07, "duty: one more ms -> 0x07");
    check(fire(0x0002, 1000) == 0, "duty is per tactor");
    idle_until(16000);
    check(fire(0x0001, 1000) == 0, "duty: free again after the window");
    /* a pattern's planned on-time counts all repeats */
    reset(1);
    {
        uint16_t m[2] = {1, 0}, d[2] = {1000, 1000};
        check(play(5, 2, m, d) == 0, "pattern 5 x 1000 on = 5000 accepted");
        idle_until(9000);
        check(wtcu_duty_spent_ms(0, now) == 5000, "pattern booked 5000 ms");
        check(fire(0x0001, 1) == 0x07, "... then 1 ms more -> 0x07");
        uint8_t p2[6] = {1, 1, 0x01, 0x00, 0x10, 0x00};
        uint8_t reason = 0;
        check(ask(0x04, seqn++, p2, 6, &reason) == 0x83 && reason == 0x07, "... and a PLAY too -> 0x07");
    }

    /* Late processing: steps happen at their own instants */
    reset(1);
    {
        uint16_t m[3] = {1, 2, 4}, d[3] = {100, 100, 100};
        check(play(1, 3, m, d) == 0, "PLAY 3 x 100");
        at(1000);
        drain();
        check(wtcu_tactors_on() == 0 && nout == 1 && out[0].type == 0x85, "late poll: one REPORT (replaced)");
        check(wtcu_duty_spent_ms(0, now) == 100 && wtcu_duty_spent_ms(1, now) == 100 &&
                  wtcu_duty_spent_ms(2, now) == 100,
              "late poll books each step at its instant");
    }
    /* ISR plan: the next change is published ahead */
    reset(1);
    {
        uint16_t m[2] = {1, 2}, d[2] = {300, 200};
        play(2, 2, m, d);
        check(plan.on == 1 && plan.has_next && plan.next_at == 300 && plan.next_mask == 2, "plan: next step");
        at(300);
        check(plan.on == 2 && plan.next_at == 500 && plan.next_mask == 1, "plan: wrap to the first frame");
        at(800);
        check(plan.on == 2 && plan.next_at == 1000 && plan.next_mask == 0, "plan: last step ends everything");
        check(plan.wd_armed && plan.wd_at == 1500, "plan: watchdog deadline published");
    }
}

static void test_session(void)
{
    /* Before HELLO: NAK 0x0A */
    now = 0;
    wtcu_init(&full, 0);
    uint8_t reason = 0;
    check(ask(0x02, 1, NULL, 0, &reason) == 0x83 && reason == 0x0A, "request before HELLO -> 0x0A");
    /* v2 types in a v1 session: 0x02 */
    reset(1);
    uint8_t r5 = 5;
    check(ask(0x08, 2, &r5, 1, &reason) == 0x83 && reason == 0x02, "HEADING_START in v1 -> 0x02");
    check(ask(0x20, 3, NULL, 0, &reason) == 0x83 && reason == 0x02, "unknown type -> 0x02");
    /* v2: rate out of range */
    reset(2);
    uint8_t r0 = 0, r11 = 11;
    check(ask(0x08, 4, &r0, 1, &reason) == 0x83 && reason == 0x03, "HEADING_START 0 Hz -> 0x03");
    check(ask(0x08, 5, &r11, 1, &reason) == 0x83 && reason == 0x03, "HEADING_START 11 Hz -> 0x03");
    uint8_t baud[4] = {0x00, 0x4B, 0x00, 0x00}; /* 19200 */
    check(ask(0x0B, 6, baud, 4, &reason) == 0x82, "GPS_START 19200");
    baud[0] = 0x01;
    check(ask(0x0B, 7, baud, 4, &reason) == 0x83 && reason == 0x03, "GPS_START odd baud -> 0x03");
    /* calibration checks */
    uint8_t cal[26] = {0};
    for (int i = 0; i < 3; i++) {
        wtcu_put16(cal + 6 + 8 * i, 4096);
    }
    wtcu_put16(cal + 24, 500);
    check(ask(0x0A, 8, cal, 26, &reason) == 0x82, "SET_CALIBRATION identity");
    wtcu_put16(cal + 24, 0);
    check(ask(0x0A, 9, cal, 26, &reason) == 0x83 && reason == 0x03, "zero field -> 0x03");
    wtcu_put16(cal + 24, 500);
    wtcu_put16(cal + 6 + 2, 100); /* w01 != w10 */
    check(ask(0x0A, 10, cal, 26, &reason) == 0x83 && reason == 0x03, "non-symmetric -> 0x03");
    wtcu_put16(cal + 6 + 2, 0);
    wtcu_put16(cal + 6 + 16, (uint16_t)-4096); /* w22 = -1 */
    check(ask(0x0A, 11, cal, 26, &reason) == 0x83 && reason == 0x03, "not positive definite -> 0x03");
    wtcu_put16(cal + 6 + 16, 4096);
    wtcu_put16(cal + 6 + 2, 8000);
    wtcu_put16(cal + 6 + 6, 8000); /* symmetric, m2 < 0 */
    check(ask(0x0A, 12, cal, 26, &reason) == 0x83 && reason == 0x03, "indefinite -> 0x03");

    /* Repeated (seq, request): answered again, not run twice */
    reset(1);
    uint8_t p[4];
    wtcu_put16(p, 1);
    wtcu_put16(p + 2, 1000);
    check(ask(0x03, 40, p, 4, &reason) == 0x82, "FIRE seq 40");
    at(600);
    check(ask(0x03, 40, p, 4, &reason) == 0x82 && plan.next_at == 1000, "repeat: ACK again, fire not restarted");
    wtcu_put16(p + 2, 1401);
    check(ask(0x03, 41, p, 4, &reason) == 0x83 && reason == 0x05, "new seq: run check applies (600 + 1401)");
}

static void test_line(void)
{
    reset(1);
    /* bad CRC -> NAK 0x01 seq 0, fault 0x08 */
    send_hex("00 04 01 02 01 03 25 ae 00");
    drain();
    check(nout == 1 && out[0].type == 0x83 && out[0].payload[0] == 0x01 && out[0].seq == 0 &&
              (wtcu_faults() & WTCU_FAULT_LINE),
          "bad CRC -> NAK 0x01, fault 0x08");
    /* garbage: no answer */
    uint32_t g = wtcu_garbage_frames();
    send_hex("00 01 01 00 00 00 05 11 00");
    send_hex("00 00 00");
    drain();
    check(nout == 0 && wtcu_garbage_frames() == g + 2, "garbage dropped and counted, empty frames ignored");
    uint8_t longf[400];
    memset(longf, 0x11, sizeof longf);
    feed(longf, sizeof longf);
    send_hex(vectors[1].frame); /* the leading 0x00 ends the junk */
    drain();
    check(nout == 1 && out[0].type == 0x82 && wtcu_garbage_frames() == g + 3, "over-long frame dropped");
    /* a frame of exactly 210 bytes on the wire is a frame (200-byte payload: malformed here) */
    uint8_t big[200] = {0}, f[300];
    big[0] = 1;
    big[1] = 49;
    uint16_t n = wtcu_build_frame(1, 0x04, 77, big, 198, f);
    feed(f, n);
    drain();
    check(n <= 210, "a 198-byte payload frame is %u bytes on the wire", n);
    check(nout == 1 && out[0].type == 0x83 && out[0].payload[0] == 0x08, "49-frame PLAY -> 0x08");
    /* STATUS clears faults and reports low battery */
    battery_mv = 3400;
    uint8_t reason;
    check(ask(0x07, 90, NULL, 0, &reason) == 0x84, "GET_STATUS");
    check(out[0].payload[5] == (WTCU_FAULT_LINE | WTCU_FAULT_LIMIT | WTCU_FAULT_LOW_BATTERY) &&
              out[0].payload[2] == 11,
          "STATUS faults line+limit+battery, 11 %% (%u %u)", out[0].payload[5], out[0].payload[2]);
    check(wtcu_faults() == 0, "STATUS clears faults");
    battery_mv = 4300;
    ask(0x07, 91, NULL, 0, &reason);
    check(out[0].payload[2] == 100 && out[0].payload[5] == 0, "4300 mV = 100 %%");
    battery_mv = 3200;
    ask(0x07, 92, NULL, 0, &reason);
    check(out[0].payload[2] == 0, "3200 mV = 0 %%");
    battery_mv = 3900;
}

static void test_queue(void)
{
    reset(1);
    for (int i = 0; i < 100; i++) {
        send(1, 0x02, (uint8_t)i, NULL, 0);
    }
    check(wtcu_queue_count() == 64 && wtcu_dropped_frames() == 36, "queue bounded at 64, oldest dropped");
    drain();
    check(out[0].seq == 36 && out[63].seq == 99, "newest answers kept");
    /* drop order: HEADING first, then GPS_DATA, then REPORT, answers last */
    reset(2);
    uint8_t gs[4] = {0x80, 0x25, 0, 0};
    send(2, 0x0B, 1, gs, 4);
    uint8_t r10 = 10;
    send(2, 0x08, 2, &r10, 1);
    drain();
    uint16_t m[1] = {1}, d[1] = {100};
    play(1, 1, m, d); /* its ACK is drained by the helper */
    int16_t mag[3] = {133, 0, 300}, acc[3] = {0, 0, -1000};
    check(wtcu_heading_due(now), "heading due");
    wtcu_heading_sample(mag, acc, 1);
    wtcu_gps_byte('\n', now);
    at(100); /* REPORT: the pattern ended */
    for (int i = 0; i < 61; i++) { /* HEADING, GPS_DATA, REPORT and 61 answers = 64 */
        send(2, 0x02, (uint8_t)(100 + i), NULL, 0);
    }
    check(wtcu_queue_count() == 64, "queue full (%u)", wtcu_queue_count());
    send(2, 0x02, 200, NULL, 0);
    send(2, 0x02, 201, NULL, 0);
    send(2, 0x02, 202, NULL, 0);
    drain();
    int heading = 0, gps = 0, report = 0;
    for (int i = 0; i < nout; i++) {
        heading += out[i].type == 0x86;
        gps += out[i].type == 0x87;
        report += out[i].type == 0x85;
    }
    check(heading == 0 && gps == 0 && report == 0 && nout == 64, "HEADING, then GPS_DATA, then REPORT dropped");
    wtcu_gps_byte('x', now);
    wtcu_gps_byte('\n', now);
    drain();
    check(nout == 1 && out[0].type == 0x87 && wtcu_le16(out[0].payload) == 1, "dropped GPS byte counted in lost");
}

static void test_heading(void)
{
    struct wtcu_calib c;
    wtcu_calib_identity(&c);
    uint8_t p[13];
    struct {
        float m[3];
        float a[3];
        int hd;
    } cases[] = {
        {{20, 0, 45}, {0, 0, -1}, 0},
        {{0, -20, 45}, {0, 0, -1}, 9000},
        {{-20, 0, 45}, {0, 0, -1}, 18000},
        {{0, 20, 45}, {0, 0, -1}, 27000},
    };
    for (int i = 0; i < 4; i++) {
        int ok = wtcu_heading_payload(cases[i].m, cases[i].a, &c, p);
        int hd = wtcu_le16(p);
        check(ok && (hd == cases[i].hd || (cases[i].hd == 0 && hd == 0)), "level heading %d (%d)", cases[i].hd,
              hd);
    }
    /* tilted: pitch 30 deg nose up, facing north: field (20, 0, 45) rotated into the body */
    {
        float th = 30.0f * 3.14159265f / 180.0f;
        float m[3] = {20 * cosf(th) - 45 * sinf(th), 0, 20 * sinf(th) + 45 * cosf(th)};
        float g[3] = {-sinf(th), 0, cosf(th)}; /* gravity in body */
        float a[3] = {-g[0], -g[1], -g[2]};
        int ok = wtcu_heading_payload(m, a, &c, p);
        int hd = wtcu_le16(p);
        check(ok && (hd <= 1 || hd >= 35999) && (int16_t)wtcu_le16(p + 2) == 3000, "pitch 30 heading %d pitch %d",
              hd, (int16_t)wtcu_le16(p + 2));
    }
    float ff[3] = {0, 0, 0}, m0[3] = {20, 0, 45};
    check(!wtcu_heading_payload(m0, ff, &c, p), "free fall: no reading");
    /* quality: F = 49.24 -> 100, raw in 0.1 uT */
    c.field = sqrtf(20 * 20 + 45 * 45);
    float a[3] = {0, 0, -1};
    wtcu_heading_payload(m0, a, &c, p);
    check(p[6] == 100 && wtcu_le16(p + 7) == 200 && wtcu_le16(p + 11) == 450, "quality 100, raw 0.1 uT");
    c.field = c.field * 1.1f;
    wtcu_heading_payload(m0, a, &c, p);
    check(p[6] >= 81 && p[6] <= 83, "quality ~82 for 9 %% off (%u)", p[6]);
    /* calibration from the vector: b = (12.3, -30, 25.5), W = I, F = 50 */
    uint8_t f[64];
    struct packet v;
    size_t n = hex(vectors[17].frame, f);
    decode_frame(f, n, &v);
    check(wtcu_calib_from_wire(v.payload, &c) == 0 && fabsf(c.b[0] - 12.3f) < 1e-4 && fabsf(c.b[1] + 30.0f) < 1e-4 &&
              fabsf(c.field - 50.0f) < 1e-4 && c.w[1][1] == 1.0f,
          "calibration vector parsed");
    /* pacing: late unit sends one reading, not a burst */
    reset(2);
    uint8_t r5 = 5;
    send(2, 0x08, 1, &r5, 1);
    drain();
    check(wtcu_heading_due(0), "due at start");
    check(wtcu_heading_due(1050) && !wtcu_heading_due(1050) && !wtcu_heading_due(1199) && wtcu_heading_due(1200),
          "late by 5 periods: one reading, then on the grid");
    int16_t mr[3] = {133, 0, 300}, ar[3] = {0, 0, -1000};
    wtcu_heading_sample(mr, ar, 1);
    wtcu_heading_sample(mr, ar, 1);
    drain();
    check(nout == 1 && out[0].type == 0x86 && out[0].version == 2 && wtcu_le16(out[0].payload + 7) == 200,
          "unsent HEADING replaced; raw 133 counts = 20.0 uT");
    /* the watchdog does not stop the stream */
    at(5000);
    check(wtcu_heading_due(5000), "stream survives the watchdog");
}

static void test_gps(void)
{
    reset(2);
    uint8_t gs[4] = {0x80, 0x25, 0, 0};
    send(2, 0x0B, 1, gs, 4);
    drain();
    for (int i = 0; i < 64; i++) {
        wtcu_gps_byte('A', now);
    }
    drain();
    check(nout == 1 && out[0].len == 66, "64 bytes: one chunk");
    now = 1000;
    wtcu_gps_byte('B', now);
    at(1049);
    drain();
    check(nout == 0, "not before 50 ms");
    at(1050);
    drain();
    check(nout == 1 && out[0].len == 3 && out[0].payload[2] == 'B', "50 ms after the first byte");
    wtcu_gps_lost(300);
    const char *s = "*5B\r\n";
    for (const char *c = s; *c; c++) {
        wtcu_gps_byte((uint8_t)*c, now);
    }
    drain();
    struct packet v;
    uint8_t f[64];
    size_t n = hex(vectors[22].frame, f);
    decode_frame(f, n, &v);
    check(nout == 1 && out[0].len == v.len && memcmp(out[0].payload, v.payload, v.len) == 0,
          "lost 300 then `*5B\\r\\n`: payload equals the vector's");
    /* HELLO stops forwarding */
    send(2, 0x01, 0, NULL, 0);
    wtcu_gps_byte('\n', now);
    drain();
    check(nout == 1 && out[0].type == 0x81 && !gps_open, "HELLO ends GPS forwarding");
}

/* The duty ledger against a brute-force per-millisecond history: never below the exact on-time of the
 * last 10 s, never above that of the last 10.5 s. Random FIREs (accepted or not) on a random clock. */
static void test_duty_property(void)
{
    static uint16_t hist[60000];
    reset(1);
    srand(12345);
    uint32_t t = 0;
    int bad = 0, checks = 0;
    while (t < 59000) {
        uint32_t step = 1 + (uint32_t)(rand() % 700);
        /* advance millisecond by millisecond, recording what is driven during [t, t + 1) */
        for (uint32_t k = 0; k < step; k++) {
            at(t);
            hist[t] = wtcu_tactors_on();
            t++;
        }
        at(t);
        heartbeat();
        uint16_t mask = (uint16_t)(rand() & 0x0F);
        uint16_t ms = (uint16_t)(1 + rand() % 2000);
        fire(mask, ms);
        for (uint8_t tac = 0; tac < 4; tac++) {
            uint32_t exact10 = 0, exact105 = 0;
            for (uint32_t k = (t > 10500 ? t - 10500 : 0); k < t; k++) {
                if (hist[k] & (1u << tac)) {
                    exact105++;
                    if (k + 10000 >= t) {
                        exact10++;
                    }
                }
            }
            uint16_t spent = wtcu_duty_spent_ms(tac, t);
            checks++;
            if (spent < exact10 || spent > exact105) {
                if (bad < 5) {
                    printf("  t=%u tactor %u: ledger %u, exact 10 s %u, 10.5 s %u\n", t, tac, spent, exact10,
                           exact105);
                }
                bad++;
            }
        }
    }
    check(bad == 0, "duty ledger within [exact 10 s, exact 10.5 s] on %d random checks (%d off)", checks, bad);
}

int main(void)
{
    test_vectors_codec();
    test_vectors_unit();
    test_limits();
    test_session();
    test_line();
    test_queue();
    test_heading();
    test_gps();
    test_duty_property();
    printf("%d passed, %d failed\n", passed, failed);
    return failed ? 1 : 0;
}
