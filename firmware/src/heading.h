/* Tilt-compensated magnetic heading (docs/heading.md) and the SET_CALIBRATION wire form.
 * Hardware-independent (float); only built into units with a magnetometer (WTCU_HAS_HEADING). */
#ifndef WTCU_HEADING_H
#define WTCU_HEADING_H

#include <stdint.h>

struct wtcu_calib {
    float b[3];    /* hard iron, uT */
    float w[3][3]; /* soft iron */
    float field;   /* |h| expected, uT; 0 = unknown (quality 0) */
};

#define WTCU_CALIB_WIRE_LEN 26u
#define WTCU_HEADING_PAYLOAD_LEN 13u

void wtcu_calib_identity(struct wtcu_calib *c);
/* Parses and checks a SET_CALIBRATION payload (26 bytes): W symmetric (within 4 Q12 steps, the wire's
 * rounding) and positive definite (Sylvester's criterion, exact integer arithmetic), field > 0.
 * Returns 0 and fills c when valid, -1 otherwise (c untouched). */
int8_t wtcu_calib_from_wire(const uint8_t *p, struct wtcu_calib *c);
/* Computes the HEADING payload from a raw reading (uT) and the accelerometer (specific force, any unit,
 * here g). Returns 0 when no heading is defined (free fall, no field, no horizontal field). */
uint8_t wtcu_heading_payload(const float raw_ut[3], const float accel_g[3], const struct wtcu_calib *c,
                             uint8_t out[WTCU_HEADING_PAYLOAD_LEN]);

#endif
