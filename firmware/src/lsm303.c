/* ST LSM303AGR over TWI (Mega: SDA D20, SCL D21), with a timeout on every bus wait: a missing or hung
 * sensor costs at most a few milliseconds per attempt and never blocks the tactor loop (the tick ISR
 * and its scheduled stops run regardless).
 *
 * Accelerometer 0x19: CTRL_REG1_A = 0x57 (100 Hz, X/Y/Z on), CTRL_REG4_A = 0x88 (block data update,
 * high resolution, +-2 g: 12-bit left-justified, ~1 mg per count after >> 4).
 * Magnetometer 0x1E: CFG_REG_A_M = 0x00 (continuous, 10 Hz, high resolution), CFG_REG_C_M = 0x10 (block
 * data update); OUTX_L_REG_M..OUTZ_H_REG_M little-endian i16, 1.5 mgauss = 0.15 uT per count.
 *
 * Mounting (docs/hardware.md): the breakout's printed X arrow points where the wearer faces and its Z
 * arrow points to the ground, so its (right-handed) Y points to the wearer's right: sensor axes are body
 * axes (x forward, y right, z down). Another mounting is one change in AXIS_MAP below. */
#include "board.h"

#if BOARD_HAS_SENSORS

#include <util/twi.h>

#define ACC_ADDR 0x19
#define MAG_ADDR 0x1E
#define WHO_AM_I_A 0x0F
#define CTRL_REG1_A 0x20
#define CTRL_REG4_A 0x23
#define OUT_X_L_A 0x28
#define WHO_AM_I_M 0x4F
#define CFG_REG_A_M 0x60
#define CFG_REG_C_M 0x62
#define OUTX_L_REG_M 0x68
#define AUTO_INCREMENT_A 0x80

/* Body axis i = sign * sensor axis index (identity for the documented mounting). */
#define AXIS_MAP(v, i) (v[i])

/* ~ 1.5 ms at 16 MHz: 100 bytes' time at 400 kHz. */
#define TWI_SPINS 4000u

static uint8_t twi_wait(void)
{
    for (uint16_t n = 0; n < TWI_SPINS; n++) {
        if (TWCR & (1 << TWINT)) {
            return 1;
        }
    }
    return 0;
}

static void twi_reset(void)
{
    TWCR = 0;
    TWCR = (1 << TWEN);
}

static uint8_t twi_start(uint8_t sla_rw)
{
    TWCR = (1 << TWINT) | (1 << TWSTA) | (1 << TWEN);
    if (!twi_wait()) {
        return 0;
    }
    uint8_t st = TW_STATUS;
    if (st != TW_START && st != TW_REP_START) {
        return 0;
    }
    TWDR = sla_rw;
    TWCR = (1 << TWINT) | (1 << TWEN);
    if (!twi_wait()) {
        return 0;
    }
    st = TW_STATUS;
    return st == TW_MT_SLA_ACK || st == TW_MR_SLA_ACK;
}

static uint8_t twi_write_byte(uint8_t b)
{
    TWDR = b;
    TWCR = (1 << TWINT) | (1 << TWEN);
    return twi_wait() && TW_STATUS == TW_MT_DATA_ACK;
}

static void twi_stop(void)
{
    TWCR = (1 << TWINT) | (1 << TWSTO) | (1 << TWEN);
    for (uint16_t n = 0; n < TWI_SPINS && (TWCR & (1 << TWSTO)); n++) {
    }
}

static uint8_t reg_write(uint8_t addr, uint8_t reg, uint8_t val)
{
    uint8_t ok = twi_start((uint8_t)(addr << 1)) && twi_write_byte(reg) && twi_write_byte(val);
    if (ok) {
        twi_stop();
    } else {
        twi_reset();
    }
    return ok;
}

static uint8_t reg_read(uint8_t addr, uint8_t reg, uint8_t *buf, uint8_t n)
{
    uint8_t ok = twi_start((uint8_t)(addr << 1)) && twi_write_byte(reg) &&
                 twi_start((uint8_t)((addr << 1) | 1));
    for (uint8_t i = 0; ok && i < n; i++) {
        TWCR = (uint8_t)((1 << TWINT) | (1 << TWEN) | ((i + 1 < n) ? (1 << TWEA) : 0));
        ok = twi_wait() && (TW_STATUS == ((i + 1 < n) ? TW_MR_DATA_ACK : TW_MR_DATA_NACK));
        if (ok) {
            buf[i] = TWDR;
        }
    }
    if (ok) {
        twi_stop();
    } else {
        twi_reset();
    }
    return ok;
}

uint8_t lsm303_init(void)
{
    TWSR = 0;                                 /* prescaler 1 */
    TWBR = (uint8_t)((F_CPU / 400000UL - 16) / 2); /* 400 kHz */
    TWCR = (1 << TWEN);
    uint8_t id = 0;
    if (!reg_read(MAG_ADDR, WHO_AM_I_M, &id, 1) || id != 0x40) {
        return 0;
    }
    if (!reg_read(ACC_ADDR, WHO_AM_I_A, &id, 1) || id != 0x33) {
        return 0; /* no tilt compensation without the accelerometer: no heading */
    }
    return reg_write(ACC_ADDR, CTRL_REG1_A, 0x57) && reg_write(ACC_ADDR, CTRL_REG4_A, 0x88) &&
           reg_write(MAG_ADDR, CFG_REG_A_M, 0x00) && reg_write(MAG_ADDR, CFG_REG_C_M, 0x10);
}

uint8_t lsm303_read(int16_t mag_raw[3], int16_t accel_mg[3])
{
    uint8_t b[6];
    int16_t m[3];
    int16_t a[3];
    if (!reg_read(MAG_ADDR, OUTX_L_REG_M, b, 6)) {
        return 0;
    }
    for (uint8_t i = 0; i < 3; i++) {
        m[i] = (int16_t)(b[2 * i] | ((uint16_t)b[2 * i + 1] << 8));
    }
    if (!reg_read(ACC_ADDR, OUT_X_L_A | AUTO_INCREMENT_A, b, 6)) {
        return 0;
    }
    for (uint8_t i = 0; i < 3; i++) {
        a[i] = (int16_t)((int16_t)(b[2 * i] | ((uint16_t)b[2 * i + 1] << 8)) >> 4);
    }
    for (uint8_t i = 0; i < 3; i++) {
        mag_raw[i] = AXIS_MAP(m, i);
        accel_mg[i] = AXIS_MAP(a, i);
    }
    return 1;
}

#endif
