/* WTCU protocol core: sessions, commands, safety limits, schedule, duty ledger, outgoing queue, GPS
 * chunking, HEADING pacing. Hardware-independent: time is a millisecond count passed in by the caller
 * (the board's 1 ms timer tick, or a simulated clock in test/host_test.c). Single instance, static state. */
#ifndef WTCU_CORE_H
#define WTCU_CORE_H

#include <stdint.h>

#define WTCU_TACTORS 16u

/* Firmware version reported in IDENTIFY and STATUS. */
#define WTCU_FW_MAJOR 1u
#define WTCU_FW_MINOR 0u
#define WTCU_FW_PATCH 0u

/* Safety limits (docs/wtcu-protocol.md, "Safety"); reported in IDENTIFY. */
#define WTCU_MAX_ON_MS 2000u
#define WTCU_MAX_SIMULTANEOUS 8u
#define WTCU_DUTY_WINDOW_MS 10000u
#define WTCU_MAX_DUTY_ON_MS 5000u
#define WTCU_MAX_PATTERN_FRAMES 32u
#define WTCU_MAX_PATTERN_MS 10000u
#define WTCU_WATCHDOG_MS 1500u
#define WTCU_LOW_BATTERY_MV 3500u

/* Capability bits */
#define WTCU_CAP_INTENSITY 0x01u
#define WTCU_CAP_PATTERNS 0x02u
#define WTCU_CAP_HEADING 0x04u
#define WTCU_CAP_GPS 0x08u

/* Fault bits */
#define WTCU_FAULT_WATCHDOG 0x01u
#define WTCU_FAULT_LOW_BATTERY 0x02u
#define WTCU_FAULT_LIMIT 0x04u
#define WTCU_FAULT_LINE 0x08u

/* Outgoing queue bound in frames (spec: at most 64). The 328P build uses fewer (RAM, see README). */
#ifndef WTCU_OUTQ_LEN
#define WTCU_OUTQ_LEN 64u
#endif
/* GPS_DATA chunk buffers shared by the queue (0 = no GPS support compiled in). */
#ifndef WTCU_GPS_SLOTS
#define WTCU_GPS_SLOTS 6u
#endif
#define WTCU_GPS_CHUNK 64u
#define WTCU_GPS_IDLE_MS 50u

/* Duty-cycle ledger: per tactor, the exact on-time (ms) of the current 500 ms bucket and of the 20 buckets
 * before it (each stored as a byte of ms/2 plus one "odd" bit, 2.5 bytes per tactor and bucket). Buckets
 * are aligned to multiples of 500 ms of the unit clock. The sum over the current and the 20 closed buckets
 * covers the last 10 s plus the part of the oldest bucket before it (10 s to 10.5 s in all): the "on-time
 * in the last 10 s" the unit checks is never under-estimated, and over-estimated by at most the on-time
 * of 500 ms that just left the window. */
#define WTCU_DUTY_BUCKET_MS 500u
#define WTCU_DUTY_BUCKETS 20u

/* What the board's tick ISR drives, published by the core whenever it changes (see board.c). */
struct wtcu_plan {
    uint16_t on;        /* tactors driven now */
    uint16_t next_mask; /* driven from next_at on (if has_next) */
    uint32_t next_at;
    uint32_t wd_at;     /* the protocol watchdog's deadline (if wd_armed): everything off */
    uint8_t has_next;
    uint8_t wd_armed;
};

/* Board services the core calls (implemented in board.c, or by the host test). */
void wtcu_hw_publish(const struct wtcu_plan *plan);
void wtcu_hw_intensity(const uint8_t level[WTCU_TACTORS]);
uint16_t wtcu_hw_battery_mv(void);
void wtcu_hw_gps_open(uint32_t baud);
void wtcu_hw_gps_close(void);

/* Which optional hardware this unit has (fixed at boot). */
struct wtcu_features {
    uint8_t heading; /* magnetometer + accelerometer found */
    uint8_t gps;     /* a GPS UART exists */
};

void wtcu_init(const struct wtcu_features *features, uint32_t now);
/* One byte from the console link. Frames are handled as soon as their closing 0x00 arrives. */
void wtcu_rx_byte(uint8_t byte, uint32_t now);
/* A UART framing/overrun error or receive-buffer overflow on the console link. */
void wtcu_line_error(void);
/* Runs everything due at or before now, each at its own instant (steps, ends, watchdog, GPS flush). */
void wtcu_poll(uint32_t now);
/* Next outgoing frame, encoded with delimiters, if one is queued and fits in room bytes; 0 otherwise. */
uint16_t wtcu_next_frame(uint8_t *buf, uint16_t room);
uint8_t wtcu_queue_count(void);

/* GPS receiver bytes (the board's GPS UART ring), and bytes the board itself had to drop. */
void wtcu_gps_byte(uint8_t byte, uint32_t now);
void wtcu_gps_lost(uint16_t count);

/* HEADING pacing: returns 1 when a reading is due at or before now (the next one is then scheduled one
 * period after the latest due instant, so a late unit sends one reading, not a burst). The board then
 * reads the sensors and calls wtcu_heading_sample (ok = 0 when the read failed: nothing is sent). */
uint8_t wtcu_heading_due(uint32_t now);
/* mag_raw: LSM303AGR counts (1.5 mgauss = 0.15 uT each), accel_mg: milli-g; both body axes x fwd, y right,
 * z down. */
void wtcu_heading_sample(const int16_t mag_raw[3], const int16_t accel_mg[3], uint8_t ok);

/* Introspection for the board and the host test. */
uint16_t wtcu_tactors_on(void);
uint8_t wtcu_faults(void);
uint8_t wtcu_session_version(void);
uint32_t wtcu_dropped_frames(void);
uint32_t wtcu_garbage_frames(void);
uint16_t wtcu_duty_spent_ms(uint8_t tactor, uint32_t now);

#endif
