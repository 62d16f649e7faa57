/* WTCU protocol core (see core.h). Written from docs/wtcu-protocol.md.
 *
 * Time: every instant is a uint32_t millisecond count; comparisons use the wrapping difference, so the
 * clock may wrap (after 49 days) as long as no two compared instants are more than 24 days apart. */
#include "core.h"
#include "proto.h"

#include <string.h>

#ifndef WTCU_HAS_HEADING
#define WTCU_HAS_HEADING 1
#endif
#if WTCU_HAS_HEADING
#include "heading.h"
#endif

/* Message types */
enum {
    T_HELLO = 0x01,
    T_HEARTBEAT = 0x02,
    T_FIRE = 0x03,
    T_PLAY = 0x04,
    T_SET_INTENSITY = 0x05,
    T_STOP_ALL = 0x06,
    T_GET_STATUS = 0x07,
    T_HEADING_START = 0x08,
    T_HEADING_STOP = 0x09,
    T_SET_CALIBRATION = 0x0A,
    T_GPS_START = 0x0B,
    T_GPS_STOP = 0x0C,
    T_IDENTIFY = 0x81,
    T_ACK = 0x82,
    T_NAK = 0x83,
    T_STATUS = 0x84,
    T_REPORT = 0x85,
    T_HEADING = 0x86,
    T_GPS_DATA = 0x87,
};

/* NAK reasons */
enum {
    NAK_CRC = 0x01,
    NAK_UNKNOWN = 0x02,
    NAK_MALFORMED = 0x03,
    NAK_VERSION = 0x04,
    NAK_ON_TIME = 0x05,
    NAK_TOO_MANY = 0x06,
    NAK_DUTY = 0x07,
    NAK_PATTERN = 0x08,
    NAK_UNSUPPORTED = 0x09,
    NAK_NO_HELLO = 0x0A,
};

/* Outgoing frame kinds, in the order they are dropped when the queue is full (answers last). */
enum { K_ANSWER = 0, K_REPORT = 1, K_GPS = 2, K_HEADING = 3 };

#define OUT_INLINE 17u /* largest payload other than GPS_DATA: IDENTIFY */

struct out_entry {
    uint8_t kind;
    uint8_t version;
    uint8_t type;
    uint8_t seq;
    uint8_t len;
    uint8_t data[OUT_INLINE]; /* GPS_DATA: data[0] is the slot index */
};

enum { S_IDLE = 0, S_FIRE, S_PATTERN };

static struct {
    struct wtcu_features feat;
    uint8_t identified;
    uint8_t session_version;

    /* receiver */
    uint8_t rx[WTCU_MAX_WIRE_BODY];
    uint8_t rx_len;
    uint8_t rx_skip; /* dropping an over-long frame up to the next delimiter */
    uint32_t garbage;

    /* the last request handled (a retransmission is answered again, not run again) */
    uint8_t last_valid;
    uint8_t last_seq;
    uint8_t last_type;
    uint8_t last_len;
    uint16_t last_crc;
    uint8_t last_reply; /* T_ACK, T_NAK, T_STATUS */
    uint8_t last_nak;

    /* what runs */
    uint8_t sched;
    uint16_t on;
    uint32_t next_at; /* fire end or next pattern step */
    uint8_t pat_count;
    uint8_t pat_repeats;
    uint8_t pat_idx;
    uint8_t pat_pass;
    uint16_t pat_mask[WTCU_MAX_PATTERN_FRAMES];
    uint16_t pat_ms[WTCU_MAX_PATTERN_FRAMES];

    /* runs: start of the current run (or of the run that ended at run_end) */
    uint32_t run_start[WTCU_TACTORS];
    uint32_t run_end[WTCU_TACTORS];
    uint16_t run_ended; /* bit t: run_end[t] is valid */

    /* duty ledger (core.h) */
    uint32_t seg_start;
    uint32_t bucket_end; /* end of the current bucket (a multiple of 500 ms) */
    uint8_t slot;        /* where the current bucket goes when it closes */
    uint16_t cur_ms[WTCU_TACTORS];
    uint16_t win_ms[WTCU_TACTORS]; /* sum of the 20 closed buckets */
    uint8_t hist[WTCU_DUTY_BUCKETS][WTCU_TACTORS]; /* on-time / 2 (floor) */
    uint16_t hist_odd[WTCU_DUTY_BUCKETS];          /* bit t: on-time was odd: 2 * hist + odd is exact */

    /* protocol watchdog */
    uint32_t last_rx;
    uint8_t wd_tripped;

    uint8_t faults;
    uint8_t intensity[WTCU_TACTORS];
    uint8_t report_seq;

#if WTCU_HAS_HEADING
    uint8_t hd_rate;
    uint32_t hd_next;
    struct wtcu_calib calib;
#endif

#if WTCU_GPS_SLOTS > 0
    uint8_t gps_on;
    uint8_t gps_len;
    uint32_t gps_first;
    uint16_t gps_lost;
    uint8_t gps_buf[WTCU_GPS_CHUNK];
    uint8_t gps_slot_used;
    uint8_t gps_slot[WTCU_GPS_SLOTS][2u + WTCU_GPS_CHUNK];
#endif

    struct out_entry outq[WTCU_OUTQ_LEN];
    uint8_t outq_n;
    uint32_t dropped;
} u;

static uint8_t reached(uint32_t now, uint32_t at) { return (int32_t)(now - at) >= 0; }

static uint8_t popcount16(uint16_t m)
{
    uint8_t n = 0;
    while (m) {
        m &= (uint16_t)(m - 1u);
        n++;
    }
    return n;
}

/* ---------------------------------------------------------------- outgoing queue */

static void outq_remove(uint8_t i)
{
#if WTCU_GPS_SLOTS > 0
    if (u.outq[i].kind == K_GPS) {
        u.gps_slot_used &= (uint8_t)~(1u << u.outq[i].data[0]);
    }
#endif
    memmove(&u.outq[i], &u.outq[i + 1], (size_t)(u.outq_n - i - 1u) * sizeof(struct out_entry));
    u.outq_n--;
}

static void outq_push(uint8_t kind, uint8_t type, uint8_t seq, uint8_t version, const uint8_t *data,
                      uint8_t len)
{
    if (kind == K_REPORT || kind == K_HEADING) {
        /* An unsent REPORT / HEADING carries nothing the newer one does not: replaced in its place. */
        for (int8_t i = (int8_t)u.outq_n - 1; i >= 0; i--) {
            struct out_entry *e = &u.outq[i];
            if (e->kind == kind) {
                e->seq = seq;
                e->version = version;
                e->len = len;
                memcpy(e->data, data, len);
                return;
            }
        }
    }
    if (u.outq_n >= WTCU_OUTQ_LEN) {
        uint8_t victim = 0;
        static const uint8_t order[3] = {K_HEADING, K_GPS, K_REPORT};
        for (uint8_t k = 0; k < 3; k++) {
            uint8_t found = 0;
            for (uint8_t i = 0; i < u.outq_n; i++) {
                if (u.outq[i].kind == order[k]) {
                    victim = i;
                    found = 1;
                    break;
                }
            }
            if (found) {
                break;
            }
        }
#if WTCU_GPS_SLOTS > 0
        if (u.outq[victim].kind == K_GPS) {
            /* Its bytes and the losses it reported are lost: counted in the next GPS_DATA. */
            const uint8_t *p = u.gps_slot[u.outq[victim].data[0]];
            uint32_t lost = (uint32_t)u.gps_lost + wtcu_le16(p) + (uint32_t)(u.outq[victim].len - 2u);
            u.gps_lost = lost > 0xFFFFu ? 0xFFFFu : (uint16_t)lost;
        }
#endif
        outq_remove(victim);
        u.dropped++;
    }
    struct out_entry *e = &u.outq[u.outq_n++];
    e->kind = kind;
    e->type = type;
    e->seq = seq;
    e->version = version;
    e->len = len;
    memcpy(e->data, data, kind == K_GPS ? 1u : len);
}

uint16_t wtcu_next_frame(uint8_t *buf, uint16_t room)
{
    if (u.outq_n == 0) {
        return 0;
    }
    struct out_entry *e = &u.outq[0];
    if (room < (uint16_t)(e->len + 9u)) {
        return 0;
    }
    const uint8_t *payload = e->data;
#if WTCU_GPS_SLOTS > 0
    if (e->kind == K_GPS) {
        payload = u.gps_slot[e->data[0]];
    }
#endif
    uint16_t n = wtcu_build_frame(e->version, e->type, e->seq, payload, e->len, buf);
    outq_remove(0);
    return n;
}

uint8_t wtcu_queue_count(void) { return u.outq_n; }

/* Replies go in the session's version; before any HELLO in the request's own (1 or 2). */
static uint8_t reply_version(uint8_t request_version)
{
    if (u.identified) {
        return u.session_version;
    }
    return (request_version == 1 || request_version == 2) ? request_version : 1;
}

static void answer(uint8_t rv, uint8_t seq, uint8_t type, const uint8_t *data, uint8_t len)
{
    outq_push(K_ANSWER, type, seq, reply_version(rv), data, len);
}

static void send_ack(uint8_t rv, uint8_t seq)
{
    uint8_t p[2];
    wtcu_put16(p, u.on);
    answer(rv, seq, T_ACK, p, 2);
}

static void send_nak(uint8_t rv, uint8_t seq, uint8_t reason)
{
    uint8_t p[3];
    p[0] = reason;
    wtcu_put16(p + 1, u.on);
    answer(rv, seq, T_NAK, p, 3);
}

static void send_report(void)
{
    uint8_t p[3];
    wtcu_put16(p, u.on);
    p[2] = u.faults;
    u.report_seq++;
    outq_push(K_REPORT, T_REPORT, u.report_seq, u.identified ? u.session_version : 1, p, 3);
}

/* ---------------------------------------------------------------- duty ledger */

/* Closes buckets until `t` lies in the current one. No division on the usual path: this runs inside
 * every FIRE/PLAY check, between the frame's arrival and its pins switching on. */
static void duty_advance(uint32_t t)
{
    if ((int32_t)(t - u.bucket_end) >= (int32_t)(WTCU_DUTY_BUCKETS * WTCU_DUTY_BUCKET_MS)) {
        /* Everything booked has left the window. */
        memset(u.hist, 0, sizeof u.hist);
        memset(u.hist_odd, 0, sizeof u.hist_odd);
        memset(u.cur_ms, 0, sizeof u.cur_ms);
        memset(u.win_ms, 0, sizeof u.win_ms);
        u.bucket_end += ((t - u.bucket_end) / WTCU_DUTY_BUCKET_MS + 1u) * WTCU_DUTY_BUCKET_MS;
        return;
    }
    while (reached(t, u.bucket_end)) {
        uint8_t b = u.slot;
        uint16_t odd = 0;
        uint16_t bit = 1;
        for (uint8_t k = 0; k < WTCU_TACTORS; k++, bit = (uint16_t)(bit << 1)) {
            /* The slot's oldest bucket leaves the window, the closing one enters it. */
            uint16_t old = (uint16_t)(2u * u.hist[b][k] + ((u.hist_odd[b] & bit) ? 1u : 0u));
            u.win_ms[k] = (uint16_t)(u.win_ms[k] - old + u.cur_ms[k]);
            u.hist[b][k] = (uint8_t)(u.cur_ms[k] / 2u);
            if (u.cur_ms[k] & 1u) {
                odd |= bit;
            }
            u.cur_ms[k] = 0;
        }
        u.hist_odd[b] = odd;
        u.slot = (uint8_t)((b + 1u == WTCU_DUTY_BUCKETS) ? 0u : b + 1u);
        u.bucket_end += WTCU_DUTY_BUCKET_MS;
    }
}

/* Books `mask`, driven from u.seg_start to `to`, and moves the segment start to `to`. */
static void duty_book(uint16_t mask, uint32_t to)
{
    uint32_t from = u.seg_start;
    while (mask && (int32_t)(to - from) > 0) {
        uint32_t stop = ((int32_t)(to - u.bucket_end) < 0) ? to : u.bucket_end;
        uint16_t chunk = (uint16_t)(stop - from);
        uint16_t bit = 1;
        for (uint8_t t = 0; t < WTCU_TACTORS; t++, bit = (uint16_t)(bit << 1)) {
            if (mask & bit) {
                u.cur_ms[t] += chunk;
            }
        }
        from = stop;
        duty_advance(from);
    }
    duty_advance(to);
    u.seg_start = to;
}

/* On-time booked in the current bucket and the 20 before it (call duty_book first). */
static uint16_t duty_spent(uint8_t t) { return (uint16_t)(u.win_ms[t] + u.cur_ms[t]); }

uint16_t wtcu_duty_spent_ms(uint8_t tactor, uint32_t now)
{
    duty_book(u.on, now);
    return duty_spent(tactor);
}

/* ---------------------------------------------------------------- what is driven */

static void publish(void)
{
    struct wtcu_plan p;
    p.on = u.on;
    p.has_next = 0;
    p.next_mask = 0;
    p.next_at = 0;
    if (u.sched == S_FIRE) {
        p.has_next = 1;
        p.next_at = u.next_at;
        p.next_mask = 0;
    } else if (u.sched == S_PATTERN) {
        p.has_next = 1;
        p.next_at = u.next_at;
        uint8_t i = (uint8_t)(u.pat_idx + 1u);
        if (i < u.pat_count) {
            p.next_mask = u.pat_mask[i];
        } else if ((uint8_t)(u.pat_pass + 1u) < u.pat_repeats) {
            p.next_mask = u.pat_mask[0];
        }
    }
    p.wd_armed = (u.identified && !u.wd_tripped) ? 1 : 0;
    p.wd_at = u.last_rx + WTCU_WATCHDOG_MS;
    wtcu_hw_publish(&p);
}

/* The driven set becomes `mask` at `at`: books the duty ledger and the runs. */
static uint8_t set_on(uint16_t mask, uint32_t at)
{
    if (mask == u.on) {
        return 0;
    }
    duty_book(u.on, at);
    uint16_t bit = 1;
    for (uint8_t t = 0; t < WTCU_TACTORS; t++, bit = (uint16_t)(bit << 1)) {
        if ((mask & bit) && !(u.on & bit)) {
            /* Switched on at the instant its last run ended: the same run goes on. */
            if (!((u.run_ended & bit) && u.run_end[t] == at)) {
                u.run_start[t] = at;
            }
        } else if (!(mask & bit) && (u.on & bit)) {
            u.run_end[t] = at;
            u.run_ended |= bit;
        }
    }
    u.on = mask;
    return 1;
}

/* Start of the run a command switching tactor t on at `now` would continue, if any. */
static uint8_t run_start_of(uint8_t t, uint32_t now, uint32_t *start)
{
    uint16_t bit = (uint16_t)(1u << t);
    if ((u.on & bit) || ((u.run_ended & bit) && u.run_end[t] == now)) {
        *start = u.run_start[t];
        return 1;
    }
    return 0;
}

static void stop_everything(uint32_t now)
{
    u.sched = S_IDLE;
    set_on(0, now);
}

/* ---------------------------------------------------------------- clock */

static void watchdog_trip(uint32_t at)
{
    u.wd_tripped = 1;
    u.faults |= WTCU_FAULT_WATCHDOG;
    stop_everything(at);
    send_report();
}

static void step(uint32_t at)
{
    uint16_t mask = 0;
    if (u.sched == S_PATTERN) {
        u.pat_idx++;
        if (u.pat_idx >= u.pat_count) {
            u.pat_idx = 0;
            u.pat_pass++;
        }
        if (u.pat_pass >= u.pat_repeats) {
            u.sched = S_IDLE;
        } else {
            mask = u.pat_mask[u.pat_idx];
            u.next_at = at + u.pat_ms[u.pat_idx];
        }
    } else {
        u.sched = S_IDLE;
    }
    if (set_on(mask, at)) {
        send_report();
    }
}

#if WTCU_GPS_SLOTS > 0
static void gps_flush(void);
#endif

void wtcu_poll(uint32_t now)
{
    uint8_t changed = 0;
    for (;;) {
        uint8_t have_c = (u.sched != S_IDLE) && reached(now, u.next_at);
        uint8_t have_w = u.identified && !u.wd_tripped && reached(now, u.last_rx + WTCU_WATCHDOG_MS);
        if (have_w && (!have_c || reached(u.next_at, u.last_rx + WTCU_WATCHDOG_MS))) {
            watchdog_trip(u.last_rx + WTCU_WATCHDOG_MS);
        } else if (have_c) {
            step(u.next_at);
        } else {
            break;
        }
        changed = 1;
    }
    if (changed) {
        publish();
    }
#if WTCU_GPS_SLOTS > 0
    if (u.gps_len && reached(now, u.gps_first + WTCU_GPS_IDLE_MS)) {
        gps_flush();
    }
#endif
}

/* ---------------------------------------------------------------- commands */

static uint8_t battery_pct(uint16_t mv)
{
    if (mv <= 3300u) {
        return 0;
    }
    if (mv >= 4200u) {
        return 100;
    }
    return (uint8_t)(((uint32_t)(mv - 3300u) * 100u + 450u) / 900u);
}

static void send_status(uint8_t rv, uint8_t seq, uint8_t clear)
{
    uint16_t mv = wtcu_hw_battery_mv();
    uint8_t faults = u.faults;
    if (mv < WTCU_LOW_BATTERY_MV) {
        faults |= WTCU_FAULT_LOW_BATTERY;
    }
    uint8_t p[9];
    wtcu_put16(p, mv);
    p[2] = battery_pct(mv);
    wtcu_put16(p + 3, u.on);
    p[5] = faults;
    p[6] = WTCU_FW_MAJOR;
    p[7] = WTCU_FW_MINOR;
    p[8] = WTCU_FW_PATCH;
    if (clear) {
        u.faults = 0;
    }
    answer(rv, seq, T_STATUS, p, 9);
}

static void send_identify(uint8_t rv, uint8_t seq)
{
    uint8_t caps = WTCU_CAP_INTENSITY | WTCU_CAP_PATTERNS;
    if (u.session_version >= 2) {
        if (u.feat.heading) {
            caps |= WTCU_CAP_HEADING;
        }
        if (u.feat.gps) {
            caps |= WTCU_CAP_GPS;
        }
    }
    uint8_t p[17];
    p[0] = WTCU_FW_MAJOR;
    p[1] = WTCU_FW_MINOR;
    p[2] = WTCU_FW_PATCH;
    p[3] = WTCU_TACTORS;
    p[4] = caps;
    wtcu_put16(p + 5, WTCU_MAX_ON_MS);
    p[7] = WTCU_MAX_SIMULTANEOUS;
    wtcu_put16(p + 8, WTCU_DUTY_WINDOW_MS);
    wtcu_put16(p + 10, WTCU_MAX_DUTY_ON_MS);
    p[12] = WTCU_MAX_PATTERN_FRAMES;
    wtcu_put16(p + 13, WTCU_MAX_PATTERN_MS);
    wtcu_put16(p + 15, WTCU_WATCHDOG_MS);
    answer(rv, seq, T_IDENTIFY, p, 17);
}

/* Both run checks and the duty check for a command driving tactor t for `leading` ms from now on
 * without a break, `planned` ms in all. Returns 0 or a NAK reason. */
static uint8_t check_runs(const uint16_t *leading, uint32_t now)
{
    for (uint8_t t = 0; t < WTCU_TACTORS; t++) {
        uint32_t start;
        if (leading[t] && run_start_of(t, now, &start)) {
            if ((now - start) + leading[t] > WTCU_MAX_ON_MS) {
                return NAK_ON_TIME;
            }
        }
    }
    return 0;
}

static uint8_t check_duty(const uint16_t *planned, uint32_t now)
{
    duty_book(u.on, now);
    for (uint8_t t = 0; t < WTCU_TACTORS; t++) {
        if (planned[t] && (uint32_t)duty_spent(t) + planned[t] > WTCU_MAX_DUTY_ON_MS) {
            return NAK_DUTY;
        }
    }
    return 0;
}

static uint8_t do_fire(const uint8_t *p, uint32_t now)
{
    uint16_t mask = wtcu_le16(p);
    uint16_t ms = wtcu_le16(p + 2);
    if (mask == 0) {
        stop_everything(now);
        return 0;
    }
    if (ms == 0 || ms > WTCU_MAX_ON_MS) {
        return NAK_ON_TIME;
    }
    if (popcount16(mask) > WTCU_MAX_SIMULTANEOUS) {
        return NAK_TOO_MANY;
    }
    uint16_t plan[WTCU_TACTORS];
    uint16_t bit = 1;
    for (uint8_t t = 0; t < WTCU_TACTORS; t++, bit = (uint16_t)(bit << 1)) {
        plan[t] = (mask & bit) ? ms : 0;
    }
    uint8_t r = check_runs(plan, now);
    if (!r) {
        r = check_duty(plan, now);
    }
    if (r) {
        return r;
    }
    u.sched = S_FIRE;
    u.next_at = now + ms;
    set_on(mask, now);
    return 0;
}

static uint8_t do_play(const uint8_t *p, uint8_t len, uint32_t now)
{
    uint8_t repeats = p[0];
    uint8_t count = p[1];
    (void)len;
    if (count == 0 || repeats == 0 || count > WTCU_MAX_PATTERN_FRAMES) {
        return NAK_PATTERN;
    }
    uint32_t once = 0;
    for (uint8_t i = 0; i < count; i++) {
        uint16_t ms = wtcu_le16(p + 2 + 4 * i + 2);
        if (ms == 0) {
            return NAK_ON_TIME;
        }
        once += ms;
    }
    if (once * repeats > WTCU_MAX_PATTERN_MS) {
        return NAK_PATTERN;
    }
    for (uint8_t i = 0; i < count; i++) {
        if (popcount16(wtcu_le16(p + 2 + 4 * i)) > WTCU_MAX_SIMULTANEOUS) {
            return NAK_TOO_MANY;
        }
    }
    /* Per tactor: longest run over the whole played pattern (closed form), leading run, total on-time. */
    uint16_t leading[WTCU_TACTORS];
    uint16_t planned[WTCU_TACTORS];
    uint16_t bit = 1;
    for (uint8_t t = 0; t < WTCU_TACTORS; t++, bit = (uint16_t)(bit << 1)) {
        uint32_t run = 0, longest = 0, total = 0, lead = 0;
        uint8_t in_all = 1, leading_open = 1;
        for (uint8_t i = 0; i < count; i++) {
            uint16_t mask = wtcu_le16(p + 2 + 4 * i);
            uint16_t ms = wtcu_le16(p + 2 + 4 * i + 2);
            if (mask & bit) {
                run += ms;
                total += ms;
                if (leading_open) {
                    lead += ms;
                }
            } else {
                run = 0;
                in_all = 0;
                leading_open = 0;
            }
            if (run > longest) {
                longest = run;
            }
        }
        /* `run` is now the trailing run S. */
        uint32_t lead_cmd;
        if (in_all) {
            longest = once * repeats;
            lead_cmd = longest;
        } else {
            if (repeats >= 2 && run + lead > longest) {
                longest = run + lead;
            }
            lead_cmd = lead;
        }
        if (longest > WTCU_MAX_ON_MS) {
            return NAK_ON_TIME;
        }
        leading[t] = (uint16_t)lead_cmd;
        planned[t] = (uint16_t)(total * repeats);
    }
    uint8_t r = check_runs(leading, now);
    if (!r) {
        r = check_duty(planned, now);
    }
    if (r) {
        return r;
    }
    for (uint8_t i = 0; i < count; i++) {
        u.pat_mask[i] = wtcu_le16(p + 2 + 4 * i);
        u.pat_ms[i] = wtcu_le16(p + 2 + 4 * i + 2);
    }
    u.pat_count = count;
    u.pat_repeats = repeats;
    u.pat_idx = 0;
    u.pat_pass = 0;
    u.sched = S_PATTERN;
    u.next_at = now + u.pat_ms[0];
    set_on(u.pat_mask[0], now);
    return 0;
}

static void gps_stop(void)
{
#if WTCU_GPS_SLOTS > 0
    if (u.gps_on) {
        wtcu_hw_gps_close();
    }
    u.gps_on = 0;
    u.gps_len = 0;
    u.gps_lost = 0;
#endif
}

/* Expected payload length of a request type in a header of `version`: -1 unknown, -2 variable (PLAY). */
static int16_t request_len(uint8_t version, uint8_t type)
{
    switch (type) {
    case T_HELLO:
    case T_HEARTBEAT:
    case T_STOP_ALL:
    case T_GET_STATUS:
        return 0;
    case T_FIRE:
        return 4;
    case T_PLAY:
        return -2;
    case T_SET_INTENSITY:
        return 3;
    default:
        break;
    }
    if (version >= 2) {
        switch (type) {
        case T_HEADING_START:
            return 1;
        case T_HEADING_STOP:
        case T_GPS_STOP:
            return 0;
        case T_SET_CALIBRATION:
            return 26;
        case T_GPS_START:
            return 4;
        default:
            break;
        }
    }
    return -1;
}

static void handle_packet(uint8_t *pkt, uint8_t n, uint32_t now)
{
    uint16_t crc = wtcu_le16(pkt + n - 2);
    if (wtcu_crc16(pkt, (uint16_t)(n - 2u)) != crc || pkt[3] != n - 6u) {
        u.faults |= WTCU_FAULT_LINE;
        send_nak(1, 0, NAK_CRC);
        return;
    }
    uint8_t version = pkt[0];
    uint8_t type = pkt[1];
    uint8_t seq = pkt[2];
    uint8_t len = pkt[3];
    const uint8_t *p = pkt + 4;
    if (version != 1 && version != 2) {
        send_nak(1, seq, NAK_VERSION);
        return;
    }
    int16_t want = request_len(version, type);
    if (want == -1) {
        send_nak(version, seq, NAK_UNKNOWN);
        return;
    }
    if ((want >= 0 && len != want) || (want == -2 && (len < 2 || len != 2u + 4u * p[1]))) {
        send_nak(version, seq, NAK_MALFORMED);
        return;
    }

    /* A well-formed request: it feeds the watchdog (and re-arms it after a trip). */
    u.last_rx = now;
    u.wd_tripped = 0;

    if (type != T_HELLO && u.last_valid && u.last_seq == seq && u.last_type == type && u.last_len == len &&
        u.last_crc == crc) {
        /* A retransmission (our answer was lost): answered again with the state of now, not run again. */
        if (u.last_reply == T_STATUS) {
            send_status(version, seq, 0);
        } else if (u.last_reply == T_NAK) {
            send_nak(version, seq, u.last_nak);
        } else {
            send_ack(version, seq);
        }
        publish();
        return;
    }

    uint8_t nak = 0;
    uint8_t reply = T_ACK;
    if (type == T_HELLO) {
        /* A new session: the previous console is gone, nothing keeps running. */
        u.identified = 1;
        u.session_version = version;
        u.last_valid = 0;
        stop_everything(now);
#if WTCU_HAS_HEADING
        u.hd_rate = 0;
#endif
        gps_stop();
        publish();
        send_identify(version, seq);
        return;
    }
    if (!u.identified) {
        nak = NAK_NO_HELLO;
    } else {
        switch (type) {
        case T_HEARTBEAT:
            break;
        case T_STOP_ALL:
            /* Outputs are cleared (published to the tick ISR, which writes the pins at once) before the
             * ACK is queued. */
            stop_everything(now);
            break;
        case T_FIRE:
            nak = do_fire(p, now);
            break;
        case T_PLAY:
            nak = do_play(p, len, now);
            break;
        case T_SET_INTENSITY: {
            uint16_t mask = wtcu_le16(p);
            for (uint8_t t = 0; t < WTCU_TACTORS; t++, mask >>= 1) {
                if (mask & 1u) {
                    u.intensity[t] = p[2];
                }
            }
            wtcu_hw_intensity(u.intensity);
            break;
        }
        case T_GET_STATUS:
            reply = T_STATUS;
            break;
        case T_HEADING_START:
#if WTCU_HAS_HEADING
            if (!u.feat.heading) {
                nak = NAK_UNSUPPORTED;
            } else if (p[0] < 1 || p[0] > 10) {
                nak = NAK_MALFORMED;
            } else {
                u.hd_rate = p[0];
                u.hd_next = now;
            }
#else
            nak = NAK_UNSUPPORTED;
#endif
            break;
        case T_HEADING_STOP:
#if WTCU_HAS_HEADING
            u.hd_rate = 0;
#endif
            break;
        case T_SET_CALIBRATION:
#if WTCU_HAS_HEADING
            if (!u.feat.heading) {
                nak = NAK_UNSUPPORTED;
            } else if (wtcu_calib_from_wire(p, &u.calib) != 0) {
                nak = NAK_MALFORMED;
            }
#else
            nak = NAK_UNSUPPORTED;
#endif
            break;
        case T_GPS_START: {
#if WTCU_GPS_SLOTS > 0
            uint32_t baud = (uint32_t)wtcu_le16(p) | ((uint32_t)wtcu_le16(p + 2) << 16);
            if (!u.feat.gps) {
                nak = NAK_UNSUPPORTED;
            } else if (baud != 4800 && baud != 9600 && baud != 19200 && baud != 38400 && baud != 57600 &&
                       baud != 115200) {
                nak = NAK_MALFORMED;
            } else {
                wtcu_hw_gps_open(baud);
                u.gps_on = 1;
            }
#else
            nak = NAK_UNSUPPORTED;
#endif
            break;
        }
        case T_GPS_STOP:
            gps_stop();
            break;
        default:
            nak = NAK_UNKNOWN;
            break;
        }
    }
    if (nak == NAK_ON_TIME || nak == NAK_TOO_MANY || nak == NAK_DUTY || nak == NAK_PATTERN) {
        u.faults |= WTCU_FAULT_LIMIT;
    }
    publish();
    if (nak) {
        send_nak(version, seq, nak);
        reply = T_NAK;
    } else if (reply == T_STATUS) {
        send_status(version, seq, 1);
    } else {
        send_ack(version, seq);
    }
    u.last_valid = 1;
    u.last_seq = seq;
    u.last_type = type;
    u.last_len = len;
    u.last_crc = crc;
    u.last_reply = reply;
    u.last_nak = nak;
}

static void garbage(void)
{
    u.garbage++;
    u.faults |= WTCU_FAULT_LINE;
}

void wtcu_line_error(void) { garbage(); }

void wtcu_rx_byte(uint8_t byte, uint32_t now)
{
    if (byte == 0) {
        if (!u.rx_skip && u.rx_len) {
            /* Everything due before this frame arrived happens first, at its own instant. */
            wtcu_poll(now);
            int16_t n = wtcu_cobs_decode(u.rx, u.rx_len, u.rx);
            if (n < 6) {
                garbage();
            } else {
                handle_packet(u.rx, (uint8_t)n, now);
            }
        }
        u.rx_len = 0;
        u.rx_skip = 0;
        return;
    }
    if (u.rx_skip) {
        return;
    }
    if (u.rx_len >= WTCU_MAX_WIRE_BODY) {
        garbage();
        u.rx_skip = 1;
        u.rx_len = 0;
        return;
    }
    u.rx[u.rx_len++] = byte;
}

/* ---------------------------------------------------------------- GPS */

#if WTCU_GPS_SLOTS > 0
static void gps_flush(void)
{
    uint8_t slot = 0xFF;
    for (uint8_t s = 0; s < WTCU_GPS_SLOTS; s++) {
        if (!(u.gps_slot_used & (1u << s))) {
            slot = s;
            break;
        }
    }
    if (slot == 0xFF) {
        uint32_t lost = (uint32_t)u.gps_lost + u.gps_len;
        u.gps_lost = lost > 0xFFFFu ? 0xFFFFu : (uint16_t)lost;
    } else {
        uint8_t *d = u.gps_slot[slot];
        wtcu_put16(d, u.gps_lost);
        memcpy(d + 2, u.gps_buf, u.gps_len);
        u.gps_lost = 0;
        u.gps_slot_used |= (uint8_t)(1u << slot);
        u.report_seq++;
        outq_push(K_GPS, T_GPS_DATA, u.report_seq, u.session_version, &slot, (uint8_t)(2u + u.gps_len));
    }
    u.gps_len = 0;
}
#endif

void wtcu_gps_byte(uint8_t byte, uint32_t now)
{
#if WTCU_GPS_SLOTS > 0
    if (!u.gps_on) {
        return;
    }
    if (u.gps_len == 0) {
        u.gps_first = now;
    }
    u.gps_buf[u.gps_len++] = byte;
    if (byte == 0x0A || u.gps_len >= WTCU_GPS_CHUNK) {
        gps_flush();
    }
#else
    (void)byte;
    (void)now;
#endif
}

void wtcu_gps_lost(uint16_t count)
{
#if WTCU_GPS_SLOTS > 0
    if (!u.gps_on) {
        return;
    }
    uint32_t lost = (uint32_t)u.gps_lost + count;
    u.gps_lost = lost > 0xFFFFu ? 0xFFFFu : (uint16_t)lost;
#else
    (void)count;
#endif
}

/* ---------------------------------------------------------------- HEADING */

uint8_t wtcu_heading_due(uint32_t now)
{
#if WTCU_HAS_HEADING
    if (!u.hd_rate || !reached(now, u.hd_next)) {
        return 0;
    }
    uint32_t period = 1000u / u.hd_rate;
    uint32_t behind = (now - u.hd_next) / period;
    u.hd_next += (behind + 1u) * period;
    return 1;
#else
    (void)now;
    return 0;
#endif
}

void wtcu_heading_sample(const int16_t mag_raw[3], const int16_t accel_mg[3], uint8_t ok)
{
#if WTCU_HAS_HEADING
    if (!ok) {
        return;
    }
    float m[3];
    float a[3];
    for (uint8_t i = 0; i < 3; i++) {
        m[i] = (float)mag_raw[i] * 0.15f;
        a[i] = (float)accel_mg[i] * 0.001f;
    }
    uint8_t p[WTCU_HEADING_PAYLOAD_LEN];
    if (!wtcu_heading_payload(m, a, &u.calib, p)) {
        return;
    }
    u.report_seq++;
    outq_push(K_HEADING, T_HEADING, u.report_seq, u.session_version, p, WTCU_HEADING_PAYLOAD_LEN);
#else
    (void)mag_raw;
    (void)accel_mg;
    (void)ok;
#endif
}

/* ---------------------------------------------------------------- init / introspection */

void wtcu_init(const struct wtcu_features *features, uint32_t now)
{
    memset(&u, 0, sizeof u);
    u.feat = *features;
#if WTCU_GPS_SLOTS == 0
    u.feat.gps = 0;
#endif
#if !WTCU_HAS_HEADING
    u.feat.heading = 0;
#else
    wtcu_calib_identity(&u.calib);
#endif
    u.session_version = 1;
    memset(u.intensity, 255, sizeof u.intensity);
    u.seg_start = now;
    u.bucket_end = (now / WTCU_DUTY_BUCKET_MS + 1u) * WTCU_DUTY_BUCKET_MS;
    wtcu_hw_intensity(u.intensity);
    publish();
}

uint16_t wtcu_tactors_on(void) { return u.on; }
uint8_t wtcu_faults(void) { return u.faults; }
uint8_t wtcu_session_version(void) { return u.session_version; }
uint32_t wtcu_dropped_frames(void) { return u.dropped; }
uint32_t wtcu_garbage_frames(void) { return u.garbage; }
